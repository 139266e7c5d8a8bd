#include "mvis/factors/aux_imu_factor.h"

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
// speed_bias_j 21-29, aux_i 30-38 (or 30-35), aux_j 39-47 (or 36-41), [dtheta_e, dp_e] 48-53,
// t_d 54, gravity 55-57, and the intrinsics 58-81 when they are estimated.
constexpr int kDim = 58;
using Jet = ceres::Jet<double, kDim>;
using IntrinsicsJet = ceres::Jet<double, kDim + kImuIntrinsicsSize>;
constexpr int kExtrinsicJet = 48, kTimeOffsetJet = 54, kGravityJet = 55, kIntrinsicsJet = 58;

std::vector<tangent_jet::BlockLayout> layoutOf(AuxImuModel model, bool intrinsics) {
  const int a = AuxImuFactor::auxBlockSize(model);
  std::vector<tangent_jet::BlockLayout> layout = {{0, 6, 7},
                                                  {6, 9, 9},
                                                  {15, 6, 7},
                                                  {21, 9, 9},
                                                  {30, a, a},
                                                  {30 + a, a, a},
                                                  {kExtrinsicJet, 6, 7},
                                                  {kTimeOffsetJet, 1, 1},
                                                  {kGravityJet, 3, 3}};
  if (intrinsics) layout.push_back({kIntrinsicsJet, kImuIntrinsicsSize, kImuIntrinsicsSize});
  return layout;
}

}  // namespace

AuxImuFactor::AuxImuFactor(AuxImuModel model, std::shared_ptr<const ImuPreintegration> pre,
                           double time_offset0_i, double time_offset0_j, const BaseMotion& base_i,
                           const BaseMotion& base_j)
    : model_(model),
      pre_(std::move(pre)),
      base_i_(base_i),
      base_j_(base_j),
      time_offset0_i_(time_offset0_i),
      time_offset0_j_(time_offset0_j) {
  set_num_residuals(15);
  auto* sizes = mutable_parameter_block_sizes();
  for (const auto& l : layoutOf(model_, false)) sizes->push_back(l.ambient);
  sqrt_information_ = sqrtInformation<15>(pre_->covariance());
}

AuxImuFactor::AuxImuFactor(AuxImuModel model, std::shared_ptr<const ImuPreintegration> pre,
                           double time_offset0_i, double time_offset0_j, const BaseMotion& base_i,
                           const BaseMotion& base_j, const ImuIntrinsicsFrame& frame,
                           IntrinsicsLinearization mode, const double* intrinsics0)
    : AuxImuFactor(model, std::move(pre), time_offset0_i, time_offset0_j, base_i, base_j) {
  intrinsics_ = true;
  mode_ = mode;
  frame_ = frame;
  mutable_parameter_block_sizes()->push_back(kImuIntrinsicsSize);
  if (mode_ == IntrinsicsLinearization::kFixed) {
    fixed_ =
        reintegrate(pre_->samples(),
                    deltaVariables(pre_->biasGyro().data(), pre_->biasAccel().data(), intrinsics0),
                    frame_, true);
  }
}

template <typename T>
void AuxImuFactor::residual(double const* const* parameters, const ImuDeltas& d, T* out) const {
  using tangent_jet::perturbRotation;
  using tangent_jet::perturbScalar;
  using tangent_jet::perturbVector;
  const ImuPreintegration& pre = *pre_;
  const bool velocity_state = model_ == AuxImuModel::kVelocityState;
  const int a = auxBlockSize(model_);

  const Mat3<T> R_i = perturbRotation<T>(poseRotation(parameters[0]), 0);
  const Vec3<T> p_i = perturbVector<T>(parameters[0] + 4, 3);
  const Vec3<T> v_i = perturbVector<T>(parameters[1], 6);
  const Vec3<T> bg_i = perturbVector<T>(parameters[1] + 3, 9);
  const Vec3<T> ba_i = perturbVector<T>(parameters[1] + 6, 12);
  const Mat3<T> R_j = perturbRotation<T>(poseRotation(parameters[2]), 15);
  const Vec3<T> p_j = perturbVector<T>(parameters[2] + 4, 18);
  const Vec3<T> v_j = perturbVector<T>(parameters[3], 21);
  const Vec3<T> bg_j = perturbVector<T>(parameters[3] + 3, 24);
  const Vec3<T> ba_j = perturbVector<T>(parameters[3] + 6, 27);
  const int bias_at = velocity_state ? 3 : 0;  // b^A_g within the aux block
  const Vec3<T> abg_i = perturbVector<T>(parameters[4] + bias_at, 30 + bias_at);
  const Vec3<T> aba_i = perturbVector<T>(parameters[4] + bias_at + 3, 33 + bias_at);
  const Vec3<T> abg_j = perturbVector<T>(parameters[5] + bias_at, 30 + a + bias_at);
  const Mat3<T> R_AI = perturbRotation<T>(poseRotation(parameters[6]), kExtrinsicJet);
  const Vec3<T> p_AI = perturbVector<T>(parameters[6] + 4, kExtrinsicJet + 3);
  const T t_d = perturbScalar<T>(parameters[7][0], kTimeOffsetJet);
  const Vec3<T> g = perturbVector<T>(parameters[8], kGravityJet);

  const T delta_i = t_d - T(time_offset0_i_), delta_j = t_d - T(time_offset0_j_);
  Mat3<T> Rs_i, Rs_j;
  Vec3<T> ps_i, ps_j;
  shiftBasePose<T>(base_i_, R_i, p_i, v_i, bg_i, ba_i, g, delta_i, &Rs_i, &ps_i);
  shiftBasePose<T>(base_j_, R_j, p_j, v_j, bg_j, ba_j, g, delta_j, &Rs_j, &ps_j);
  const Mat3<T> R_IA = R_AI.transpose();
  const Mat3<T> RA_i = Rs_i * R_IA;
  const Mat3<T> RA_j = Rs_j * R_IA;
  const Vec3<T> pA_i = ps_i - RA_i * p_AI;
  const Vec3<T> pA_j = ps_j - RA_j * p_AI;

  Vec3<T> vA_i, vA_j;
  if (velocity_state) {
    vA_i = perturbVector<T>(parameters[4], 30);
    vA_j = perturbVector<T>(parameters[5], 30 + a);
  } else {
    // Eq. 78 with the base velocity carried to t_k + delta and the aux gyroscope taken as exact.
    const Vec3<T> p_IA = -(R_IA * p_AI);
    const Vec3<T> w_i = R_IA * (pre.samples().front().gyro.cast<T>() - abg_i);
    const Vec3<T> w_j = R_IA * (pre.samples().back().gyro.cast<T>() - abg_j);
    vA_i = v_i + (R_i * (base_i_.accel.cast<T>() - ba_i) + g) * delta_i +
           Rs_i * tangent_jet::hatT<T>(w_i) * p_IA;
    vA_j = v_j + (R_j * (base_j_.accel.cast<T>() - ba_j) + g) * delta_j +
           Rs_j * tangent_jet::hatT<T>(w_j) * p_IA;
  }

  Eigen::Matrix<T, kDeltaVariables, 1> x;
  x.template head<3>() = abg_i;
  x.template segment<3>(3) = aba_i;
  for (int k = 0; k < kImuIntrinsicsSize; ++k) {
    x[6 + k] = intrinsics_
                   ? tangent_jet::perturbScalarIfPresent<T>(parameters[9][k], kIntrinsicsJet + k)
                   : T(d.x0[6 + k]);
  }
  const CorrectedDeltas<T> deltas = correctDeltas<T>(d, x);
  const Mat3<T>& dR = deltas.dR;
  const Vec3<T>& dp = deltas.dp;
  const Vec3<T>& dv = deltas.dv;
  const T dT(pre.duration());
  using P = ImuPreintegration;

  Eigen::Matrix<T, 15, 1> r;
  r.template segment<3>(P::kRotation) =
      tangent_jet::logT<T>(Mat3<T>(dR.transpose() * RA_i.transpose() * RA_j));
  r.template segment<3>(P::kPosition) =
      RA_i.transpose() * (pA_j - pA_i - vA_i * dT - g * (T(0.5) * dT * dT)) - dp;
  r.template segment<3>(P::kVelocity) = RA_i.transpose() * (vA_j - vA_i - g * dT) - dv;
  r.template segment<3>(P::kBiasGyro) = abg_j - abg_i;
  r.template segment<3>(P::kBiasAccel) =
      perturbVector<T>(parameters[5] + bias_at + 3, 33 + a + bias_at) - aba_i;
  Eigen::Map<Eigen::Matrix<T, 15, 1>>{out} = r;  // whitened in Evaluate
}

bool AuxImuFactor::Evaluate(double const* const* parameters, double* residuals,
                            double** jacobians) const {
  const int bias_at = model_ == AuxImuModel::kVelocityState ? 3 : 0;
  ImuDeltas local;
  const ImuDeltas* d =
      &factorDeltas(*pre_, intrinsics_, mode_, fixed_,
                    deltaVariables(parameters[4] + bias_at, parameters[4] + bias_at + 3,
                                   intrinsics_ ? parameters[9] : nullptr),
                    frame_, jacobians != nullptr, &local);
  if (jacobians == nullptr) {
    residual<double>(parameters, *d, residuals);
  } else if (intrinsics_) {
    IntrinsicsJet r[15];
    residual<IntrinsicsJet>(parameters, *d, r);
    tangent_jet::writeJacobians(r, 15, layoutOf(model_, true), residuals, jacobians);
  } else {
    Jet r[15];
    residual<Jet>(parameters, *d, r);
    tangent_jet::writeJacobians(r, 15, layoutOf(model_, false), residuals, jacobians);
  }
  whiten<15>(sqrt_information_, parameter_block_sizes(), residuals, jacobians);
  return true;
}

}  // namespace mvis
