// Base-IMU preintegration factor between window states i and j (report Eq. 35-37).
//
// Parameters: pose_i [7], speed_bias_i [9], pose_j [7], speed_bias_j [9], gravity [3], and with
// the base IMU's intrinsics estimated its intrinsics block [24] (layouts in
// mvis/factors/state_blocks.h and mvis/inertial/imu_reintegration.h). With T = t_j - t_i, g
// the gravity vector and the deltas dR, dp, dv at x = [b_g,i b_a,i intrinsics]:
//   r_theta = Log(dR(x)^T R_i^T R_j)
//   r_p     = R_i^T (p_j - p_i - v_i T - 1/2 g T^2) - dp(x)
//   r_v     = R_i^T (v_j - v_i - g T) - dv(x)
//   r_bg    = b_g,j - b_g,i
//   r_ba    = b_a,j - b_a,i
// whitened by L with L^T L = P^-1, P the preintegrated covariance. The bias rows carry the
// random walks of the two biases over T, so this factor is also the bias random-walk factor of
// the base IMU.
// With the intrinsics estimated P is the raw readings' (their noise densities), while the deltas
// use corrected readings w = G (w_m - ...), a = M (a_m - ...) (imu_reintegration.h), whose noise
// is G n_g, M n_a: the residual is whitened as L S^-1 r with S = diag(G, M, M, I, I) at the
// current intrinsics (to first order in the interval's rotation), and d(S^-1)/dx r joins the
// intrinsics' Jacobian. With a whitening fixed at construction instead, the cost compares
// D times noisy readings with the states' motion at a fixed weight, and least squares shrinks D
// by the noise's share of the readings' variation (errors in variables): on the test trajectory
// with the states held at the truth and four times the VI-Rig's noise, the accelerometer's scales
// across gravity ended 6.9e-4 and 4.9e-4 small (5.5 and 3.0 standard errors over 16 seeds), with
// this whitening within 1.3 (test ImuFactor.IntrinsicsUnbiasedUnderNoiseAtTheTrueStates).
//
// The deltas at x come from an ImuDeltas (integrated at x0, Jacobian J = d delta / dx):
//   dR(x) = dR Exp(phi), phi = J_theta (x - x0);  dp(x) = dp + J_p (x - x0);  dv likewise.
// Without intrinsics x0 is the preintegration's bias linearization point (Eq. 32-34, bias
// correction); with intrinsics and IntrinsicsLinearization::kReintegrate the readings are
// re-integrated at x on every evaluation (x0 = x, phi = 0; Sec. 2.2), with kFixed x0 is a fixed
// point (the configured intrinsics in the estimator).
//
// Jacobians in the tangent spaces (right perturbation R Exp(dtheta), p + dp), with
// E = dR(x)^T R_i^T R_j, e = r_theta:
//   d r_theta / d theta_i = -Jr^-1(e) R_j^T R_i        d r_theta / d theta_j = Jr^-1(e)
//   d r_theta / d x       = -Jr^-1(e) E^T Jr(phi) J_theta
//   d r_p / d theta_i = [R_i^T (p_j - p_i - v_i T - 1/2 g T^2)]x
//   d r_p / d p_i = -R_i^T,  d r_p / d p_j = R_i^T,  d r_p / d v_i = -R_i^T T,
//   d r_p / d x = -J_p,  d r_p / d g = -1/2 R_i^T T^2
//   d r_v / d theta_i = [R_i^T (v_j - v_i - g T)]x
//   d r_v / d v_i = -R_i^T,  d r_v / d v_j = R_i^T,  d r_v / d x = -J_v,  d r_v / d g = -R_i^T T
// (x's bias part belongs to speed_bias_i, the rest to the intrinsics block), each times L S^-1.
#pragma once

#include <ceres/cost_function.h>

#include <memory>

#include "mvis/inertial/imu_preintegration.h"
#include "mvis/inertial/imu_reintegration.h"

namespace mvis {

class ImuFactor final : public ceres::CostFunction {
 public:
  // Readings taken as calibrated. The preintegration is shared and must not change while the
  // factor exists: its square-root information (L^T with L L^T = P^-1) is taken here.
  explicit ImuFactor(std::shared_ptr<const ImuPreintegration> preintegration);
  // With the intrinsics block as sixth parameter; `intrinsics0`: the linearization point of
  // kFixed. The preintegration gives the raw readings, the covariance
  // and (kFixed) the bias linearization point.
  ImuFactor(std::shared_ptr<const ImuPreintegration> preintegration,
            const ImuIntrinsicsFrame& frame, IntrinsicsLinearization mode,
            const double* intrinsics0);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  const ImuPreintegration& preintegration() const { return *preintegration_; }

 private:
  std::shared_ptr<const ImuPreintegration> preintegration_;
  Eigen::Matrix<double, 15, 15> sqrt_information_;
  bool intrinsics_ = false;
  ImuIntrinsicsFrame frame_;
  IntrinsicsLinearization mode_ = IntrinsicsLinearization::kReintegrate;
  ImuDeltas fixed_;  // kFixed
};

}  // namespace mvis
