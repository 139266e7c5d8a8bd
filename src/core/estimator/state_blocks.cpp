#include "mvis/estimator/state_blocks.h"

namespace mvis {

bool PoseManifold::Plus(const double* x, const double* delta, double* x_plus_delta) const {
  const Eigen::Map<const Eigen::Vector3d> dtheta(delta), dp(delta + 3);
  Eigen::Map<Eigen::Quaterniond> q(x_plus_delta);
  q = (poseRotation(x) * lie::expQuat(dtheta)).normalized();
  Eigen::Map<Eigen::Vector3d>(x_plus_delta + 4) = posePosition(x) + dp;
  return true;
}

bool PoseManifold::PlusJacobian(const double* /*x*/, double* jacobian) const {
  Eigen::Map<Eigen::Matrix<double, 7, 6, Eigen::RowMajor>> J(jacobian);
  J.setZero();
  J.topRows<6>().setIdentity();
  return true;
}

bool PoseManifold::Minus(const double* y, const double* x, double* y_minus_x) const {
  Eigen::Map<Eigen::Vector3d>{y_minus_x} =
      lie::logQuat(poseRotation(x).conjugate() * poseRotation(y));
  Eigen::Map<Eigen::Vector3d>(y_minus_x + 3) = posePosition(y) - posePosition(x);
  return true;
}

bool PoseManifold::MinusJacobian(const double* /*x*/, double* jacobian) const {
  Eigen::Map<Eigen::Matrix<double, 6, 7, Eigen::RowMajor>> J(jacobian);
  J.setZero();
  J.leftCols<6>().setIdentity();
  return true;
}

bool RotationManifold::Plus(const double* x, const double* delta, double* x_plus_delta) const {
  Eigen::Map<Eigen::Quaterniond>{x_plus_delta} =
      (poseRotation(x) * lie::expQuat(Eigen::Vector3d(delta))).normalized();
  return true;
}

bool RotationManifold::PlusJacobian(const double* /*x*/, double* jacobian) const {
  Eigen::Map<Eigen::Matrix<double, 4, 3, Eigen::RowMajor>> J(jacobian);
  J.setZero();
  J.topRows<3>().setIdentity();
  return true;
}

bool RotationManifold::Minus(const double* y, const double* x, double* y_minus_x) const {
  Eigen::Map<Eigen::Vector3d>{y_minus_x} =
      lie::logQuat(poseRotation(x).conjugate() * poseRotation(y));
  return true;
}

bool RotationManifold::MinusJacobian(const double* /*x*/, double* jacobian) const {
  Eigen::Map<Eigen::Matrix<double, 3, 4, Eigen::RowMajor>> J(jacobian);
  J.setZero();
  J.leftCols<3>().setIdentity();
  return true;
}

}  // namespace mvis
