#include "observability_monitor.h"

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <algorithm>
#include <cstdio>
#include <sstream>

#include "mvis/common/lie.h"
#include "mvis/estimator/observability.h"
#include "mvis/factors/tangent_prior_factor.h"

namespace mvis {

namespace estimator_internal {
namespace {

// Gravity in the base IMU's frame, g_I = R^T gravity, at each reading that has a later one
// (others: zero), R from R_start turned by the rates less bias_gyro over the readings' intervals.
std::vector<Eigen::Vector3d> gravityInSensor(const std::vector<ImuMeasurement>& readings,
                                             const Eigen::Quaterniond& R_start,
                                             const Eigen::Vector3d& gravity,
                                             const Eigen::Vector3d& bias_gyro) {
  std::vector<Eigen::Vector3d> out(readings.size(), Eigen::Vector3d::Zero());
  Eigen::Quaterniond R = R_start;
  for (std::size_t k = 0; k + 1 < readings.size(); ++k) {
    const double dt = toSeconds(readings[k + 1].stamp_ns - readings[k].stamp_ns);
    if (!(dt > 0.0)) continue;
    out[k] = R.conjugate() * gravity;
    R = (R * lie::expQuat((readings[k].gyro - bias_gyro) * dt)).normalized();
  }
  return out;
}

}  // namespace

std::string intrinsicsElementName(const std::vector<int>& elements,
                                  const Eigen::VectorXd& direction, bool kalibr) {
  int k = 0;
  direction.cwiseAbs().maxCoeff(&k);
  using L = ImuIntrinsicsLayout;
  const int e = elements[k];
  if (e < L::kTg) {
    const int u = e < L::kDa ? e - L::kDw : e - L::kDa;
    int c = 0;
    while ((c + 1) * (c + 2) / 2 <= u) ++c;
    const int r = u - c * (c + 1) / 2;
    // kalibr: the entry of (r, c) holds the lower-triangular D(c, r).
    const int row = kalibr ? c : r, col = kalibr ? r : c;
    return std::string(e < L::kDa ? "dw" : "da") + std::to_string(row + 1) +
           std::to_string(col + 1);
  }
  if (e < L::kAccRotation) {
    const int u = e - L::kTg;
    return "tg" + std::to_string(u / 3 + 1) + std::to_string(u % 3 + 1);
  }
  return std::string(kalibr ? "theta_g_" : "theta_") + "xyz"[e - L::kAccRotation];
}

ObservabilityMonitor::ObservabilityMonitor(const Rig& rig, const EstimatorOptions& options,
                                           const CalibrationBlocks& calibration,
                                           const ImuIntrinsicsBlocks& intrinsics)
    : rig_(rig),
      options_(options),
      calibration_(calibration),
      intrinsics_(intrinsics),
      moments_(rig.inertial.size()),
      consider_(!options.batch) {}

void ObservabilityMonitor::clear() {
  unobservable_.clear();
  uninformative_.clear();
  motion_.clear();
  for (auto& m : moments_) m.clear();
  holds_.clear();
  followers_.clear();
  window_parts_.clear();
  window_found_.clear();
  window_blocks_.clear();
  window_weak_ = false;
  solves_since_window_check_ = 0;
}

void ObservabilityMonitor::addMotion(TimeNs a, TimeNs b,
                                     const std::vector<ImuMeasurement>& readings,
                                     const Eigen::Vector3d& bias_gyro,
                                     const Eigen::Quaterniond& R_a,
                                     const Eigen::Vector3d& gravity) {
  // Chunks of about 25 ms: their mean rates, and angular accelerations between them. The
  // gyroscope's noise makes each alpha noisy (variance s2 per axis), which would add 2 s2 I to
  // hat(alpha)^T hat(alpha) on average: it is taken out again, or noise alone would look like
  // rotation about every axis. A chunk's mean rate has the noise variance density^2 / T over its
  // T = (readings) x (their mean period): the interval's last chunk is often shorter (taking
  // every chunk as 25 ms, a rig that did not turn showed 1.6x the noise's |alpha|^2 and a
  // gyroscope's time offset looked observable).
  constexpr double kChunk = 0.025;
  const double density = rig_.inertial[0].noise.gyroscope_noise_density;
  struct Chunk {
    double mid;         // [s]
    Eigen::Vector3d w;  // mean rate
    int n;              // readings
  };
  std::vector<Chunk> chunks;
  double t0 = toSeconds(readings.front().stamp_ns - a), sum_t = 0.0;
  Eigen::Vector3d sum_w = Eigen::Vector3d::Zero();
  int n = 0;
  for (const auto& m : readings) {
    const double t = toSeconds(m.stamp_ns - a);
    if (n > 0 && t - t0 > kChunk) {
      chunks.push_back({sum_t / n, sum_w / n, n});
      t0 = t;
      sum_t = 0.0;
      sum_w.setZero();
      n = 0;
    }
    sum_t += t;
    sum_w += m.gyro - bias_gyro;
    ++n;
  }
  if (n > 0) chunks.push_back({sum_t / n, sum_w / n, n});
  const double period = readings.size() > 1
                            ? toSeconds(readings.back().stamp_ns - readings.front().stamp_ns) /
                                  static_cast<double>(readings.size() - 1)
                            : kChunk;
  MotionInformation info;
  info.t = b;
  for (std::size_t i = 0; i + 1 < chunks.size(); ++i) {
    const double dt = chunks[i + 1].mid - chunks[i].mid;
    if (!(dt > 0.0)) continue;
    const Eigen::Vector3d w = 0.5 * (chunks[i].w + chunks[i + 1].w);
    const Eigen::Vector3d alpha = (chunks[i + 1].w - chunks[i].w) / dt;
    const double s2 = density * density *
                      (1.0 / (chunks[i].n * period) + 1.0 / (chunks[i + 1].n * period)) / (dt * dt);
    const Eigen::Matrix3d Jp = lie::hat(alpha) + lie::hat(w) * lie::hat(w);
    info.translation += dt * (Jp.transpose() * Jp - 2.0 * s2 * Eigen::Matrix3d::Identity());
    info.rotation += dt * lie::hat(w).transpose() * lie::hat(w);
    // |alpha + n|^2 - 3 s2 is unbiased, with variance 6 s2^2 + 4 s2 |alpha|^2 (Gaussian n); not
    // clipped per chunk (spatialQuantities takes the sum's lower bound).
    const double e = alpha.squaredNorm() - 3.0 * s2;
    info.time_offset += dt * e;
    info.time_offset_var += dt * dt * (6.0 * s2 * s2 + 4.0 * s2 * std::max(e, 0.0));
    // Along a unit u the translation's term is |(alpha + n) x u|^2 - 2 s2: the two components
    // of alpha + n across u, variance 4 s2^2 + 4 s2 |alpha x u|^2 <= 4 s2^2 + 4 s2 |alpha|^2.
    info.translation_var += dt * dt * (4.0 * s2 * s2 + 4.0 * s2 * std::max(e, 0.0));
  }
  if (readings.size() > 1) {
    info.span = toSeconds(readings.back().stamp_ns - readings.front().stamp_ns);
  }
  // Asked only while the cameras' intrinsics are estimated: by the base accelerometer's check
  // (parallelViews) and by the cameras' translations' (accelerationAlong).
  if (gravity.squaredNorm() > 0.0 && options_.estimate_intrinsics) {
    const std::vector<Eigen::Vector3d> g = gravityInSensor(readings, R_a, gravity, bias_gyro);
    for (std::size_t k = 0; k + 1 < readings.size(); ++k) {
      const double dt = toSeconds(readings[k + 1].stamp_ns - readings[k].stamp_ns);
      if (!(dt > 0.0)) continue;
      const Eigen::Vector3d kin = readings[k].accel + g[k];
      info.T += dt;
      info.g += g[k] * dt;
      info.gg += g[k] * g[k].transpose() * dt;
      info.k += kin * dt;
      info.kk += kin * kin.transpose() * dt;
    }
  }
  motion_.push_back(info);
  const TimeNs horizon = fromSeconds(options_.observability_horizon_s);
  while (!motion_.empty() && motion_.front().t < b - horizon) motion_.pop_front();
}

bool ObservabilityMonitor::parallelViews() const {
  double T = 0.0, span = 0.0;
  Eigen::Vector3d g = Eigen::Vector3d::Zero();
  Eigen::Matrix3d gg = Eigen::Matrix3d::Zero();
  for (const auto& m : motion_) {
    T += m.T;
    span += m.span;
    g += m.g;
    gg += m.gg;
  }
  // Only over 2 s or more, most of the horizon's motion (not while the first states are few).
  if (T < 2.0 || T < 0.8 * span || !(g.norm() > 0.0)) return false;
  const Eigen::Matrix3d spread = (gg - g * g.transpose() / T) / T;
  const double tilt = std::sqrt(std::max(
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(spread).eigenvalues().maxCoeff(), 0.0));
  return tilt < std::sin(5.0 * M_PI / 180.0) * g.norm() / T;
}

double ObservabilityMonitor::accelerationAlong(const Eigen::Vector3d& n) const {
  double T = 0.0, span = 0.0, k = 0.0, kk = 0.0;
  for (const auto& m : motion_) {
    T += m.T;
    span += m.span;
    k += n.dot(m.k);
    kk += n.dot(m.kk * n);
  }
  if (T < 2.0 || T < 0.8 * span) return -1.0;  // as parallelViews
  return std::sqrt(std::max(kk / T - (k / T) * (k / T), 0.0));
}

void ObservabilityMonitor::addReadingMoments(std::size_t i, TimeNs t,
                                             const std::vector<ImuMeasurement>& readings,
                                             const Eigen::Quaterniond& R_start,
                                             const Eigen::Vector3d& gravity,
                                             const Eigen::Vector3d& bias_gyro) {
  if (!intrinsics_.block(i) || readings.size() < 2) return;
  ReadingMoments m;
  m.t = t;
  // Gravity's moments only where they are asked: the base accelerometer's check while the
  // cameras' intrinsics are estimated (intrinsicsQuantities); zero moments change nothing else.
  const bool with_gravity = i == 0 && options_.estimate_intrinsics;
  const std::vector<Eigen::Vector3d> gravities =
      with_gravity ? gravityInSensor(readings, R_start, gravity, bias_gyro)
                   : std::vector<Eigen::Vector3d>();
  for (std::size_t k = 0; k + 1 < readings.size(); ++k) {
    const double dt = toSeconds(readings[k + 1].stamp_ns - readings[k].stamp_ns);
    if (!(dt > 0.0)) continue;
    const Eigen::Vector3d& w = readings[k].gyro;
    const Eigen::Vector3d& a = readings[k].accel;
    m.T += dt;
    ++m.n;
    m.w += w * dt;
    m.a += a * dt;
    m.ww += w * w.transpose() * dt;
    m.aa += a * a.transpose() * dt;
    m.wa += w * a.transpose() * dt;
    if (with_gravity) {
      const Eigen::Vector3d& g = gravities[k];
      m.g += g * dt;
      m.gg += g * g.transpose() * dt;
      m.wg += w * g.transpose() * dt;
      m.ag += a * g.transpose() * dt;
    }
  }
  auto& q = moments_[i];
  q.push_back(m);
  const TimeNs horizon = fromSeconds(options_.observability_horizon_s);
  while (!q.empty() && q.front().t < t - horizon) q.pop_front();
}

void ObservabilityMonitor::check(ceres::Problem* problem) {
  unobservable_.clear();
  uninformative_.clear();
  const bool off = options_.observability_ratio <= 0.0 &&
                   options_.imu_intrinsics_observability_ratio <= 0.0 &&
                   options_.window_observability_ratio <= 0.0;
  if (off || motion_.empty()) {
    applyHolds(problem);
    return;
  }
  std::vector<Quantity> quantities;
  spatialQuantities(*problem, &quantities);
  intrinsicsQuantities(*problem, &quantities);
  for (const auto& q : quantities) {
    const Eigen::MatrixXd S = q.prior_std.asDiagonal();
    // IMU intrinsics: a block already held is released only when the motion tells 4x the ratio
    // (hysteresis). Their gains hover near the ratio when a reading component is only nearly
    // constant, and each release leaves a direction free with little information, where it
    // moves on noise before it is held again.
    const double ratio = q.symbol.empty()        ? options_.observability_ratio
                         : holds_.count(q.block) ? 4.0 * options_.imu_intrinsics_observability_ratio
                                                 : options_.imu_intrinsics_observability_ratio;
    if (!(ratio > 0.0)) continue;
    const WeakDirections weak = weakDirections(S * q.information * S, q.prior_std, ratio);
    if (weak.directions.cols() == 0) continue;
    UnobservableCalibration u;
    u.sensor = q.sensor;
    u.base = rig_.inertial[0].name;
    u.quantity = q.name;
    for (int c = 0; c < weak.directions.cols(); ++c) {
      u.information_ratio.push_back(std::max(weak.gains[c], 0.0));
      if (!q.symbol.empty()) {
        u.advice = q.advice;
        u.elements.push_back(intrinsicsElementName(q.elements, weak.directions.col(c), q.kalibr));
        continue;
      }
      if (q.size != 3) continue;
      Eigen::Vector3d d = q.to_I * weak.directions.col(c);
      int largest = 0;
      d.cwiseAbs().maxCoeff(&largest);
      if (d[largest] < 0) d = -d;
      u.directions_I.push_back(d.normalized());
    }
    unobservable_.push_back(std::move(u));
    // The block's tangent directions (disjoint rows per quantity, so the columns stay
    // orthonormal).
    const ceres::Manifold* own = baseManifold(*problem, q.block);
    const int tangent = own != nullptr ? own->TangentSize() : problem->ParameterBlockSize(q.block);
    Eigen::MatrixXd& D = uninformative_[q.block];
    const auto old = D.cols();
    D.conservativeResize(tangent, old + weak.directions.cols());
    D.rightCols(weak.directions.cols()).setZero();
    if (q.rows.empty()) {
      D.block(q.offset, old, q.size, weak.directions.cols()) = weak.directions;
    } else {
      for (int k = 0; k < q.size; ++k) {
        D.block(q.rows[k], old, 1, weak.directions.cols()) = weak.directions.row(k);
      }
    }
  }
  windowCheck(problem);
  applyHolds(problem);
}

void ObservabilityMonitor::spatialQuantities(const ceres::Problem& problem,
                                             std::vector<Quantity>* out) const {
  // The recent motion's information (report Sec. 5.1, Table 2), per unit noise density.
  MotionInformation sum;
  for (const auto& m : motion_) {
    sum.translation += m.translation;
    sum.translation_var += m.translation_var;
    sum.rotation += m.rotation;
    sum.time_offset += m.time_offset;
    sum.time_offset_var += m.time_offset_var;
  }
  // A gyroscope's time offset is told by the angular acceleration alone: what the noisy rates
  // show of it is counted at its lower 3-sigma bound (adjacent chunks share a mean, hence the
  // doubled variance), so that a rig that does not turn gives none. Translation-only motion,
  // with the noise's share clipped per chunk instead: the gyroscope's time offset estimated and
  // 3-20 sigma off.
  const double time_offset_information =
      std::max(sum.time_offset - 3.0 * std::sqrt(2.0 * sum.time_offset_var), 0.0);
  std::vector<Quantity>& quantities = *out;
  // Translations (cameras and aux IMUs): the relative acceleration of two rigidly attached
  // points is (hat(alpha) + hat(w)^2) p, measured with the accelerometer's noise. Extrinsic
  // translations are p_X_I in {X}; the sensor's position in {I} is -R^T p. What the noisy rates
  // show of it is counted at its lower 3-sigma bound too, in every direction alike: divided by
  // a quiet accelerometer's density the noise's scatter alone looked like rotation (an aux IMU
  // 10x quieter than imu0 on translation-only motion, 0.05 px corners: its translation estimated
  // and 1.6-2.6 m off after 60 s; held from the start now, test_estimator_sensors).
  const Eigen::Matrix3d translation_information =
      sum.translation - 3.0 * std::sqrt(2.0 * sum.translation_var) * Eigen::Matrix3d::Identity();
  // Against an uninformed prior: a saved calibration's sigmas made exciting motion look weak.
  auto translation = [&](const std::string& name, const double* block,
                         const CalibrationPrior& configured, double uninformed_m, double density) {
    CalibrationPrior prior = configured;
    prior.translation = prior.translation.cwiseMax(uninformed_m);
    if (!estimated(problem, block) || !(density > 0.0)) return;
    const Eigen::Matrix3d R_X_I = poseRotation(block).toRotationMatrix();
    quantities.push_back(
        {name, "translation", block, 3, 3, prior.translation, R_X_I.transpose(),
         R_X_I * translation_information * R_X_I.transpose() / (density * density)});
  };
  // The cameras' positions relative to each other are seen (each one's poses on the board, the
  // trajectory between them); what the motion must tell is where they sit on the base IMU
  // together. With the cameras' intrinsics estimated only the first camera's translation is
  // checked and held, and the others follow it through the images (the gauge: anchors(),
  // held_covariance.cpp, which carries its held uncertainty into theirs and the poses'). Each
  // held on its own, they were held where the first batch left them relative to each other,
  // with the intrinsics at their guesses, which the intrinsics then absorbed: translation-only
  // motion, noise-free data from the Monte Carlo's guess, ended the focal lengths 2.6-5.4 px and
  // cam1's centre 3.7 px off at 4-33 sigma (0.07 px and 0.001 px with the first held alone);
  // with noise, 6 x 60 s with every quantity free, focal lengths 2.7-5.6 px off at RMS
  // error/sigma 5.6-6.4 (now 0.55-1.23 px, 0.27-0.29). With the intrinsics known each camera is
  // held on its own as before (the first batch places them right).
  // But with a camera's intrinsics estimated, its distance to the board may come only with its
  // focal lengths (f / Z, parallel views) unless the rig moves along its viewing axis, which the
  // accelerometer measures: until it does (0.1 m/s^2 RMS over the horizon) the camera is checked
  // on its own (yaw-only with every quantity free, in a variant of 2026-11-27 that let it follow
  // the first camera: cam2's focal lengths ended 10 px off, RMS error/sigma 2.7 over 6 runs). The
  // batch (no consider parameters) checks each one as before, from the online result, where their
  // relative positions are the images'. A camera whose extrinsic is known (held by the options)
  // places the others: none is checked but for that trade.
  bool placed = false;
  for (std::size_t c = 0; c < calibration_.cameras(); ++c) {
    placed = placed || !estimated(problem, calibration_.camera(c).extrinsic);
  }
  for (std::size_t c = 0; c < calibration_.cameras(); ++c) {
    const CameraBlocks& cb = calibration_.camera(c);
    const Eigen::Vector3d axis = poseRotation(cb.extrinsic).conjugate() * Eigen::Vector3d::UnitZ();
    const bool alone = !consider_ || !estimated(problem, cb.intrinsics) || (c == 0 && !placed) ||
                       accelerationAlong(axis) < 0.1;
    if (!alone) continue;
    translation(rig_.cameras[c].name, cb.extrinsic, cb.prior,
                options_.extrinsic_translation_prior_m,
                rig_.inertial[0].noise.accelerometer_noise_density);
  }
  for (std::size_t i = 0; i < calibration_.auxiliaries(); ++i) {
    const AuxCalibration* a = &calibration_.aux(i);
    const std::string& name = rig_.inertial[a->sensor].name;
    const ImuNoise& noise = rig_.inertial[a->sensor].noise;
    if (!a->gyro) {
      translation(name, a->extrinsic, a->prior, options_.aux_translation_prior_m,
                  noise.accelerometer_noise_density);
      continue;
    }
    // A gyroscope's rotation (right perturbation, {I}): w_G = R Exp(dtheta) w_I, so
    // d w_G / d dtheta = -R hat(w); its time offset: d w_G / d t = R alpha.
    const double density = noise.gyroscope_noise_density;
    if (!(density > 0.0)) continue;
    CalibrationPrior prior = a->prior;
    prior.rotation = prior.rotation.cwiseMax(options_.aux_rotation_prior_rad);
    prior.time_offset = std::max(prior.time_offset, options_.aux_time_offset_prior_s);
    if (estimated(problem, a->rotation)) {
      quantities.push_back({name, "rotation", a->rotation, 0, 3, prior.rotation,
                            Eigen::Matrix3d::Identity(), sum.rotation / (density * density)});
    }
    if (estimated(problem, a->time_offset)) {
      quantities.push_back(
          {name, "time offset", a->time_offset, 0, 1,
           Eigen::VectorXd::Constant(1, prior.time_offset), Eigen::Matrix3d::Identity(),
           Eigen::MatrixXd::Constant(1, 1, time_offset_information / (density * density))});
    }
  }
}

Eigen::MatrixXd ObservabilityMonitor::latestCovariance(const double* block) const {
  if (auto C = intrinsics_.latestCovariance(block)) return *C;
  Eigen::VectorXd sd = calibration_.latestStd(block);
  if (sd.size() == 0) sd = intrinsics_.latestStd(block);
  return Eigen::MatrixXd(sd.cwiseAbs2().asDiagonal());
}

const ceres::Manifold* ObservabilityMonitor::baseManifold(const ceres::Problem& problem,
                                                          const double* block) const {
  const auto h = holds_.find(block);
  return h != holds_.end() ? h->second.base : problem.GetManifold(block);
}

bool ObservabilityMonitor::estimated(const ceres::Problem& problem, const double* block) const {
  return holds_.count(block) > 0 || !problem.IsParameterBlockConstant(block);
}

void ObservabilityMonitor::applyHolds(ceres::Problem* problem) {
  // Release what is observable again.
  for (auto it = holds_.begin(); it != holds_.end();) {
    double* block = const_cast<double*>(it->first);
    if (uninformative_.count(block)) {
      ++it;
      continue;
    }
    if (it->second.subspace) {
      problem->SetManifold(block, it->second.base);
    } else {
      problem->SetParameterBlockVariable(block);
    }
    it = holds_.erase(it);
  }
  for (const auto& [const_block, D] : uninformative_) {
    double* block = const_cast<double*>(const_block);
    auto existing = holds_.find(block);
    if (existing != holds_.end() && existing->second.directions.cols() == D.cols()) {
      // The same subspace: held as it is. IMU intrinsics' weak directions wobble from solve to
      // solve with the readings' moments (mixtures of elements when an axis is only nearly
      // constant); re-holding them every time would move the block along the old directions
      // and re-estimate their variance, so a subspace within ~0.1 rad counts as the same.
      const Eigen::MatrixXd& E = existing->second.directions;
      const double change = (E * E.transpose() - D * D.transpose()).norm();
      const bool wobbles = intrinsics_.isBlock(block) || window_blocks_.count(block) > 0;
      if (change < (wobbles ? 0.1 : 1e-9)) continue;
    }
    Hold hold;
    hold.base = existing != holds_.end()
                    ? existing->second.base
                    : const_cast<ceres::Manifold*>(problem->GetManifold(block));
    // The held subspace keeps the latest covariance there, D^T Sigma D; its basis is turned to
    // that matrix's eigenvectors so the kept variances are exact per direction.
    const Eigen::MatrixXd kept = D.transpose() * latestCovariance(block) * D;
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (kept + kept.transpose()));
    hold.directions = D * eig.eigenvectors();
    hold.variance = eig.eigenvalues().cwiseMax(0.0);
    const int tangent = static_cast<int>(D.rows());
    const bool was_constant = existing != holds_.end() && !existing->second.subspace;
    if (D.cols() >= tangent) {
      if (existing != holds_.end() && existing->second.subspace) {
        problem->SetManifold(block, hold.base);
      }
      problem->SetParameterBlockConstant(block);
    } else {
      // The free directions: the orthogonal complement of D.
      const Eigen::HouseholderQR<Eigen::MatrixXd> qr(D);
      const Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(tangent, tangent);
      const int ambient = problem->ParameterBlockSize(block);
      hold.subspace =
          std::make_unique<SubspaceManifold>(hold.base, ambient, Q.rightCols(tangent - D.cols()));
      if (was_constant) problem->SetParameterBlockVariable(block);
      problem->SetManifold(block, hold.subspace.get());
    }
    hold.sequence = existing != holds_.end() ? existing->second.sequence : holds_made_++;
    holds_[block] = std::move(hold);  // the replaced manifold is no longer in use
  }
  findFollowers(*problem);
}

Eigen::MatrixXd ObservabilityMonitor::tangentCovariance(const ceres::Problem& problem,
                                                        const BlockCovariance& cov,
                                                        const double* block) const {
  const int t = problem.ParameterBlockTangentSize(block);
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> C(t, t);
  // Only for blocks that were in the computation (not constant); NaN otherwise, never garbage.
  if (!cov.GetCovarianceBlockInTangentSpace(block, block, C.data())) {
    C.setConstant(std::numeric_limits<double>::quiet_NaN());
  }
  const auto h = holds_.find(block);
  if (h == holds_.end() || !h->second.subspace) {
    const Eigen::MatrixXd G = gaugeMap(block);
    if (G.size() > 0 && G.rows() == C.rows()) C += G * gaugeVariance().asDiagonal() * G.transpose();
    return C;
  }
  const Hold& hold = h->second;
  const Eigen::MatrixXd& B = hold.subspace->basis();
  return B * C * B.transpose() +
         hold.directions * hold.variance.asDiagonal() * hold.directions.transpose();
}

Eigen::MatrixXd ObservabilityMonitor::jointTangentCovariance(
    const ceres::Problem& problem, const BlockCovariance& cov,
    const std::vector<const double*>& blocks, bool considered_lifted,
    std::map<const double*, std::pair<int, int>>* offsets) const {
  Eigen::MatrixXd C;
  if (!cov.joint(blocks, &C)) return Eigen::MatrixXd();
  // Blocks partly held have the subspace's tangent in C: map each to its own tangent (B) and
  // add the variance its held directions kept, as tangentCovariance does for one.
  std::vector<Eigen::MatrixXd> maps;
  std::vector<Eigen::MatrixXd> kept, gauge;
  int rows = 0, cols = 0;
  for (const double* block : blocks) {
    const int t = problem.ParameterBlockTangentSize(block);
    const auto h = holds_.find(block);
    gauge.push_back(gaugeMap(block));
    if (h == holds_.end() || !h->second.subspace || (considered_lifted && considered(block))) {
      maps.push_back(Eigen::MatrixXd::Identity(t, t));
      kept.push_back(Eigen::MatrixXd::Zero(t, t));
    } else {
      const Hold& hold = h->second;
      maps.push_back(hold.subspace->basis());
      // The anchor's kept variance comes with the gauge's, below.
      const auto n = hold.directions.rows();
      kept.push_back(anchors(block) ? Eigen::MatrixXd::Zero(n, n)
                                    : Eigen::MatrixXd(hold.directions * hold.variance.asDiagonal() *
                                                      hold.directions.transpose()));
    }
    if (offsets != nullptr) (*offsets)[block] = {rows, static_cast<int>(maps.back().rows())};
    rows += static_cast<int>(maps.back().rows());
    cols += static_cast<int>(maps.back().cols());
  }
  if (cols != C.rows()) return Eigen::MatrixXd();
  Eigen::MatrixXd B = Eigen::MatrixXd::Zero(rows, cols), K = Eigen::MatrixXd::Zero(rows, rows);
  int r = 0, c = 0;
  for (std::size_t i = 0; i < maps.size(); ++i) {
    B.block(r, c, maps[i].rows(), maps[i].cols()) = maps[i];
    K.block(r, r, kept[i].rows(), kept[i].cols()) = kept[i];
    r += static_cast<int>(maps[i].rows());
    c += static_cast<int>(maps[i].cols());
  }
  const Eigen::VectorXd v = gaugeVariance();
  if (v.size() > 0) {
    Eigen::MatrixXd G = Eigen::MatrixXd::Zero(rows, v.size());
    r = 0;
    for (std::size_t i = 0; i < maps.size(); ++i) {
      if (gauge[i].size() > 0 && gauge[i].rows() == maps[i].rows()) {
        G.middleRows(r, gauge[i].rows()) = gauge[i];
      }
      r += static_cast<int>(maps[i].rows());
    }
    K += G * v.asDiagonal() * G.transpose();
  }
  return B * C * B.transpose() + K;
}

std::map<const double*, Eigen::MatrixXd> ObservabilityMonitor::heldDirections() const {
  std::map<const double*, Eigen::MatrixXd> out;
  // A held extrinsic translation, gyroscope rotation or time offset is a gauge of what the
  // cameras and readings show (a camera's translation along the only rotation axis against
  // imu0's position along it): the leaving frames tell nothing along it, only about the states
  // relative to it, so they are marginalized with it as any block (the window holds it, the
  // prior keeps the ties). Forgetting it as unknown took along what they told of imu0's
  // positions and all tied to them: on translation-only motion the cameras ended 0.23 deg and
  // 1.4-4.4 ms off with ~1 ms sigmas, 15x what the batch knows (test
  // TranslationOnlyMotionKeepsWhatLeavingFramesTellTheCameras). Not so while the cameras'
  // intrinsics are estimated: a translation along the board's normal is then tied to the focal
  // lengths (the image's scale), and kept it pulled them (yaw-only with everything free: 226
  // against 229 of 238 inside 3 sigma, position NEES 17-21 against 9-12), so there it is
  // forgotten, as are the joint check's directions. The IMU intrinsics' held directions are
  // kept too, as consider parameters (held_covariance.cpp): the covariance adds what their kept
  // variance makes of everything else, once. Forgotten as unknown the cameras' tilt was left to
  // the current window; marginalized within their kept variance every time (2026-11-26/27), that
  // variance counted once per marginalization and the focal lengths, tied to them on yaw-only
  // motion, ended 2.6x surer than the batch over the whole recording (RMS error/sigma 2.2-3.5).
  // The gauge's anchor (the first camera's held translation, which the other cameras' follow:
  // anchors()) is kept, so that the prior is conditioned on it as the solves are. Forgotten, it
  // took along what the leaving frames told of the first camera's focal lengths and time offset
  // (their tie to imu0's position went with it: 8.6 px and 0.8 ms off on translation-only
  // motion, against 0.7-1.4 px and 0.13 ms for the others), while the followers, kept, let the
  // prior learn the shift nothing tells from the leaving frames' linearization points (position
  // NEES rising to 47 for 3 over a run; 2026-11-27).
  bool camera_intrinsics = false;  // any camera's estimated
  for (const Camera& c : rig_.cameras) {
    camera_intrinsics = camera_intrinsics || (options_.estimate_intrinsics &&
                                              !heldByOption(options_, c.name, "intrinsics"));
  }
  for (const auto& [block, D] : uninformative_) {
    if (intrinsics_.isBlock(block)) continue;                              // kept: considered
    if (anchors(block)) continue;                                          // kept: the gauge
    if (!camera_intrinsics && window_blocks_.count(block) == 0) continue;  // kept
    out[block] = D;                                                        // as unknown
  }
  return out;
}

}  // namespace estimator_internal
}  // namespace mvis
