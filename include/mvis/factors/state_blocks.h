// The estimator's parameter blocks and their manifolds.
//
// Layouts (all double):
//   pose        [qx qy qz qw px py pz]  R_G_I as an Eigen (Hamilton) quaternion, p_G_I [m]
//   speed_bias  [v(3) b_g(3) b_a(3)]    v_G_I [m/s], gyroscope [rad/s] and accelerometer
//                                       [m/s^2] biases
//   gravity     [g(3)]                  gravity in the world (board) frame [m/s^2]; its norm is
//                                       fixed (SphereManifold)
//   extrinsic   as pose                 T_C_I of a camera (p_C = T_C_I p_I)
//   time_offset [t_d]                   [s], t_imu0 = t_cam + t_d
//   intrinsics  [fu fv pu pv d0 d1 d2 d3]  [px] and the distortion coefficients
//   aux_state   [v(3) b_g(3) b_a(3)]    an auxiliary IMU's velocity and biases at a window time
//               (its own frame's biases; v in the world frame), or [b_g(3) b_a(3)] with the
//               rigid-velocity model (aux_imu_factor.h)
//   aux extrinsic as pose               T_i_b of an auxiliary IMU (p_imui = T_i_b p_imu0)
//   gyro extrinsic [qx qy qz qw]        the rotation of T_i_b of a gyroscope (RotationManifold)
//   gyro bias   [b_g(3)]                a gyroscope's bias at a window time [rad/s]
//
// Poses (and rotations) are perturbed on the right: Plus([q, p], [dtheta, dp]) = [q Exp(dtheta), p
// + dp]. PoseManifold's PlusJacobian is the lift [I6; 0] rather than the true derivative of the
// quaternion: every cost function touching a pose block writes the Jacobian in the tangent
// [dtheta, dp] into its first six columns and zero into the seventh, so that Ceres's product
// (ambient Jacobian) x (PlusJacobian) is the tangent Jacobian. Automatic differentiation through
// the quaternion would break that contract, so pose-touching factors are analytic.
#pragma once

#include <ceres/manifold.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "mvis/common/lie.h"

namespace mvis {

constexpr int kPoseSize = 7, kPoseTangent = 6, kSpeedBiasSize = 9, kGravitySize = 3,
              kIntrinsicsSize = 8, kRotationSize = 4;

class PoseManifold final : public ceres::Manifold {
 public:
  int AmbientSize() const override { return kPoseSize; }
  int TangentSize() const override { return kPoseTangent; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override;
  bool PlusJacobian(const double* x, double* jacobian) const override;
  bool Minus(const double* y, const double* x, double* y_minus_x) const override;
  bool MinusJacobian(const double* x, double* jacobian) const override;
};

// A rotation block [qx qy qz qw], perturbed on the right, PlusJacobian the lift [I3; 0] (the
// same contract as PoseManifold).
class RotationManifold final : public ceres::Manifold {
 public:
  int AmbientSize() const override { return kRotationSize; }
  int TangentSize() const override { return 3; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override;
  bool PlusJacobian(const double* x, double* jacobian) const override;
  bool Minus(const double* y, const double* x, double* y_minus_x) const override;
  bool MinusJacobian(const double* x, double* jacobian) const override;
};

// A block held along some of its tangent directions: Plus(x, d) = base.Plus(x, B d) for an
// orthonormal basis B (tangent x k) of the directions left free. `base` (not owned; nullptr:
// Euclidean of `ambient` size) is one of the manifolds above, whose PlusJacobian is a lift, so
// the contract stays: PlusJacobian = base.PlusJacobian B, MinusJacobian = B^T base.MinusJacobian.
// The estimator holds calibration directions that the recent motion cannot observe this way.
class SubspaceManifold final : public ceres::Manifold {
 public:
  SubspaceManifold(const ceres::Manifold* base, int ambient, Eigen::MatrixXd basis);
  int AmbientSize() const override { return ambient_; }
  int TangentSize() const override { return static_cast<int>(basis_.cols()); }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override;
  bool PlusJacobian(const double* x, double* jacobian) const override;
  bool Minus(const double* y, const double* x, double* y_minus_x) const override;
  bool MinusJacobian(const double* x, double* jacobian) const override;
  const Eigen::MatrixXd& basis() const { return basis_; }

 private:
  const ceres::Manifold* base_;
  int ambient_;
  Eigen::MatrixXd basis_;
};

// Views of a pose block.
inline Eigen::Map<const Eigen::Quaterniond> poseRotation(const double* pose) {
  return Eigen::Map<const Eigen::Quaterniond>(pose);
}
inline Eigen::Map<const Eigen::Vector3d> posePosition(const double* pose) {
  return Eigen::Map<const Eigen::Vector3d>(pose + 4);
}
inline SE3 poseToSE3(const double* pose) {
  return SE3(Eigen::Quaterniond(poseRotation(pose)), Eigen::Vector3d(posePosition(pose)));
}
inline void se3ToPose(const SE3& T, double* pose) {
  Eigen::Map<Eigen::Quaterniond>{pose} = T.q;
  Eigen::Map<Eigen::Vector3d>(pose + 4) = T.p;
}

}  // namespace mvis
