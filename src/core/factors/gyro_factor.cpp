#include "mvis/factors/gyro_factor.h"

#include "base_motion_shift.h"
#include "delta_correction.h"
#include "mvis/factors/state_blocks.h"
#include "../common/tangent_jet.h"
#include "whitening.h"

namespace mvis {
namespace {

using tangent_jet::Mat3;
using tangent_jet::Vec3;

// Jet directions: [dtheta_i, dp_i] 0-5, speed_bias_i 6-14, [dtheta_j, dp_j] 15-20,
// speed_bias_j 21-29, bias_i 30-32, bias_j 33-35, extrinsic dtheta 36-38, t_d 39, and Dw 40-45,
// Tg 46-54 when the intrinsics are estimated (the rest of that block does not enter).
constexpr int kDim = 40, kDwJet = 40, kTgJet = 46;
using Jet = ceres::Jet<double, kDim>;
using IntrinsicsJet = ceres::Jet<double, kDim + 15>;
const std::vector<tangent_jet::BlockLayout> kLayout = {
    {0, 6, 7}, {6, 9, 9}, {15, 6, 7}, {21, 9, 9}, {30, 3, 3}, {33, 3, 3}, {36, 3, 4}, {39, 1, 1}};

// Writes the Dw and Tg columns of the intrinsics block's Jacobian (the rest zero).
void writeIntrinsicsJacobian(const IntrinsicsJet* r, double* jacobian) {
  using L = ImuIntrinsicsLayout;
  for (int i = 0; i < 6; ++i) {
    double* row = jacobian + kImuIntrinsicsSize * i;
    std::fill(row, row + kImuIntrinsicsSize, 0.0);
    for (int k = 0; k < 6; ++k) row[L::kDw + k] = r[i].v[kDwJet + k];
    for (int k = 0; k < 9; ++k) row[L::kTg + k] = r[i].v[kTgJet + k];
  }
}

}  // namespace

GyroFactor::GyroFactor(std::shared_ptr<const ImuPreintegration> pre, double time_offset0_i,
                       double time_offset0_j, const BaseMotion& base_i, const BaseMotion& base_j)
    : pre_(std::move(pre)),
      time_offset0_i_(time_offset0_i),
      time_offset0_j_(time_offset0_j),
      base_i_(base_i),
      base_j_(base_j) {
  set_num_residuals(6);
  auto* sizes = mutable_parameter_block_sizes();
  for (const auto& l : kLayout) sizes->push_back(l.ambient);
  using P = ImuPreintegration;
  Eigen::Matrix<double, 6, 6> cov;
  const auto& C = pre_->covariance();
  cov.topLeftCorner<3, 3>() = C.block<3, 3>(P::kRotation, P::kRotation);
  cov.topRightCorner<3, 3>() = C.block<3, 3>(P::kRotation, P::kBiasGyro);
  cov.bottomLeftCorner<3, 3>() = C.block<3, 3>(P::kBiasGyro, P::kRotation);
  cov.bottomRightCorner<3, 3>() = C.block<3, 3>(P::kBiasGyro, P::kBiasGyro);
  sqrt_information_ = sqrtInformation<6>(cov);
}

GyroFactor::GyroFactor(std::shared_ptr<const ImuPreintegration> pre, double time_offset0_i,
                       double time_offset0_j, const BaseMotion& base_i, const BaseMotion& base_j,
                       const ImuIntrinsicsFrame& frame, IntrinsicsLinearization mode,
                       const double* intrinsics0)
    : GyroFactor(std::move(pre), time_offset0_i, time_offset0_j, base_i, base_j) {
  intrinsics_ = true;
  frame_ = frame;
  frame_.gyro_only = true;
  mode_ = mode;
  mutable_parameter_block_sizes()->push_back(kImuIntrinsicsSize);
  if (mode_ == IntrinsicsLinearization::kFixed) {
    fixed_ =
        reintegrate(pre_->samples(), deltaVariables(pre_->biasGyro().data(), nullptr, intrinsics0),
                    frame_, true);
  }
}

template <typename T>
void GyroFactor::residual(double const* const* parameters, const ImuDeltas& d, T* out) const {
  using tangent_jet::perturbRotation;
  using tangent_jet::perturbScalar;
  using tangent_jet::perturbVector;
  const Mat3<T> R_i = perturbRotation<T>(poseRotation(parameters[0]), 0);
  const Vec3<T> bg_i = perturbVector<T>(parameters[1] + 3, 9);
  const Mat3<T> R_j = perturbRotation<T>(poseRotation(parameters[2]), 15);
  const Vec3<T> bg_j = perturbVector<T>(parameters[3] + 3, 24);
  const Vec3<T> abg_i = perturbVector<T>(parameters[4], 30);
  const Vec3<T> abg_j = perturbVector<T>(parameters[5], 33);
  const Mat3<T> R_AI = perturbRotation<T>(
      Eigen::Quaterniond(Eigen::Map<const Eigen::Quaterniond>(parameters[6])), 36);
  const T t_d = perturbScalar<T>(parameters[7][0], 39);
  const T delta_i = t_d - T(time_offset0_i_), delta_j = t_d - T(time_offset0_j_);
  const Vec3<T> unused = Vec3<T>::Zero();
  Mat3<T> Rs_i, Rs_j;
  shiftBasePose<T>(base_i_, R_i, unused, unused, bg_i, unused, unused, delta_i, &Rs_i, nullptr);
  shiftBasePose<T>(base_j_, R_j, unused, unused, bg_j, unused, unused, delta_j, &Rs_j, nullptr);
  const Mat3<T> RA_i = Rs_i * R_AI.transpose();
  const Mat3<T> RA_j = Rs_j * R_AI.transpose();
  Eigen::Matrix<T, kDeltaVariables, 1> x;
  for (int k = 0; k < kDeltaVariables; ++k) x[k] = T(d.x0[k]);
  x.template head<3>() = abg_i;
  for (int k = 0; intrinsics_ && k < 6; ++k) {
    x[6 + ImuIntrinsicsLayout::kDw + k] = tangent_jet::perturbScalarIfPresent<T>(
        parameters[8][ImuIntrinsicsLayout::kDw + k], kDwJet + k);
  }
  for (int k = 0; intrinsics_ && k < 9; ++k) {
    x[6 + ImuIntrinsicsLayout::kTg + k] = tangent_jet::perturbScalarIfPresent<T>(
        parameters[8][ImuIntrinsicsLayout::kTg + k], kTgJet + k);
  }
  const Mat3<T> dR = correctDeltas<T>(d, x).dR;
  Eigen::Matrix<T, 6, 1> r;
  r.template head<3>() = tangent_jet::logT<T>(Mat3<T>(dR.transpose() * RA_i.transpose() * RA_j));
  r.template tail<3>() = abg_j - abg_i;
  Eigen::Map<Eigen::Matrix<T, 6, 1>>{out} = r;  // whitened in Evaluate
}

bool GyroFactor::Evaluate(double const* const* parameters, double* residuals,
                          double** jacobians) const {
  ImuDeltas local;
  const ImuDeltas* d =
      &factorDeltas(*pre_, intrinsics_, mode_, fixed_,
                    deltaVariables(parameters[4], nullptr, intrinsics_ ? parameters[8] : nullptr),
                    frame_, jacobians != nullptr, &local);
  if (jacobians == nullptr) {
    residual<double>(parameters, *d, residuals);
  } else if (intrinsics_) {
    IntrinsicsJet r[6];
    residual<IntrinsicsJet>(parameters, *d, r);
    tangent_jet::writeJacobians(r, 6, kLayout, residuals, jacobians);
    if (jacobians[8] != nullptr) writeIntrinsicsJacobian(r, jacobians[8]);
  } else {
    Jet r[6];
    residual<Jet>(parameters, *d, r);
    tangent_jet::writeJacobians(r, 6, kLayout, residuals, jacobians);
  }
  whiten<6>(sqrt_information_, parameter_block_sizes(), residuals, jacobians);
  return true;
}

}  // namespace mvis
