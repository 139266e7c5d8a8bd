// IMU intrinsics as estimator states (report Eq. 1-4, Sec. 2.2): blocks, priors, covariance and
// output. The factors that use them are in estimator_window.cpp and estimator_aux.cpp.
#include <ceres/manifold.h>

#include "estimator_impl.h"

namespace mvis {
namespace {

using L = ImuIntrinsicsLayout;

}  // namespace

void Estimator::Impl::initImuIntrinsics() {
  reading_moments.resize(rig.inertial.size());
  for (const auto& sensor : rig.inertial) {
    const bool gyro = sensor.type == InertialType::kGyroscope;
    const bool estimated = options.estimate_imu_intrinsics && sensor.model == ImuModel::kRpng &&
                           !heldByOption(sensor.name, "intrinsics");
    if (!estimated) {
      imu_corrections.emplace_back(sensor.intrinsics);
      imu_intrinsics.push_back(nullptr);
      continue;
    }
    // The readings stay raw: the factors apply the current intrinsics.
    imu_corrections.emplace_back(ImuIntrinsics());
    auto b = std::make_unique<ImuIntrinsicsBlock>();
    intrinsicsToBlock(sensor.intrinsics, b->x);
    std::copy(b->x, b->x + kImuIntrinsicsSize, b->initial);
    b->frame.R0 = sensor.intrinsics.R_IMUtoACC.transpose();
    b->frame.gyro_only = gyro;
    // Priors: the configuration's *_std where positive (Dw = Tw^-1 moves as -Tw to first order
    // near identity), else the options'.
    const auto& sd = sensor.std;
    const auto pick = [](double given, double fallback) { return given > 0.0 ? given : fallback; };
    for (int c = 0; c < 3; ++c) {
      for (int r = 0; r <= c; ++r) {
        const int k = upperIndex(r, c);
        b->prior_std[L::kDw + k] =
            pick(sd ? sd->Tw(r, c) : 0.0, options.imu_scale_misalignment_prior);
        b->prior_std[L::kDa + k] =
            pick(sd ? sd->Ta(r, c) : 0.0, options.imu_scale_misalignment_prior);
      }
    }
    for (int k = 0; k < 9; ++k) {
      b->prior_std[L::kTg + k] =
          pick(sd ? sd->Tg(k / 3, k % 3) : 0.0, options.imu_gravity_sensitivity_prior);
    }
    for (int k = 0; k < 3; ++k) {
      b->prior_std[L::kAccRotation + k] =
          pick(sd ? sd->R_IMUtoACC[k] : 0.0, options.imu_acc_rotation_prior_rad);
    }
    std::vector<int> held;
    const bool gravity =
        options.estimate_gravity_sensitivity && !heldByOption(sensor.name, "gravity_sensitivity");
    for (int k = 0; k < kImuIntrinsicsSize; ++k) {
      const bool tg = k >= L::kTg && k < L::kTg + 9;
      if ((gyro && k >= L::kDa) || (tg && !gravity)) {
        held.push_back(k);
      } else {
        b->free.push_back(k);
      }
    }
    if (!held.empty())
      b->manifold = std::make_unique<ceres::SubsetManifold>(kImuIntrinsicsSize, held);
    imu_intrinsics.push_back(std::move(b));
  }
}

void Estimator::Impl::addImuIntrinsicsBlocks() {
  using Vector24d = Eigen::Matrix<double, kImuIntrinsicsSize, 1>;
  for (auto& b : imu_intrinsics) {
    if (!b) continue;
    problem->AddParameterBlock(b->x, kImuIntrinsicsSize, b->manifold.get());
    problem->AddResidualBlock(
        new ceres::NormalPrior(Eigen::MatrixXd(b->prior_std.cwiseInverse().asDiagonal()),
                               Vector24d(Eigen::Map<const Vector24d>(b->x))),
        nullptr, b->x);
  }
}

void Estimator::Impl::refreshBaseCorrection() {
  if (imu_intrinsics[0]) {
    base_correction =
        ImuCorrection(intrinsicsFromBlock(imu_intrinsics[0]->x, imu_intrinsics[0]->frame.R0));
  }
}

ImuMeasurement Estimator::Impl::propagationReading(const ImuMeasurement& m) const {
  return base_correction.apply(m, false);
}

void Estimator::Impl::propagationBiases(const Eigen::Vector3d& bg, const Eigen::Vector3d& ba,
                                        Eigen::Vector3d* bg_out, Eigen::Vector3d* ba_out) const {
  base_correction.biases(bg, ba, bg_out, ba_out);
}

void Estimator::Impl::imuIntrinsicsCovariance(const ceres::Covariance& cov) {
  for (auto& b : imu_intrinsics) {
    // A block held whole (constant) is not in the computation: it keeps what it had.
    if (!b || problem->IsParameterBlockConstant(b->x)) continue;
    // In the block's own tangent (held directions with the variance they keep), then ambient.
    const Eigen::MatrixXd C = tangentCovariance(cov, b->x);
    const std::vector<int>& idx = b->free;
    Eigen::Matrix<double, kImuIntrinsicsSize, kImuIntrinsicsSize> A =
        Eigen::Matrix<double, kImuIntrinsicsSize, kImuIntrinsicsSize>::Zero();
    for (std::size_t r = 0; r < idx.size(); ++r) {
      for (std::size_t c = 0; c < idx.size(); ++c) A(idx[r], idx[c]) = C(r, c);
    }
    b->covariance = A;
  }
}

void Estimator::Impl::writeImuIntrinsics(Rig* out) const {
  for (std::size_t i = 0; i < imu_intrinsics.size(); ++i) {
    const ImuIntrinsicsBlock* b = imu_intrinsics[i].get();
    if (b == nullptr) continue;
    InertialSensor& s = out->inertial[i];
    s.intrinsics = intrinsicsFromBlock(b->x, b->frame.R0);
    if (!b->covariance) continue;
    // Standard deviations of the rpng matrices to first order: Tw = Dw^-1 moves by
    // -Tw dDw Tw, Ta likewise; R_IMUtoACC = Exp(-theta) R0^T moves on the right by
    // -R0 Jr(-theta) dtheta.
    const auto& C = *b->covariance;
    InertialCalibrationStd sd = s.std ? *s.std : InertialCalibrationStd{};
    const auto upperStd = [&](int offset, const Eigen::Matrix3d& T) {
      Eigen::Matrix3d out = Eigen::Matrix3d::Zero();
      Eigen::Matrix<double, 9, 6> J;
      for (int c = 0; c < 3; ++c) {
        for (int r = 0; r <= c; ++r) {
          Eigen::Matrix3d E = Eigen::Matrix3d::Zero();
          E(r, c) = 1.0;
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
    if (!b->frame.gyro_only) {
      sd.Ta = upperStd(L::kDa, s.intrinsics.Ta);
      for (int k = 0; k < 9; ++k)
        sd.Tg(k / 3, k % 3) = std::sqrt(std::max(C(L::kTg + k, L::kTg + k), 0.0));
      const Eigen::Vector3d theta(b->x + L::kAccRotation);
      const Eigen::Matrix3d J = -b->frame.R0 * lie::rightJacobianSO3(-theta);
      sd.R_IMUtoACC = (J * C.block<3, 3>(L::kAccRotation, L::kAccRotation) * J.transpose())
                          .diagonal()
                          .cwiseMax(0.0)
                          .cwiseSqrt();
    }
    s.std = sd;
  }
}

}  // namespace mvis
