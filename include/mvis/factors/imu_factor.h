// Base-IMU preintegration factor between window states i and j (report Eq. 35-36).
//
// Parameters: pose_i [7], speed_bias_i [9], pose_j [7], speed_bias_j [9], gravity [3]
// (layouts in mvis/estimator/state_blocks.h). With T = t_j - t_i, g the gravity vector and the
// deltas of ImuPreintegration corrected to the biases of state i (Eq. 32-34):
//   r_theta = Log(dR(b_g,i)^T R_i^T R_j)
//   r_p     = R_i^T (p_j - p_i - v_i T - 1/2 g T^2) - dp(b_i)
//   r_v     = R_i^T (v_j - v_i - g T) - dv(b_i)
//   r_bg    = b_g,j - b_g,i
//   r_ba    = b_a,j - b_a,i
// whitened by L with L^T L = P^-1, P the preintegrated covariance. The bias rows carry the
// random walks of the two biases over T, so this factor is also the bias random-walk factor of
// the base IMU.
//
// Jacobians in the tangent spaces (right perturbation R Exp(dtheta), p + dp), with
// E = dR(b_g,i)^T R_i^T R_j, e = r_theta, phi = J_R_bg (b_g,i - b_g0):
//   d r_theta / d theta_i = -Jr^-1(e) R_j^T R_i        d r_theta / d theta_j = Jr^-1(e)
//   d r_theta / d b_g,i   = -Jr^-1(e) E^T Jr(phi) J_R_bg
//   d r_p / d theta_i = [R_i^T (p_j - p_i - v_i T - 1/2 g T^2)]x
//   d r_p / d p_i = -R_i^T,  d r_p / d p_j = R_i^T,  d r_p / d v_i = -R_i^T T,
//   d r_p / d b_i = -J_p_b,  d r_p / d g = -1/2 R_i^T T^2
//   d r_v / d theta_i = [R_i^T (v_j - v_i - g T)]x
//   d r_v / d v_i = -R_i^T,  d r_v / d v_j = R_i^T,  d r_v / d b_i = -J_v_b,  d r_v / d g = -R_i^T
//   T
#pragma once

#include <ceres/sized_cost_function.h>

#include <memory>

#include "mvis/estimator/imu_preintegration.h"

namespace mvis {

class ImuFactor final : public ceres::SizedCostFunction<15, 7, 9, 7, 9, 3> {
 public:
  // The preintegration is shared, so re-integrating it (new bias linearization point) updates
  // the factor.
  explicit ImuFactor(std::shared_ptr<const ImuPreintegration> preintegration);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  const ImuPreintegration& preintegration() const { return *preintegration_; }

 private:
  std::shared_ptr<const ImuPreintegration> preintegration_;
};

}  // namespace mvis
