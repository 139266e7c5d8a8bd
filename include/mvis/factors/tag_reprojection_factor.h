// Tag-corner reprojection factor: every known board corner seen in one camera frame (report
// Eq. 24-26), through the pose interpolation of Appendix A.
//
// A frame stamped t_c in the camera's clock happened at base time t = t_c + t_d. The base-IMU
// pose at t comes from the window states:
//   kinematic (Appendix A.1, the base camera, whose frames sit next to a state k):
//     dt = t - t_k,  R(t) = R_k Exp((w_m - b_g,k) dt),  p(t) = p_k + v_k dt
//     with w_m the base gyroscope reading at t_k;
//   pose-based (Appendix A.2, every other camera, between bounding states k and k+1):
//     s = (t - t_k) / (t_k+1 - t_k),  R(t) = R_k Exp(s Log(R_k^T R_k+1)),
//     p(t) = p_k + s (p_k+1 - p_k).
// A board corner p_G (world = board frame) is then seen at
//   p_C = R_C_I R(t)^T (p_G - p(t)) + p_C_I
//   z = pi(k, d, p_C) + n,  n ~ N(0, sigma^2 I2)
// with pi the pinhole projection and distortion of mvis/camera/camera_model.h. The residual is
// (pi(...) - z) / sigma for each corner, 2 N residuals.
//
// Parameters:
//   kinematic:  pose_k [7], speed_bias_k [9], extrinsic T_C_I [7], time_offset [1],
//               intrinsics [8]
//   pose-based: pose_k [7], pose_k+1 [7], extrinsic T_C_I [7], time_offset [1], intrinsics [8]
// Jacobians: the camera pose R_C_G, t_C_G is differentiated once per frame by forward-mode
// automatic differentiation in the 19 tangent directions (pose and extrinsic perturbations on
// the right, see state_blocks.h; v and b_g; t_d), then chained per corner with the projection's
// Jacobian in p_C and in the intrinsics (also forward mode). Pose-block Jacobians are written
// in the tangent lift convention of state_blocks.h.
#pragma once

#include <ceres/cost_function.h>

#include <Eigen/Core>
#include <vector>

#include "mvis/rig/rig.h"

namespace mvis {

struct CornerObservation {
  Eigen::Vector3d p_G = Eigen::Vector3d::Zero();  // board point [m]
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();   // detected pixel
};

class TagReprojectionFactor final : public ceres::CostFunction {
 public:
  enum class Interpolation { kKinematic, kPoseBased };

  // Kinematic: `dt_nominal` = t_c - t_k [s] (t_d added at evaluation), `gyro_k` the base gyroscope
  // reading at t_k.
  static TagReprojectionFactor* kinematic(DistortionModel model,
                                          std::vector<CornerObservation> corners,
                                          double pixel_sigma, double dt_nominal,
                                          const Eigen::Vector3d& gyro_k);
  // Pose-based: `dt_nominal` = t_c - t_k [s], `interval` = t_k+1 - t_k [s].
  static TagReprojectionFactor* poseBased(DistortionModel model,
                                          std::vector<CornerObservation> corners,
                                          double pixel_sigma, double dt_nominal, double interval);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  Interpolation interpolation() const { return interpolation_; }
  const std::vector<CornerObservation>& corners() const { return corners_; }
  double pixelSigma() const { return sigma_; }

 private:
  TagReprojectionFactor(Interpolation interpolation, DistortionModel model,
                        std::vector<CornerObservation> corners, double pixel_sigma,
                        double dt_nominal, double interval, const Eigen::Vector3d& gyro_k);

  Interpolation interpolation_;
  DistortionModel model_;
  std::vector<CornerObservation> corners_;
  double sigma_;
  double dt_nominal_;
  double interval_;
  Eigen::Vector3d gyro_k_;
};

}  // namespace mvis
