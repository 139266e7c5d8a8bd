// SO(3) and SE(3) toolbox: exponential and logarithm maps, right Jacobians, interpolation.
//
// Conventions (see doc/conventions.md):
// - hat(w) is the skew-symmetric matrix with hat(w) * v = w x v; vee is its inverse.
// - Exp/Log map between a rotation vector phi [rad] and a rotation matrix or Hamilton
//   quaternion.
// - Right Jacobian Jr(phi): Exp(phi + d) = Exp(phi) * Exp(Jr(phi) * d) to first order.
//   Left Jacobian Jl(phi) = Jr(-phi): Exp(phi + d) = Exp(Jl(phi) * d) * Exp(phi).
// - SE(3) tangent vectors are xi = [phi; rho] (rotation first, then translation, matching the
//   estimator's [q, p] state order). Exp(xi) = [Exp(phi), Jl(phi) * rho; 0 1].
//   Right Jacobian: Exp(xi + d) = Exp(xi) * Exp(Jr(xi) * d) to first order.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace mvis {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

// A rigid transform T_A_B: p_A = T_A_B * p_B. Rotation as a unit Hamilton quaternion.
struct SE3 {
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();  // rotation R_A_B
  Eigen::Vector3d p = Eigen::Vector3d::Zero();            // position p_A_B [m]

  SE3() = default;
  SE3(const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation)
      : q(rotation.normalized()), p(translation) {}
  SE3(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation)
      : q(Eigen::Quaterniond(rotation).normalized()), p(translation) {}

  static SE3 Identity() { return SE3(); }
  // From a 4x4 homogeneous matrix; the rotation block is taken as given (validate it first).
  static SE3 fromMatrix(const Eigen::Matrix4d& T);

  Eigen::Matrix3d rotation() const { return q.toRotationMatrix(); }
  Eigen::Matrix4d matrix() const;
  SE3 inverse() const;
  SE3 operator*(const SE3& other) const;
  Eigen::Vector3d operator*(const Eigen::Vector3d& point) const;
};

namespace lie {

Eigen::Matrix3d hat(const Eigen::Vector3d& w);
Eigen::Vector3d vee(const Eigen::Matrix3d& W);

Eigen::Matrix3d expSO3(const Eigen::Vector3d& phi);
Eigen::Quaterniond expQuat(const Eigen::Vector3d& phi);
// Rotation vector of R, |phi| in [0, pi]. R must be a rotation matrix.
Eigen::Vector3d logSO3(const Eigen::Matrix3d& R);
Eigen::Vector3d logQuat(const Eigen::Quaterniond& q);

Eigen::Matrix3d rightJacobianSO3(const Eigen::Vector3d& phi);
Eigen::Matrix3d rightJacobianInvSO3(const Eigen::Vector3d& phi);
Eigen::Matrix3d leftJacobianSO3(const Eigen::Vector3d& phi);
Eigen::Matrix3d leftJacobianInvSO3(const Eigen::Vector3d& phi);

SE3 expSE3(const Vector6d& xi);
Vector6d logSE3(const SE3& T);
Matrix6d rightJacobianSE3(const Vector6d& xi);
Matrix6d rightJacobianInvSE3(const Vector6d& xi);
Matrix6d leftJacobianSE3(const Vector6d& xi);

// Geodesic interpolation R0 * Exp(lambda * Log(R0^T R1)); lambda in [0, 1] interpolates,
// outside extrapolates.
Eigen::Quaterniond interpolateSO3(const Eigen::Quaterniond& q0, const Eigen::Quaterniond& q1,
                                  double lambda);

// The report's pose-based interpolation (Appendix A.2): rotation along the SO(3) geodesic,
// position linearly, p = p0 + lambda * (p1 - p0).
SE3 interpolatePose(const SE3& T0, const SE3& T1, double lambda);

// Nearest rotation matrix in the Frobenius norm (SVD projection), det = +1.
Eigen::Matrix3d nearestRotation(const Eigen::Matrix3d& M);

}  // namespace lie
}  // namespace mvis
