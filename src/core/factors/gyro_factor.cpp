#include "mvis/factors/gyro_factor.h"

#include "base_motion_shift.h"
#include "mvis/estimator/state_blocks.h"
#include "tangent_jet.h"
#include "whitening.h"

namespace mvis {
namespace {

using tangent_jet::Mat3;
using tangent_jet::Vec3;

// Jet directions: [dtheta_i, dp_i] 0-5, speed_bias_i 6-14, [dtheta_j, dp_j] 15-20,
// speed_bias_j 21-29, bias_i 30-32, bias_j 33-35, extrinsic dtheta 36-38, t_d 39.
constexpr int kDim = 40;
using Jet = ceres::Jet<double, kDim>;
const std::vector<tangent_jet::BlockLayout> kLayout = {
    {0, 6, 7}, {6, 9, 9}, {15, 6, 7}, {21, 9, 9}, {30, 3, 3}, {33, 3, 3}, {36, 3, 4}, {39, 1, 1}};

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

template <typename T>
void GyroFactor::residual(double const* const* parameters, T* out) const {
  using tangent_jet::perturbRotation;
  using tangent_jet::perturbScalar;
  using tangent_jet::perturbVector;
  const ImuPreintegration& pre = *pre_;
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
  using P = ImuPreintegration;
  const Vec3<T> dbg = abg_i - pre.biasGyro().cast<T>();
  const Mat3<T> dR =
      pre.deltaR().toRotationMatrix().cast<T>() *
      tangent_jet::expT<T>(pre.jacobian().block<3, 3>(P::kRotation, P::kBiasGyro).cast<T>() * dbg);
  Eigen::Matrix<T, 6, 1> r;
  r.template head<3>() = tangent_jet::logT<T>(Mat3<T>(dR.transpose() * RA_i.transpose() * RA_j));
  r.template tail<3>() = abg_j - abg_i;
  Eigen::Map<Eigen::Matrix<T, 6, 1>>{out} = sqrt_information_.cast<T>() * r;
}

bool GyroFactor::Evaluate(double const* const* parameters, double* residuals,
                          double** jacobians) const {
  if (jacobians == nullptr) {
    residual<double>(parameters, residuals);
    return true;
  }
  Jet r[6];
  residual<Jet>(parameters, r);
  tangent_jet::writeJacobians(r, 6, kLayout, residuals, jacobians);
  return true;
}

}  // namespace mvis
