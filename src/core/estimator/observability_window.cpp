// ObservabilityMonitor's joint check: degeneracy from the window's information.
//
// The per-quantity checks (observability_monitor.cpp) look at one calibrated quantity at a time
// with the states known. Some motions leave a direction unobservable that no single quantity
// has: on rotation about one axis k, turning the base accelerometer (R_IMUtoACC) about k together
// with every extrinsic rotation about k changes no measurement (the gyroscope cannot tell the
// body's turn about k from a turn of the frame about k, and the accelerometer's specific force
// turns with it). Here the window itself is asked: Lambda, the Schur complement of the window's
// information onto every estimated calibration block (window_information.h, its own priors
// left out), is whitened by the blocks' prior standard deviations s,
//   W = diag(s) Lambda diag(s)   (how many times more the window tells than the priors),
// restricted to the complement Q of what the per-quantity checks hold (Q^T W Q: held directions
// are known, not marginalized), and its eigenvectors u with eigenvalue below
// `window_observability_ratio` are weak. Such a direction v = Q u spans blocks; holding it exactly
// would need a constraint across blocks, so each block with a share |v_b|^2 >= kShare of it holds
// its own part diag(s_b) v_b (normalized): more than the joint direction, never less; each block
// keeps the variance it had along its part (the hold's rule), but the rest is conditioned on the
// held values without their uncertainty, and what the held parts' relative values could have
// told is given up while the motion lasts. Measured on the simulated yaw-only runs with every
// quantity free it did not make them consistent, and on hand-held motion it held weak but
// informative directions: off by default (doc/results.md, "Every quantity free").
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <chrono>
#include <cstdio>

#include "mvis/estimator/observability.h"
#include "mvis/estimator/window_information.h"
#include "observability_monitor.h"

namespace mvis {
namespace estimator_internal {
namespace {

// A block's part of a weak direction is held when it carries at least this share of it (the
// direction's whitened squared norm).
constexpr double kShare = 0.02;
// Solves between joint checks (each costs about one Jacobian evaluation of the window and a
// sparse factorization); what a check found stays held until the next.
constexpr long kWindowCheckEvery = 10;

// "(0.00, 0.71, 0.71)" with the largest entry positive.
std::string axisText(Eigen::Vector3d d) {
  int largest = 0;
  d.cwiseAbs().maxCoeff(&largest);
  if (d[largest] < 0) d = -d;
  d.normalize();
  char text[64];
  std::snprintf(text, sizeof text, "(%.2f, %.2f, %.2f)", d.x(), d.y(), d.z());
  return text;
}

}  // namespace

void ObservabilityMonitor::holdWindowParts() {
  window_blocks_.clear();
  for (const auto& [block, part] : window_parts_) {
    const int size = static_cast<int>(part.size());
    const auto existing = uninformative_.find(block);
    Eigen::MatrixXd D =
        existing != uninformative_.end() ? existing->second : Eigen::MatrixXd(size, 0);
    Eigen::VectorXd d = part;
    if (D.cols() > 0) d -= D * (D.transpose() * d);
    if (d.norm() < 0.3 || D.cols() >= size) continue;  // (nearly) held already
    D.conservativeResize(size, D.cols() + 1);
    D.col(D.cols() - 1) = d.normalized();
    uninformative_[block] = std::move(D);
    window_blocks_.insert(block);
  }
  unobservable_.insert(unobservable_.end(), window_found_.begin(), window_found_.end());
}

void ObservabilityMonitor::windowCheck(ceres::Problem* problem) {
  const double base_ratio = options_.window_observability_ratio;
  if (!(base_ratio > 0.0)) {
    window_parts_.clear();
    window_found_.clear();
    return;
  }
  // Between checks, what the last one found stays held.
  if (solves_since_window_check_++ % kWindowCheckEvery != 0) {
    holdWindowParts();
    return;
  }
  window_parts_.clear();
  window_found_.clear();
  const auto start = std::chrono::steady_clock::now();
  // The estimated calibration blocks: their own tangent's prior standard deviations, and how to
  // name a direction in them.
  struct Checked {
    double* block;
    std::string sensor;
    Eigen::VectorXd prior_std;
    enum Kind { kExtrinsic, kRotation, kTimeOffset, kCameraIntrinsics, kImuIntrinsics } kind;
    Eigen::Matrix3d R_X_I = Eigen::Matrix3d::Identity();  // extrinsics: the block's rotation
    const ImuIntrinsicsBlock* imu = nullptr;
  };
  std::vector<Checked> checked;
  const auto tangentOf = [&](const double* block) {
    const ceres::Manifold* own = baseManifold(*problem, block);
    return own != nullptr ? own->TangentSize() : problem->ParameterBlockSize(block);
  };
  const auto pose = [&](double* block, const std::string& sensor, const CalibrationPrior& p) {
    if (!estimated(*problem, block)) return;
    Checked c{block, sensor, Eigen::VectorXd(6), Checked::kExtrinsic};
    c.prior_std << p.rotation, p.translation;
    c.R_X_I = poseRotation(block).toRotationMatrix();
    checked.push_back(c);
  };
  const auto offset = [&](double* block, const std::string& sensor, double prior) {
    if (!estimated(*problem, block)) return;
    checked.push_back({block, sensor, Eigen::VectorXd::Constant(1, prior), Checked::kTimeOffset});
  };
  for (std::size_t c = 0; c < calibration_.cameras(); ++c) {
    const CameraBlocks& cb = calibration_.camera(c);
    const std::string& name = rig_.cameras[c].name;
    pose(const_cast<double*>(cb.extrinsic), name, cb.prior);
    offset(const_cast<double*>(cb.time_offset), name, cb.prior.time_offset);
    if (estimated(*problem, cb.intrinsics) && tangentOf(cb.intrinsics) == kIntrinsicsSize) {
      checked.push_back({const_cast<double*>(cb.intrinsics), name, cb.intrinsics_prior,
                         Checked::kCameraIntrinsics});
    }
  }
  for (std::size_t i = 0; i < calibration_.auxiliaries(); ++i) {
    const AuxCalibration& a = calibration_.aux(i);
    const std::string& name = rig_.inertial[a.sensor].name;
    if (a.gyro) {
      if (estimated(*problem, a.rotation)) {
        checked.push_back(
            {const_cast<double*>(a.rotation), name, a.prior.rotation, Checked::kRotation});
      }
    } else {
      pose(const_cast<double*>(a.extrinsic), name, a.prior);
    }
    offset(const_cast<double*>(a.time_offset), name, a.prior.time_offset);
  }
  for (std::size_t i = 0; i < intrinsics_.sensors(); ++i) {
    const ImuIntrinsicsBlock* b = intrinsics_.block(i);
    if (b == nullptr || !estimated(*problem, b->x)) continue;
    Checked c{const_cast<double*>(b->x), rig_.inertial[i].name,
              Eigen::VectorXd(static_cast<int>(b->free.size())), Checked::kImuIntrinsics};
    for (std::size_t k = 0; k < b->free.size(); ++k) c.prior_std[k] = b->prior_std[b->free[k]];
    c.imu = b;
    if (tangentOf(b->x) == c.prior_std.size()) checked.push_back(c);
  }
  if (checked.empty()) return;

  std::vector<double*> blocks;
  std::vector<int> at;  // each block's first row
  int n = 0;
  for (const Checked& c : checked) {
    blocks.push_back(c.block);
    at.push_back(n);
    n += static_cast<int>(c.prior_std.size());
  }
  liftHolds(problem);
  const StatusOr<Eigen::MatrixXd> information = windowInformation(problem, blocks);
  restoreHolds(problem);
  if (!information.ok() || information.value().rows() != n) return;
  Eigen::VectorXd s(n);
  for (std::size_t k = 0; k < checked.size(); ++k) {
    s.segment(at[k], checked[k].prior_std.size()) = checked[k].prior_std;
  }
  const Eigen::MatrixXd W = s.asDiagonal() * information.value() * s.asDiagonal();
  // What the per-quantity checks hold, whitened (tangent d is diag(s)^-1 d there); W restricted
  // to its complement.
  Eigen::MatrixXd held = Eigen::MatrixXd::Zero(n, 0);
  for (std::size_t k = 0; k < checked.size(); ++k) {
    const auto u = uninformative_.find(checked[k].block);
    if (u == uninformative_.end()) continue;
    const Eigen::MatrixXd& D = u->second;
    const auto old = held.cols();
    held.conservativeResize(n, old + D.cols());
    held.rightCols(D.cols()).setZero();
    held.block(at[k], old, D.rows(), D.cols()) =
        checked[k].prior_std.cwiseInverse().asDiagonal() * D;
  }
  Eigen::MatrixXd Q = Eigen::MatrixXd::Identity(n, n);
  if (held.cols() > 0) {
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(held);
    const auto rank = qr.rank();
    const Eigen::MatrixXd full = qr.householderQ() * Eigen::MatrixXd::Identity(n, n);
    Q = full.rightCols(n - rank);
  }
  const Eigen::MatrixXd Wr = Q.transpose() * W * Q;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(0.5 * (Wr + Wr.transpose()));
  // Once weak directions are held, they are released only when the window tells 4x the ratio.
  const double ratio = window_weak_ ? 4.0 * base_ratio : base_ratio;
  // What the motion lacks, for the words.
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Zero();
  for (const auto& m : motion_) rotation += m.rotation;
  const Eigen::Vector3d spin =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(rotation).eigenvalues();
  const char* advice = !(spin[2] > 0.0)           ? "rotate the rig"
                       : spin[1] < 1e-2 * spin[2] ? "rotate about another axis too"
                                                  : "vary the motion on every axis";
  bool weak_found = false;
  for (int e = 0; e < es.eigenvalues().size() && es.eigenvalues()[e] < ratio; ++e) {
    weak_found = true;
    const Eigen::VectorXd v = Q * es.eigenvectors().col(e);
    UnobservableCalibration u;
    u.base = rig_.inertial[0].name;
    u.quantity = "shared direction";
    u.advice = advice;
    u.information_ratio.push_back(std::max(es.eigenvalues()[e], 0.0));
    for (std::size_t k = 0; k < checked.size(); ++k) {
      const Checked& c = checked[k];
      const int size = static_cast<int>(c.prior_std.size());
      const Eigen::VectorXd vb = v.segment(at[k], size);
      if (vb.squaredNorm() < kShare) continue;
      Eigen::VectorXd d = c.prior_std.asDiagonal() * vb;
      d.normalize();
      // Words: the part that carries most of the block's share.
      std::string part = c.sensor + " ";
      switch (c.kind) {
        case Checked::kExtrinsic:
          part += vb.head<3>().squaredNorm() >= vb.tail<3>().squaredNorm()
                      ? "rotation about " + axisText(d.head<3>())
                      : "translation along " + axisText(c.R_X_I.transpose() * d.tail<3>());
          break;
        case Checked::kRotation:
          part += "rotation about " + axisText(d);
          break;
        case Checked::kTimeOffset:
          part += "time offset";
          break;
        case Checked::kCameraIntrinsics: {
          int largest = 0;
          vb.cwiseAbs().maxCoeff(&largest);
          const char* names[] = {"fu", "fv", "cu", "cv"};
          part += std::string("intrinsics (") +
                  (largest < 4 ? std::string(names[largest]) : "d" + std::to_string(largest - 4)) +
                  ")";
          break;
        }
        case Checked::kImuIntrinsics:
          part +=
              "intrinsics (" + intrinsicsElementName(c.imu->free, vb, c.imu->frame.kalibr) + ")";
          break;
      }
      u.sensor += (u.sensor.empty() ? "" : "+") + c.sensor;
      u.shared.push_back(part);
      window_parts_.emplace_back(c.block, d);
    }
    window_found_.push_back(std::move(u));
  }
  // Each block holds its parts, orthogonal to what it holds already.
  holdWindowParts();
  window_weak_ = weak_found;
  window_check_s_ +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ++window_checks_;
}

}  // namespace estimator_internal
}  // namespace mvis
