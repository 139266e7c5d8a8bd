// Auxiliary-gyroscope factor between window states i and j (report Sec. 3.3, Eq. 44).
//
// As for auxiliary IMUs (aux_imu_factor.h), gyroscope state k belongs to the gyroscope-clock time
// tau_k = t_k - t_d0,k, t_d0,k its time offset (t_imu0 = t_gyro + t_d) when that state was made.
// The readings are preintegrated (rotation only: ImuPreintegration with the accelerometer unused)
// over [tau_i, tau_j]; they happened at base times t_k + delta_k, delta_k = t_d - t_d0,k, where
// the base rotations R_k' are the states' shifted as in base_motion.h.
// The gyroscope frame {A} follows through the extrinsic rotation R_AI of T_i_b (Eq. 44):
//   R_G_A,k = R_k' R_AI^T
// With the delta corrected to the gyroscope bias of state i (Eq. 32; with the gyroscope's Dw
// estimated, at x = [b^A_g,i Dw] re-integrated or first order about a fixed point, as ImuFactor):
//   r_theta = Log(dR(b^A_g,i)^T R_G_A,i^T R_G_A,j)
//   r_bg    = b^A_g,j - b^A_g,i   (the bias random walk)
// whitened by the rotation and gyroscope-bias rows and columns of the preintegrated covariance.
//
// Parameters: pose_i [7], speed_bias_i [9], pose_j [7], speed_bias_j [9], bias_i [3],
// bias_j [3], extrinsic rotation [4] (the quaternion of T_i_b, RotationManifold),
// time_offset [1], and with its intrinsics estimated its intrinsics block [24] (Dw and the
// gravity sensitivity Tg enter, imu_reintegration.h: the readings carry the specific force at
// the gyroscope, aux_sensors.h; the rotation of the kalibr model is held, being the
// extrinsic's). A gyroscope's translation does not enter: it is not calibrated
// (report Table 1). Jacobians by hand in the blocks' tangent spaces (tangent lift convention of
// state_blocks.h): AuxImuFactor's rotation rows (aux_imu_factor.h) chained with the ends' R_G_A
// (aux_end.h); whitened after (whitening.h).
#pragma once

#include <ceres/cost_function.h>

#include <memory>

#include "mvis/factors/base_motion.h"
#include "mvis/inertial/imu_preintegration.h"
#include "mvis/inertial/imu_reintegration.h"

namespace mvis {

class GyroFactor final : public ceres::CostFunction {
 public:
  // `pre`: the gyroscope readings over the interval (accelerometer zero), linearized at the
  // bias of state i; `time_offset0_i`, `time_offset0_j`: t_d0,i and t_d0,j [s]; `base_i`,
  // `base_j`: the base motion at t_i, t_j.
  GyroFactor(std::shared_ptr<const ImuPreintegration> pre, double time_offset0_i,
             double time_offset0_j, const BaseMotion& base_i, const BaseMotion& base_j);
  // With the intrinsics block as last parameter (`frame`: the sensor's model, rpng or kalibr;
  // `intrinsics0`: the linearization point of kFixed), as ImuFactor.
  GyroFactor(std::shared_ptr<const ImuPreintegration> pre, double time_offset0_i,
             double time_offset0_j, const BaseMotion& base_i, const BaseMotion& base_j,
             const ImuIntrinsicsFrame& frame, IntrinsicsLinearization mode,
             const double* intrinsics0);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  const ImuPreintegration& preintegration() const { return *pre_; }

 private:
  std::shared_ptr<const ImuPreintegration> pre_;
  double time_offset0_i_, time_offset0_j_;
  BaseMotion base_i_, base_j_;
  Eigen::Matrix<double, 6, 6> sqrt_information_;
  bool intrinsics_ = false;
  ImuIntrinsicsFrame frame_{Eigen::Matrix3d::Identity(), true, false};
  IntrinsicsLinearization mode_ = IntrinsicsLinearization::kReintegrate;
  ImuDeltas fixed_;  // kFixed
};

}  // namespace mvis
