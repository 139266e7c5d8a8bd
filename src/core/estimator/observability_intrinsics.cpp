// ObservabilityMonitor's check of the IMU intrinsics (report Table 3): what the inertial
// sensors' readings over the observability horizon tell each estimated intrinsics element.
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "observability_monitor.h"

namespace mvis {
namespace estimator_internal {
namespace {

// The information of the `size` coordinates at `first` of I with every other one unknown (its
// block's pseudo-inverse: what nothing tells stays untold).
Eigen::MatrixXd schurComplement(const Eigen::MatrixXd& I, int first, int size) {
  const int n = static_cast<int>(I.rows());
  std::vector<int> rest;
  for (int j = 0; j < n; ++j) {
    if (j < first || j >= first + size) rest.push_back(j);
  }
  const int m = static_cast<int>(rest.size());
  Eigen::MatrixXd A = I.block(first, first, size, size);
  if (m == 0) return A;
  Eigen::MatrixXd B(size, m), R(m, m);
  for (int c = 0; c < m; ++c) {
    B.col(c) = I.block(first, rest[c], size, 1);
    for (int r = 0; r < m; ++r) R(r, c) = I(rest[r], rest[c]);
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(0.5 * (R + R.transpose()));
  const double floor = 1e-9 * std::max(es.eigenvalues().maxCoeff(), 0.0);
  Eigen::VectorXd inv = Eigen::VectorXd::Zero(m);
  for (int j = 0; j < m; ++j) {
    if (es.eigenvalues()[j] > floor) inv[j] = 1.0 / es.eigenvalues()[j];
  }
  const Eigen::MatrixXd V = B * es.eigenvectors();
  return A - V * inv.asDiagonal() * V.transpose();
}

}  // namespace

void ObservabilityMonitor::intrinsicsQuantities(const ceres::Problem& problem,
                                                std::vector<Quantity>* out) const {
  std::vector<Quantity>& quantities = *out;
  // IMU intrinsics (report Table 3). To first order a reading errs by
  //   gyroscope:      dDw w - dTg a                  (Dw ~ I)
  //   accelerometer:  (dDa + hat(dtheta)) a = dDa a - hat(a) dtheta
  // for the rates w and specific forces a, so each output row r has a regressor phi_r over the
  // elements it involves (Dw's row r and Tg's row r; Da's row r and dtheta). Whatever is
  // constant over the horizon cannot be told from the bias: the information is
  // sum_r int (phi_r - mean)(phi_r - mean)^T dt / s^2, from the readings' centered moments
  // (white noise's share taken out). Da and dtheta are checked together: their null spaces mix
  // them (a constant a_1 leaves da11 and, with da12 and da13, the pitch and yaw of R_IMUtoACC
  // unobservable). Dw and Tg are checked apart, neglecting the cross-moment of w and a: held
  // directions mixing elements of different prior sizes would keep a wrong variance (the hold
  // keeps the held subspace's variance and conditions the rest on it).
  for (std::size_t i = 0; i < intrinsics_.sensors(); ++i) {
    const ImuIntrinsicsBlock* b = intrinsics_.block(i);
    if (b == nullptr || !estimated(problem, b->x) || moments_[i].empty() ||
        !(options_.imu_intrinsics_observability_ratio > 0.0)) {
      continue;
    }
    ReadingMoments m;
    for (const auto& r : moments_[i]) {
      m.T += r.T;
      m.n += r.n;
      m.w += r.w;
      m.a += r.a;
      m.ww += r.ww;
      m.aa += r.aa;
      m.wa += r.wa;
      m.g += r.g;
      m.gg += r.gg;
      m.wg += r.wg;
      m.ag += r.ag;
    }
    if (!(m.T > 0.0)) continue;
    const ImuNoise& noise = rig_.inertial[i].noise;
    const double sg = noise.gyroscope_noise_density, sa = noise.accelerometer_noise_density;
    const bool accel = !b->frame.gyro_only && sa > 0.0;
    // Centered second moments of z = [w; a; g_I] (g_I: gravity in the base IMU's frame, zero
    // for the others).
    Eigen::Matrix<double, 9, 9> C;
    const Eigen::Matrix<double, 9, 1> mean =
        (Eigen::Matrix<double, 9, 1>() << m.w, m.a, m.g).finished();
    C << m.ww, m.wa, m.wg, m.wa.transpose(), m.aa, m.ag, m.wg.transpose(), m.ag.transpose(), m.gg;
    C -= mean * mean.transpose() / m.T;
    C.topLeftCorner<3, 3>() -= m.n * sg * sg * Eigen::Matrix3d::Identity();
    // A gyroscope's specific force is the base IMU's (aux_sensors.h), with its white noise.
    double force_noise = accel ? sa * sa : 0.0;
    if (b->frame.gyro_only) {
      const InertialSensor& base = rig_.inertial[0];
      const double sb = base.noise.accelerometer_noise_density;
      const double rate = rig_.inertial[i].update_rate;
      force_noise = sb * sb * (rate > 0.0 && base.update_rate > 0.0 ? base.update_rate / rate : 1);
    }
    C.block<3, 3>(3, 3) -= m.n * force_noise * Eigen::Matrix3d::Identity();
    using L = ImuIntrinsicsLayout;
    // Tangent position of an ambient entry (-1: held by the block's own manifold).
    const auto tangentOf = [&](int ambient) {
      const auto it = std::find(b->free.begin(), b->free.end(), ambient);
      return it == b->free.end() ? -1 : static_cast<int>(it - b->free.begin());
    };
    // One channel: per output row, (element, linear map from z to its regressor) pairs.
    using Row = Eigen::Matrix<double, 1, 9>;
    struct Term {
      int element;  // ambient index in the block
      Row g;        // regressor = g z
    };
    // `nuisance`: per output row, the regressors of parameters outside the block that move the
    // same readings (the sensor's extrinsic rotation, below), after the block's free elements
    // (`elements`, ambient, in block order) in the information returned.
    using Regressors = std::vector<Row>;
    const auto information = [&](const std::vector<std::vector<Term>>& rows, double density,
                                 const std::vector<Regressors>& nuisance,
                                 std::vector<int>* elements) {
      elements->clear();
      for (const auto& row : rows) {
        for (const auto& t : row) {
          if (tangentOf(t.element) >= 0 &&
              std::find(elements->begin(), elements->end(), t.element) == elements->end()) {
            elements->push_back(t.element);
          }
        }
      }
      std::sort(elements->begin(), elements->end());
      const int n = static_cast<int>(elements->size());
      const int k = nuisance.empty() ? 0 : static_cast<int>(nuisance[0].size());
      Eigen::MatrixXd I = Eigen::MatrixXd::Zero(n + k, n + k);
      if (n == 0 || !(density > 0.0)) return I;
      for (std::size_t r = 0; r < rows.size(); ++r) {
        Eigen::MatrixXd G = Eigen::MatrixXd::Zero(n + k, 9);
        for (const auto& t : rows[r]) {
          const auto at = std::find(elements->begin(), elements->end(), t.element);
          if (at != elements->end()) G.row(at - elements->begin()) += t.g;
        }
        for (int j = 0; j < k; ++j) G.row(n + j) = nuisance[r][static_cast<std::size_t>(j)];
        I += G * C * G.transpose() / (density * density);
      }
      return I;
    };
    const auto addChannel = [&](const std::vector<int>& elements, const Eigen::MatrixXd& I,
                                double density, const char* quantity, const char* symbol) {
      const int n = static_cast<int>(elements.size());
      if (n == 0 || !(density > 0.0)) return;
      Quantity q{rig_.inertial[i].name,       quantity, b->x, 0, n, Eigen::VectorXd(n),
                 Eigen::Matrix3d::Identity(), I};
      q.symbol = symbol;
      for (int k = 0; k < n; ++k) {
        q.prior_std[k] = b->prior_std[elements[k]];
        q.rows.push_back(tangentOf(elements[k]));
        q.elements.push_back(elements[k]);
      }
      q.kalibr = b->frame.kalibr;
      quantities.push_back(q);
    };
    const auto unit = [](int k) {
      Row g = Row::Zero();
      g[k] = 1.0;
      return g;
    };
    // rpng: D upper triangular, the rotation on the accelerometer; kalibr: D lower triangular
    // (entry upperIndex(c, r) is D(r, c)), the rotation on the gyroscope (a gyroscope-only
    // sensor's is held: it is its extrinsic rotation).
    const bool kalibr = b->frame.kalibr;
    std::vector<std::vector<Term>> gyro(3), gravity(3), acc(3);
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        if (kalibr ? c > r : c < r) continue;
        const int entry = kalibr ? upperIndex(c, r) : upperIndex(r, c);
        gyro[r].push_back({L::kDw + entry, unit(c)});
        acc[r].push_back({L::kDa + entry, unit(3 + c)});
      }
      for (int c = 0; c < 3; ++c) gravity[r].push_back({L::kTg + 3 * r + c, -unit(3 + c)});
      // Row r of -hat(x) (x the specific force, kalibr: the rate): the regressor of dtheta_k is
      // -(e_r x e_k) . x.
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d e = -Eigen::Vector3d::Unit(r).cross(Eigen::Vector3d::Unit(k));
        Row g = Row::Zero();
        if (kalibr) {
          g.head<3>() = e.transpose();
          gyro[r].push_back({L::kAccRotation + k, g});
        } else {
          g.segment<3>(3) = e.transpose();
          acc[r].push_back({L::kAccRotation + k, g});
        }
      }
    }
    // An auxiliary sensor's readings also turn with its extrinsic rotation (x -> Exp(d) x:
    // -hat(x) d for the rates and, with an accelerometer, the specific force), which the
    // accelerometer's own rotation (rpng) moves the same way in the specific force: the gyroscope
    // tells it apart only where the rig turns. On rotation about one axis the sensor's rotation
    // across the axis and the off-diagonal of Dw's column for the axis move the same rates
    // (yaw-only with every quantity free left imu1's rotation and dw12 5 sigma off together, with
    // R_IMUtoACC); without rotation R_IMUtoACC and the extrinsic rotation move the same forces.
    // So each channel is checked with that rotation unknown but for what the other channel tells
    // of it once its own elements are unknown: the exact marginal information of the channel's
    // elements in the joint problem (the channels share only the rotation). On rotation about
    // every axis this holds nothing more (an upper-triangular Dw and a rotation make any 3x3 map
    // once, so the gyroscope pins the rotation).
    std::vector<Regressors> turn_w, turn_a;
    const double* extrinsic = nullptr;
    for (std::size_t j = 0; j < calibration_.auxiliaries(); ++j) {
      const AuxCalibration& a = calibration_.aux(j);
      if (a.sensor == i) extrinsic = a.gyro ? a.rotation : a.extrinsic;
    }
    if (!kalibr && extrinsic != nullptr && estimated(problem, extrinsic)) {
      turn_w.assign(3, Regressors(3, Row::Zero()));
      turn_a = turn_w;
      for (int r = 0; r < 3; ++r) {
        for (int k = 0; k < 3; ++k) {
          const Eigen::Vector3d e = Eigen::Vector3d::Unit(r).cross(Eigen::Vector3d::Unit(k));
          turn_w[r][k].head<3>() = e.transpose();
          turn_a[r][k].segment<3>(3) = e.transpose();
        }
      }
    }
    // The base IMU's accelerometer against the cameras' intrinsics. Views of the board from one
    // orientation tell a camera's focal lengths f only with its distance Z, as f / Z, and its
    // principal point only with its tilt (parallel views give the same two constraints on the
    // intrinsics each: Sturm and Maybank 1999, Zhang 2000). What separates them is the metric
    // motion, which the accelerometer gives; with every camera's intrinsics estimated, the
    // cameras tell the kinematic acceleration only up to a map that their intrinsics (and tilts)
    // absorb, and what tells the accelerometer's own map is then gravity turning in it (its
    // size is known). So the check takes the kinematic acceleration's 3x3 map B as a nuisance,
    // the regressor of B_pq in output row p being (a + g_I)_q, the specific force plus gravity in
    // the sensor's frame (centred: the constant part is the bias's). Where the rig turns it
    // differs from the specific force a. It applies only while the views are parallel, with
    // gravity's direction in the sensor spread by less than 5 deg (RMS) over the horizon
    // (translation-only motion, rotation about the vertical over a flat board): views from
    // several orientations tell the intrinsics themselves (Zhang 2000), and on hand-held motion
    // the nuisance held imu0's Ta 4e-3 off (0.75e-3 without it). A bound on the information, not
    // the exact null space (the board's size and several cameras' views pin some of B): without
    // it, translation-only motion with every quantity free moved the focal lengths and imu0's
    // da11 by 0.46% together (3.5 sigma) on noise-free data from the truth.
    std::vector<Regressors> scale_a;
    std::string advice;
    bool cameras_free = calibration_.cameras() > 0;
    for (std::size_t c = 0; c < calibration_.cameras(); ++c) {
      cameras_free = cameras_free && estimated(problem, calibration_.camera(c).intrinsics);
    }
    const bool parallel = i == 0 && parallelViews();
    if (i == 0 && accel && cameras_free && parallel && turn_a.empty()) {
      scale_a.assign(3, Regressors(9, Row::Zero()));
      for (int r = 0; r < 3; ++r) {
        for (int q = 0; q < 3; ++q) {
          scale_a[r][3 * r + q][3 + q] = 1.0;
          scale_a[r][3 * r + q][6 + q] = 1.0;
        }
      }
      advice =
          "tilt the rig: with the cameras' intrinsics estimated only gravity turning "
          "tells the accelerometer's scale and axes";
    }
    std::vector<int> gyro_elements, acc_elements;
    Eigen::MatrixXd Iw = information(gyro, sg, turn_w, &gyro_elements);
    Eigen::MatrixXd Ia =
        accel ? information(acc, sa, scale_a.empty() ? turn_a : scale_a, &acc_elements)
              : Eigen::MatrixXd::Zero(0, 0);
    if (!scale_a.empty() && Ia.rows() > 0) {
      Ia = schurComplement(Ia, 0, static_cast<int>(acc_elements.size()));
    }
    if (!turn_w.empty()) {
      const int nw = static_cast<int>(gyro_elements.size());
      if (Ia.rows() == 0) Ia = Eigen::MatrixXd::Zero(3, 3);  // no accelerometer: nothing
      const int na = static_cast<int>(Ia.rows()) - 3;
      // What each channel tells of the rotation with its own elements unknown.
      const Eigen::Matrix3d from_w = schurComplement(Iw, nw, 3);
      const Eigen::Matrix3d from_a = schurComplement(Ia, na, 3);
      Iw.bottomRightCorner<3, 3>() += from_a;
      Ia.bottomRightCorner<3, 3>() += from_w;
      Iw = schurComplement(Iw, 0, nw);
      Ia = schurComplement(Ia, 0, na);
    }
    addChannel(gyro_elements, Iw, sg,
               kalibr ? "gyroscope intrinsics" : "gyroscope scale and misalignment", "gyro");
    // A gyroscope's Tg against the specific force it is given (aux_sensors.h), as an IMU's.
    std::vector<int> gravity_elements;
    const Eigen::MatrixXd Ig = information(gravity, sg, {}, &gravity_elements);
    addChannel(gravity_elements, Ig, sg, "gravity sensitivity", "gravity");
    if (!accel) continue;
    addChannel(acc_elements, Ia, sa,
               kalibr ? "accelerometer scale and misalignment" : "accelerometer intrinsics",
               "accel");
    if (!advice.empty() && !quantities.empty() && quantities.back().symbol == "accel") {
      quantities.back().advice = advice;
    }
  }
}

}  // namespace estimator_internal
}  // namespace mvis
