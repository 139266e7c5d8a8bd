#include "mvis/factors/imu_factor.h"

#include "mvis/common/lie.h"
#include "mvis/factors/state_blocks.h"
#include "whitening.h"

namespace mvis {

ImuFactor::ImuFactor(std::shared_ptr<const ImuPreintegration> preintegration)
    : preintegration_(std::move(preintegration)),
      sqrt_information_(sqrtInformation<15>(preintegration_->covariance())) {
  set_num_residuals(15);
  *mutable_parameter_block_sizes() = {kPoseSize, kSpeedBiasSize, kPoseSize, kSpeedBiasSize,
                                      kGravitySize};
}

ImuFactor::ImuFactor(std::shared_ptr<const ImuPreintegration> preintegration,
                     const ImuIntrinsicsFrame& frame, IntrinsicsLinearization mode,
                     const double* intrinsics0)
    : ImuFactor(std::move(preintegration)) {
  intrinsics_ = true;
  frame_ = frame;
  mode_ = mode;
  mutable_parameter_block_sizes()->push_back(kImuIntrinsicsSize);
  if (mode_ == IntrinsicsLinearization::kFixed) {
    const ImuPreintegration& pre = *preintegration_;
    fixed_ = reintegrate(pre.samples(),
                         deltaVariables(pre.biasGyro().data(), pre.biasAccel().data(), intrinsics0),
                         frame_, true);
  }
}

bool ImuFactor::Evaluate(double const* const* parameters, double* residuals,
                         double** jacobians) const {
  using Matrix3 = Eigen::Matrix3d;
  using Vector3 = Eigen::Vector3d;
  const ImuPreintegration& pre = *preintegration_;
  constexpr int O_R = ImuPreintegration::kRotation, O_P = ImuPreintegration::kPosition,
                O_V = ImuPreintegration::kVelocity, O_BG = ImuPreintegration::kBiasGyro,
                O_BA = ImuPreintegration::kBiasAccel;

  const Eigen::Quaterniond q_i = poseRotation(parameters[0]);
  const Vector3 p_i(parameters[0] + 4);
  const Vector3 v_i(parameters[1]), bg_i(parameters[1] + 3), ba_i(parameters[1] + 6);
  const Eigen::Quaterniond q_j = poseRotation(parameters[2]);
  const Vector3 p_j(parameters[2] + 4);
  const Vector3 v_j(parameters[3]), bg_j(parameters[3] + 3), ba_j(parameters[3] + 6);
  const Vector3 g(parameters[4]);
  const double T = pre.duration();

  // The deltas at x = [b_g,i b_a,i intrinsics].
  const ImuDeltas::Vector30d x =
      deltaVariables(parameters[1] + 3, parameters[1] + 6, intrinsics_ ? parameters[5] : nullptr);
  ImuDeltas local;
  const ImuDeltas* d =
      &factorDeltas(pre, intrinsics_, mode_, fixed_, x, frame_, jacobians != nullptr, &local);
  const Eigen::Matrix<double, 9, 1> lin = d->J * (x - d->x0);
  const Vector3 phi = lin.head<3>();
  const Matrix3 dR = d->dR * lie::expSO3(phi);

  const Matrix3 R_i = q_i.toRotationMatrix();
  const Matrix3 R_j = q_j.toRotationMatrix();
  const Matrix3 Rt_i = R_i.transpose();
  const Matrix3 E = dR.transpose() * Rt_i * R_j;
  const Vector3 e = lie::logSO3(E);
  const Vector3 dp_world = p_j - p_i - v_i * T - 0.5 * g * T * T;
  const Vector3 dv_world = v_j - v_i - g * T;
  const Vector3 a_p = Rt_i * dp_world;
  const Vector3 a_v = Rt_i * dv_world;

  Eigen::Matrix<double, 15, 1> r;
  r.segment<3>(O_R) = e;
  r.segment<3>(O_P) = a_p - (d->dp + lin.segment<3>(3));
  r.segment<3>(O_V) = a_v - (d->dv + lin.segment<3>(6));
  r.segment<3>(O_BG) = bg_j - bg_i;
  r.segment<3>(O_BA) = ba_j - ba_i;

  // With the intrinsics estimated the whitening is the raw readings' covariance seen through
  // the current corrections (imu_factor.h): W = L S^-1, S^-1 = diag(G^-1, M^-1, M^-1, I, I).
  const Eigen::Matrix<double, 15, 15>& sqrt_info = sqrt_information_;
  Eigen::Matrix<double, 15, 15> W = sqrt_info;
  Eigen::Matrix<double, 9, kImuIntrinsicsSize> K;  // d(S^-1 r)/d intrinsics at fixed r
  if (intrinsics_) {
    Eigen::Matrix<double, 9, 1> scaled;
    Matrix3 G_inv, M_inv;
    noiseMapInverses(parameters[5], frame_, r.head<9>(), &scaled,
                     jacobians != nullptr ? &K : nullptr, &G_inv, &M_inv);
    r.head<9>() = scaled;
    W.middleCols<3>(O_R) = sqrt_info.middleCols<3>(O_R) * G_inv;
    W.middleCols<3>(O_P) = sqrt_info.middleCols<3>(O_P) * M_inv;
    W.middleCols<3>(O_V) = sqrt_info.middleCols<3>(O_V) * M_inv;
  }
  Eigen::Map<Eigen::Matrix<double, 15, 1>>{residuals} = sqrt_info * r;
  if (jacobians == nullptr) return true;

  const Matrix3 Jr_inv_e = lie::rightJacobianInvSO3(e);
  // The deltas' rows of d r / d x (bias columns 0-5, intrinsics 6-29).
  Eigen::Matrix<double, 9, kDeltaVariables> Dx;
  Dx.topRows<3>() = -Jr_inv_e * E.transpose() * lie::rightJacobianSO3(phi) * d->J.topRows<3>();
  Dx.bottomRows<6>() = -d->J.bottomRows<6>();

  if (jacobians[0] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 15, 7, Eigen::RowMajor>> out(jacobians[0]);
    Eigen::Matrix<double, 15, 6> D = Eigen::Matrix<double, 15, 6>::Zero();
    D.block<3, 3>(O_R, 0) = -Jr_inv_e * R_j.transpose() * R_i;
    D.block<3, 3>(O_P, 0) = lie::hat(a_p);
    D.block<3, 3>(O_P, 3) = -Rt_i;
    D.block<3, 3>(O_V, 0) = lie::hat(a_v);
    out.setZero();
    out.leftCols<6>() = W * D;
  }
  if (jacobians[1] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 15, 9, Eigen::RowMajor>> out(jacobians[1]);
    Eigen::Matrix<double, 15, 9> D = Eigen::Matrix<double, 15, 9>::Zero();
    D.block<9, 6>(O_R, 3) = Dx.leftCols<6>();
    D.block<3, 3>(O_P, 0) = -Rt_i * T;
    D.block<3, 3>(O_V, 0) = -Rt_i;
    D.block<3, 3>(O_BG, 3) = -Matrix3::Identity();
    D.block<3, 3>(O_BA, 6) = -Matrix3::Identity();
    out = W * D;
  }
  if (jacobians[2] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 15, 7, Eigen::RowMajor>> out(jacobians[2]);
    Eigen::Matrix<double, 15, 6> D = Eigen::Matrix<double, 15, 6>::Zero();
    D.block<3, 3>(O_R, 0) = Jr_inv_e;
    D.block<3, 3>(O_P, 3) = Rt_i;
    out.setZero();
    out.leftCols<6>() = W * D;
  }
  if (jacobians[3] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 15, 9, Eigen::RowMajor>> out(jacobians[3]);
    Eigen::Matrix<double, 15, 9> D = Eigen::Matrix<double, 15, 9>::Zero();
    D.block<3, 3>(O_V, 0) = Rt_i;
    D.block<3, 3>(O_BG, 3) = Matrix3::Identity();
    D.block<3, 3>(O_BA, 6) = Matrix3::Identity();
    out = W * D;
  }
  if (jacobians[4] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 15, 3, Eigen::RowMajor>> out(jacobians[4]);
    Eigen::Matrix<double, 15, 3> D = Eigen::Matrix<double, 15, 3>::Zero();
    D.block<3, 3>(O_P, 0) = -0.5 * Rt_i * T * T;
    D.block<3, 3>(O_V, 0) = -Rt_i * T;
    out = W * D;
  }
  if (intrinsics_ && jacobians[5] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 15, kImuIntrinsicsSize, Eigen::RowMajor>> out(jacobians[5]);
    Eigen::Matrix<double, 15, kImuIntrinsicsSize> D =
        Eigen::Matrix<double, 15, kImuIntrinsicsSize>::Zero();
    D.topRows<9>() = Dx.rightCols<kImuIntrinsicsSize>();
    out = W * D + sqrt_info.leftCols<9>() * K;
  }
  return true;
}

}  // namespace mvis
