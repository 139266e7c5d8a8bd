#include "mvis/common/lie.h"

#include <Eigen/SVD>
#include <cmath>

namespace mvis {

SE3 SE3::fromMatrix(const Eigen::Matrix4d& T) {
  return SE3(Eigen::Matrix3d(T.topLeftCorner<3, 3>()), Eigen::Vector3d(T.topRightCorner<3, 1>()));
}

Eigen::Matrix4d SE3::matrix() const {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = rotation();
  T.topRightCorner<3, 1>() = p;
  return T;
}

SE3 SE3::inverse() const {
  const Eigen::Quaterniond q_inv = q.conjugate();
  return SE3(q_inv, -(q_inv * p));
}

SE3 SE3::operator*(const SE3& other) const { return SE3(q * other.q, q * other.p + p); }

Eigen::Vector3d SE3::operator*(const Eigen::Vector3d& point) const { return q * point + p; }

namespace lie {
namespace {

// Below this angle [rad] the closed forms lose precision and Taylor series take over.
constexpr double kSmallAngle = 1e-5;

// Barfoot's Q(rho, phi) for the SE(3) left Jacobian (State Estimation for Robotics, eq. 7.86).
Eigen::Matrix3d seQ(const Eigen::Vector3d& phi, const Eigen::Vector3d& rho) {
  const double theta = phi.norm();
  const Eigen::Matrix3d P = hat(phi);
  const Eigen::Matrix3d Rh = hat(rho);
  double c1, c2, c3;
  if (theta < 1e-3) {
    const double t2 = theta * theta;
    c1 = 1.0 / 6.0 - t2 / 120.0;
    c2 = 1.0 / 24.0 - t2 / 720.0;
    c3 = 1.0 / 120.0 - t2 / 2520.0;
  } else {
    const double t2 = theta * theta, t3 = t2 * theta, t4 = t3 * theta, t5 = t4 * theta;
    const double s = std::sin(theta), c = std::cos(theta);
    c1 = (theta - s) / t3;
    c2 = (t2 + 2.0 * c - 2.0) / (2.0 * t4);
    c3 = (2.0 * theta - 3.0 * s + theta * c) / (2.0 * t5);
  }
  const Eigen::Matrix3d PR = P * Rh;
  const Eigen::Matrix3d RP = Rh * P;
  const Eigen::Matrix3d PRP = PR * P;
  return 0.5 * Rh + c1 * (PR + RP + PRP) + c2 * (P * PR + RP * P - 3.0 * PRP) +
         c3 * (PRP * P + P * PRP);
}

}  // namespace

Eigen::Matrix3d hat(const Eigen::Vector3d& w) {
  Eigen::Matrix3d W;
  W << 0.0, -w.z(), w.y(), w.z(), 0.0, -w.x(), -w.y(), w.x(), 0.0;
  return W;
}

Eigen::Vector3d vee(const Eigen::Matrix3d& W) { return Eigen::Vector3d(W(2, 1), W(0, 2), W(1, 0)); }

Eigen::Quaterniond expQuat(const Eigen::Vector3d& phi) {
  const double theta = phi.norm();
  const double half = 0.5 * theta;
  // sin(half) / theta, with its series near zero.
  const double k = theta < kSmallAngle ? 0.5 - theta * theta / 48.0 : std::sin(half) / theta;
  Eigen::Quaterniond q(std::cos(half), k * phi.x(), k * phi.y(), k * phi.z());
  return q.normalized();
}

Eigen::Matrix3d expSO3(const Eigen::Vector3d& phi) {
  const double theta = phi.norm();
  const Eigen::Matrix3d W = hat(phi);
  if (theta < kSmallAngle) return Eigen::Matrix3d::Identity() + W + 0.5 * W * W;
  return Eigen::Matrix3d::Identity() + std::sin(theta) / theta * W +
         (1.0 - std::cos(theta)) / (theta * theta) * W * W;
}

Eigen::Vector3d logQuat(const Eigen::Quaterniond& q_in) {
  Eigen::Quaterniond q = q_in.normalized();
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();  // the shorter way round, |phi| <= pi
  const Eigen::Vector3d v = q.vec();
  const double n = v.norm();
  if (n < kSmallAngle) {
    // 2 * atan(n / w) / n = (2 / w) * (1 - n^2 / (3 w^2)) + O(n^4)
    return (2.0 / q.w()) * (1.0 - n * n / (3.0 * q.w() * q.w())) * v;
  }
  return (2.0 * std::atan2(n, q.w()) / n) * v;
}

Eigen::Vector3d logSO3(const Eigen::Matrix3d& R) { return logQuat(Eigen::Quaterniond(R)); }

Eigen::Matrix3d rightJacobianSO3(const Eigen::Vector3d& phi) {
  const double theta = phi.norm();
  const Eigen::Matrix3d W = hat(phi);
  if (theta < kSmallAngle) return Eigen::Matrix3d::Identity() - 0.5 * W + W * W / 6.0;
  const double t2 = theta * theta;
  return Eigen::Matrix3d::Identity() - (1.0 - std::cos(theta)) / t2 * W +
         (theta - std::sin(theta)) / (t2 * theta) * W * W;
}

Eigen::Matrix3d rightJacobianInvSO3(const Eigen::Vector3d& phi) {
  const double theta = phi.norm();
  const Eigen::Matrix3d W = hat(phi);
  if (theta < kSmallAngle) return Eigen::Matrix3d::Identity() + 0.5 * W + W * W / 12.0;
  const double t2 = theta * theta;
  return Eigen::Matrix3d::Identity() + 0.5 * W +
         (1.0 / t2 - (1.0 + std::cos(theta)) / (2.0 * theta * std::sin(theta))) * W * W;
}

Eigen::Matrix3d leftJacobianSO3(const Eigen::Vector3d& phi) { return rightJacobianSO3(-phi); }

Eigen::Matrix3d leftJacobianInvSO3(const Eigen::Vector3d& phi) { return rightJacobianInvSO3(-phi); }

SE3 expSE3(const Vector6d& xi) {
  const Eigen::Vector3d phi = xi.head<3>();
  return SE3(expQuat(phi), leftJacobianSO3(phi) * xi.tail<3>());
}

Vector6d logSE3(const SE3& T) {
  Vector6d xi;
  xi.head<3>() = logQuat(T.q);
  xi.tail<3>() = leftJacobianInvSO3(xi.head<3>()) * T.p;
  return xi;
}

Matrix6d leftJacobianSE3(const Vector6d& xi) {
  const Eigen::Vector3d phi = xi.head<3>();
  const Eigen::Matrix3d Jl = leftJacobianSO3(phi);
  Matrix6d J = Matrix6d::Zero();
  J.topLeftCorner<3, 3>() = Jl;
  J.bottomRightCorner<3, 3>() = Jl;
  J.bottomLeftCorner<3, 3>() = seQ(phi, xi.tail<3>());
  return J;
}

Matrix6d rightJacobianSE3(const Vector6d& xi) { return leftJacobianSE3(-xi); }

Matrix6d rightJacobianInvSE3(const Vector6d& xi) {
  // Block lower-triangular [A 0; B A] has inverse [A^-1 0; -A^-1 B A^-1 A^-1].
  const Matrix6d J = rightJacobianSE3(xi);
  const Eigen::Matrix3d A_inv = rightJacobianInvSO3(xi.head<3>());
  Matrix6d J_inv = Matrix6d::Zero();
  J_inv.topLeftCorner<3, 3>() = A_inv;
  J_inv.bottomRightCorner<3, 3>() = A_inv;
  J_inv.bottomLeftCorner<3, 3>() = -A_inv * J.bottomLeftCorner<3, 3>() * A_inv;
  return J_inv;
}

Eigen::Quaterniond interpolateSO3(const Eigen::Quaterniond& q0, const Eigen::Quaterniond& q1,
                                  double lambda) {
  return (q0 * expQuat(lambda * logQuat(q0.conjugate() * q1))).normalized();
}

SE3 interpolatePose(const SE3& T0, const SE3& T1, double lambda) {
  return SE3(interpolateSO3(T0.q, T1.q, lambda), T0.p + lambda * (T1.p - T0.p));
}

Eigen::Matrix3d nearestRotation(const Eigen::Matrix3d& M) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  return svd.matrixU() * D * svd.matrixV().transpose();
}

}  // namespace lie
}  // namespace mvis
