// Auxiliary-IMU factor between window states i and j (report Sec. 3.1, Eq. 38-39, and the second
// model of Appendix B).
//
// Each aux state k belongs to the aux-clock time tau_k = t_k - t_d0,k, t_d0,k the aux time offset
// (t_imu0 = t_aux + t_d) when that aux state was made. The auxiliary readings are preintegrated
// (ImuPreintegration, in the aux frame {A} and clock) over [tau_i, tau_j]; they happened at base
// times tau_k + t_d = t_k + delta_k, delta_k = t_d - t_d0,k, where the base poses R_k', p_k' are
// the states' shifted as in base_motion.h. The aux velocity state v^A_k is the velocity at
// tau_k. The aux pose follows the
// base pose through the extrinsic T_A_I (Kalibr's T_i_b: p_A = R_AI p_I + p_AI), Eq. 38-39:
//   R_G_A,k = R_k' R_AI^T,   p_G_A,k = p_k' - R_G_A,k p_AI
// With T = tau_j - tau_i, g gravity, and the deltas corrected to the aux biases of state i as in
// ImuFactor (Eq. 32-34; with the aux IMU's intrinsics estimated, at x = [b^A_g,i b^A_a,i
// intrinsics] re-integrated or first order about a fixed point, as ImuFactor):
//   r_theta = Log(dR(b^A_g,i)^T R_G_A,i^T R_G_A,j)
//   r_p     = R_G_A,i^T (p_G_A,j - p_G_A,i - v^A_i T - 1/2 g T^2) - dp(b^A_i)
//   r_v     = R_G_A,i^T (v^A_j - v^A_i - g T) - dv(b^A_i)
//   r_bg    = b^A_g,j - b^A_g,i,   r_ba = b^A_a,j - b^A_a,i   (the aux bias random walks)
// whitened by the preintegrated covariance, as ImuFactor.
//
// Models of the aux velocity v^A_k:
//   kVelocityState (report Sec. 3.1, the default): a state of its own, aux block
//     [v^A(3) b^A_g(3) b^A_a(3)];
//   kRigidVelocity (Appendix B, Eq. 78): the rigid-body velocity from the base state, aux block
//     [b^A_g(3) b^A_a(3)]:
//       v^A_k = v_k' + R_k' [R_AI^T (w^A_m,k - b^A_g,k)]x p_IA,   p_IA = -R_AI^T p_AI,
//     with v_k' = v_k + (R_k (a_m - b_a,k) + g) delta_k and w^A_m,k the aux gyroscope reading at
//     the interval's end k. That reading's noise is not modelled, which is the hidden inconsistency
//     the report's Sec. 6.3 finds on degenerate motion; kept to reproduce it.
//
// Parameters: pose_i [7], speed_bias_i [9], pose_j [7], speed_bias_j [9], aux_i [9 or 6],
// aux_j [9 or 6], extrinsic T_A_I [7], time_offset [1], gravity [3] (state_blocks.h), and with
// its intrinsics estimated the aux IMU's intrinsics block [24] (imu_reintegration.h).
// Jacobians by hand in the blocks' tangent spaces (tangent lift convention of state_blocks.h):
// the residual's derivatives in each end's aux pose and velocity are ImuFactor's (imu_factor.h,
// with R_G_A, p_G_A, v^A for R, p, v), chained with the ends' derivatives in the base state,
// extrinsic, time offset, gravity and aux block (aux_end.h); gravity also enters directly
// (-1/2 R_G_A,i^T T^2 in r_p, -R_G_A,i^T T in r_v). Whitened after (whitening.h).
#pragma once

#include <ceres/cost_function.h>

#include <memory>

#include "mvis/factors/aux_imu_model.h"
#include "mvis/factors/base_motion.h"
#include "mvis/inertial/imu_preintegration.h"
#include "mvis/inertial/imu_reintegration.h"

namespace mvis {

class AuxImuFactor final : public ceres::CostFunction {
 public:
  // `pre`: the aux readings over the interval, linearized at the aux biases of state i.
  // `time_offset0_i`, `time_offset0_j`: t_d0,i and t_d0,j [s]. `base_i`, `base_j`: the base motion
  // at t_i and t_j. The aux gyroscope readings at the interval's ends are the first and last of
  // `pre`'s samples.
  AuxImuFactor(AuxImuModel model, std::shared_ptr<const ImuPreintegration> pre,
               double time_offset0_i, double time_offset0_j, const BaseMotion& base_i,
               const BaseMotion& base_j);
  // With the intrinsics block as last parameter (`intrinsics0`: the linearization point of kFixed),
  // as ImuFactor.
  AuxImuFactor(AuxImuModel model, std::shared_ptr<const ImuPreintegration> pre,
               double time_offset0_i, double time_offset0_j, const BaseMotion& base_i,
               const BaseMotion& base_j, const ImuIntrinsicsFrame& frame,
               IntrinsicsLinearization mode, const double* intrinsics0);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  static int auxBlockSize(AuxImuModel model) {
    return model == AuxImuModel::kVelocityState ? 9 : 6;
  }

  const ImuPreintegration& preintegration() const { return *pre_; }

 private:
  AuxImuModel model_;
  std::shared_ptr<const ImuPreintegration> pre_;
  BaseMotion base_i_, base_j_;
  double time_offset0_i_, time_offset0_j_;
  Eigen::Matrix<double, 15, 15> sqrt_information_;
  bool intrinsics_ = false;
  IntrinsicsLinearization mode_ = IntrinsicsLinearization::kReintegrate;
  ImuIntrinsicsFrame frame_;
  ImuDeltas fixed_;  // kFixed
};

}  // namespace mvis
