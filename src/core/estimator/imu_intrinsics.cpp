#include "imu_intrinsics.h"

#include <ceres/manifold.h>
#include <ceres/normal_prior.h>

#include "mvis/common/lie.h"

namespace mvis {
namespace estimator_internal {
namespace {

using L = ImuIntrinsicsLayout;

}  // namespace

ImuIntrinsicsBlocks::ImuIntrinsicsBlocks(const Rig& rig, const EstimatorOptions& options) {
  for (const auto& sensor : rig.inertial) {
    names_.push_back(sensor.name);
    const bool gyro = sensor.type == InertialType::kGyroscope;
    const bool kalibr = sensor.model == ImuModel::kKalibr;
    const bool estimated = options.estimate_imu_intrinsics &&
                           sensor.model != ImuModel::kCalibrated &&
                           !heldByOption(options, sensor.name, "intrinsics");
    if (!estimated) {
      arrival_.emplace_back(sensor.intrinsics);
      blocks_.push_back(nullptr);
      continue;
    }
    // The readings stay raw: the factors apply the current intrinsics.
    arrival_.emplace_back(ImuIntrinsics());
    auto b = std::make_unique<ImuIntrinsicsBlock>();
    intrinsicsToBlock(sensor.intrinsics, b->x, kalibr);
    std::copy(b->x, b->x + kImuIntrinsicsSize, b->initial);
    // The rotation the model estimates: the accelerometer's (rpng) or the gyroscope's (kalibr).
    b->frame.R0 =
        (kalibr ? sensor.intrinsics.R_IMUtoGYRO : sensor.intrinsics.R_IMUtoACC).transpose();
    b->frame.gyro_only = gyro;
    b->frame.kalibr = kalibr;
    // Priors: the configuration's *_std where positive (Dw = Tw^-1 moves as -Tw to first order
    // near identity), else the options'.
    const auto& sd = sensor.std;
    const auto pick = [](double given, double fallback) { return given > 0.0 ? given : fallback; };
    for (int c = 0; c < 3; ++c) {
      for (int r = 0; r <= c; ++r) {
        // The block's entry k is D(r, c), kalibr's lower-triangular D(c, r).
        const int k = upperIndex(r, c);
        const int row = kalibr ? c : r, col = kalibr ? r : c;
        b->prior_std[L::kDw + k] =
            pick(sd ? sd->Tw(row, col) : 0.0, options.imu_scale_misalignment_prior);
        b->prior_std[L::kDa + k] =
            pick(sd ? sd->Ta(row, col) : 0.0, options.imu_scale_misalignment_prior);
      }
    }
    for (int k = 0; k < 9; ++k) {
      b->prior_std[L::kTg + k] =
          pick(sd ? sd->Tg(k / 3, k % 3) : 0.0, options.imu_gravity_sensitivity_prior);
    }
    for (int k = 0; k < 3; ++k) {
      b->prior_std[L::kAccRotation + k] =
          pick(sd ? (kalibr ? sd->R_IMUtoGYRO[k] : sd->R_IMUtoACC[k]) : 0.0,
               options.imu_acc_rotation_prior_rad);
    }
    std::vector<int> held;
    const bool gravity = options.estimate_gravity_sensitivity &&
                         !heldByOption(options, sensor.name, "gravity_sensitivity");
    for (int k = 0; k < kImuIntrinsicsSize; ++k) {
      // A gyroscope has Dw and Tg (against the specific force the base IMU reads, brought to
      // it: aux_sensors.h); no Da, and its rotation is its extrinsic's.
      const bool tg = k >= L::kTg && k < L::kTg + 9;
      if ((gyro && k >= L::kDa && !tg) || (tg && !gravity)) {
        held.push_back(k);
      } else {
        b->free.push_back(k);
      }
    }
    if (!held.empty())
      b->manifold = std::make_unique<ceres::SubsetManifold>(kImuIntrinsicsSize, held);
    blocks_.push_back(std::move(b));
  }
}

void ImuIntrinsicsBlocks::addTo(ceres::Problem* problem, const TrustedCalibration& trusted) {
  using Vector24d = Eigen::Matrix<double, kImuIntrinsicsSize, 1>;
  for (auto& b : blocks_) {
    if (!b) continue;
    problem->AddParameterBlock(b->x, kImuIntrinsicsSize, b->manifold.get());
    if (trusted.covers(b->x)) continue;  // the trusted calibration's joint prior stands instead
    problem->AddResidualBlock(
        new ceres::NormalPrior(Eigen::MatrixXd(b->prior_std.cwiseInverse().asDiagonal()),
                               Vector24d(Eigen::Map<const Vector24d>(b->x))),
        nullptr, b->x);
  }
}

std::vector<TrustedCalibration::Block> ImuIntrinsicsBlocks::trustedBlocks(
    const ceres::Problem* problem) {
  std::vector<TrustedCalibration::Block> out;
  for (std::size_t i = 0; i < blocks_.size(); ++i) {
    auto& b = blocks_[i];
    if (!b) continue;
    out.push_back(TrustedCalibration::make(names_[i] + " intrinsics", b->x, kImuIntrinsicsSize,
                                           b->manifold.get(), problem, true));
  }
  return out;
}

void ImuIntrinsicsBlocks::refreshBase() {
  if (blocks_[0]) base_ = ImuCorrection(intrinsicsFromBlock(blocks_[0]->x, blocks_[0]->frame));
}

std::optional<ImuCorrection> ImuIntrinsicsBlocks::estimatedCorrection(std::size_t i) const {
  if (!blocks_[i]) return std::nullopt;
  return ImuCorrection(intrinsicsFromBlock(blocks_[i]->x, blocks_[i]->frame));
}

bool ImuIntrinsicsBlocks::isBlock(const double* x) const {
  for (const auto& b : blocks_) {
    if (b && b->x == x) return true;
  }
  return false;
}

void ImuIntrinsicsBlocks::covarianceBlocks(
    const ceres::Problem& problem,
    std::vector<std::pair<const double*, const double*>>* blocks) const {
  for (const auto& b : blocks_) {
    if (b && !problem.IsParameterBlockConstant(b->x)) blocks->emplace_back(b->x, b->x);
  }
}
void ImuIntrinsicsBlocks::updateCovariance(const ceres::Problem& problem,
                                           const TangentCovariance& tangent) {
  for (auto& b : blocks_) {
    if (!b) continue;
    // A block held whole (constant: by the motion) is not in the computation: it keeps what it
    // had, or before any covariance its prior's (the uncertainty it is held at).
    if (problem.IsParameterBlockConstant(b->x)) {
      if (!b->covariance) {
        Eigen::Matrix<double, kImuIntrinsicsSize, kImuIntrinsicsSize> A =
            Eigen::Matrix<double, kImuIntrinsicsSize, kImuIntrinsicsSize>::Zero();
        for (const int e : b->free) A(e, e) = b->prior_std[e] * b->prior_std[e];
        b->covariance = A;
      }
      continue;
    }
    // In the block's own tangent (held directions with the variance they keep), then ambient.
    const Eigen::MatrixXd C = tangent(b->x);
    const std::vector<int>& idx = b->free;
    Eigen::Matrix<double, kImuIntrinsicsSize, kImuIntrinsicsSize> A =
        Eigen::Matrix<double, kImuIntrinsicsSize, kImuIntrinsicsSize>::Zero();
    for (std::size_t r = 0; r < idx.size(); ++r) {
      for (std::size_t c = 0; c < idx.size(); ++c) A(idx[r], idx[c]) = C(r, c);
    }
    b->covariance = A;
  }
}

void ImuIntrinsicsBlocks::write(Rig* out) const {
  for (std::size_t i = 0; i < blocks_.size(); ++i) {
    const ImuIntrinsicsBlock* b = blocks_[i].get();
    if (b == nullptr) continue;
    InertialSensor& s = out->inertial[i];
    s.intrinsics = intrinsicsFromBlock(b->x, b->frame);
    if (!b->covariance) continue;
    // Standard deviations of the model's matrices to first order: Tw = Dw^-1 moves by
    // -Tw dDw Tw, Ta likewise; R_IMUtoACC (kalibr: R_IMUtoGYRO) = Exp(-theta) R0^T moves on the
    // right by -R0 Jr(-theta) dtheta.
    const bool kalibr = b->frame.kalibr;
    const auto& C = *b->covariance;
    InertialCalibrationStd sd = s.std ? *s.std : InertialCalibrationStd{};
    const auto upperStd = [&](int offset, const Eigen::Matrix3d& T) {
      Eigen::Matrix3d out = Eigen::Matrix3d::Zero();
      Eigen::Matrix<double, 9, 6> J;
      for (int c = 0; c < 3; ++c) {
        for (int r = 0; r <= c; ++r) {
          Eigen::Matrix3d E = Eigen::Matrix3d::Zero();
          (kalibr ? E(c, r) : E(r, c)) = 1.0;
          const Eigen::Matrix3d dT = -T * E * T;
          J.col(upperIndex(r, c)) = Eigen::Map<const Eigen::Matrix<double, 9, 1>>(dT.data());
        }
      }
      const Eigen::Matrix<double, 9, 1> var =
          (J * C.block<6, 6>(offset, offset) * J.transpose()).diagonal();
      Eigen::Map<Eigen::Matrix<double, 9, 1>>(out.data()) = var.cwiseMax(0.0).cwiseSqrt();
      return out;
    };
    sd.Tw = upperStd(L::kDw, s.intrinsics.Tw);
    for (int k = 0; k < 9; ++k)
      sd.Tg(k / 3, k % 3) = std::sqrt(std::max(C(L::kTg + k, L::kTg + k), 0.0));
    if (!b->frame.gyro_only) {
      sd.Ta = upperStd(L::kDa, s.intrinsics.Ta);
      const Eigen::Vector3d theta(b->x + L::kAccRotation);
      const Eigen::Matrix3d J = -b->frame.R0 * lie::rightJacobianSO3(-theta);
      (kalibr ? sd.R_IMUtoGYRO : sd.R_IMUtoACC) =
          (J * C.block<3, 3>(L::kAccRotation, L::kAccRotation) * J.transpose())
              .diagonal()
              .cwiseMax(0.0)
              .cwiseSqrt();
    }
    s.std = sd;
  }
}

Eigen::VectorXd ImuIntrinsicsBlocks::latestStd(const double* x) const {
  for (const auto& b : blocks_) {
    if (!b || x != b->x) continue;
    Eigen::VectorXd sd(b->free.size());
    for (std::size_t k = 0; k < b->free.size(); ++k) {
      const int e = b->free[k];
      sd[k] = b->covariance && (*b->covariance)(e, e) > 0.0 ? std::sqrt((*b->covariance)(e, e))
                                                            : b->prior_std[e];
    }
    return sd;
  }
  return Eigen::VectorXd();
}

std::optional<Eigen::MatrixXd> ImuIntrinsicsBlocks::latestCovariance(const double* x) const {
  for (const auto& b : blocks_) {
    if (!b || x != b->x || !b->covariance) continue;
    const auto n = static_cast<int>(b->free.size());
    Eigen::MatrixXd C(n, n);
    for (int r = 0; r < n; ++r) {
      for (int c = 0; c < n; ++c) C(r, c) = (*b->covariance)(b->free[r], b->free[c]);
    }
    return C;
  }
  return std::nullopt;
}

void ImuIntrinsicsBlocks::setValues(const Rig& start) {
  for (std::size_t i = 0; i < blocks_.size(); ++i) {
    ImuIntrinsicsBlock* b = blocks_[i].get();
    if (b == nullptr) continue;
    const ImuIntrinsics& in = start.inertial[i].intrinsics;
    intrinsicsToBlock(in, b->x, b->frame.kalibr);
    // intrinsicsToBlock puts theta = 0 at `in`'s own rotation; the block's rotation is relative
    // to R0 (the configured one): R^T = R0 Exp(theta), so theta = Log(R0^T R^T).
    const Eigen::Matrix3d R = b->frame.kalibr ? in.R_IMUtoGYRO : in.R_IMUtoACC;
    Eigen::Map<Eigen::Vector3d>(b->x + L::kAccRotation) =
        lie::logSO3(b->frame.R0.transpose() * R.transpose());
  }
  refreshBase();
}

}  // namespace estimator_internal
}  // namespace mvis
