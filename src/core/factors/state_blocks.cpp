#include "mvis/factors/state_blocks.h"

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

SubspaceManifold::SubspaceManifold(const ceres::Manifold* base, int ambient, Eigen::MatrixXd basis)
    : base_(base), ambient_(ambient), basis_(std::move(basis)) {}

bool SubspaceManifold::Plus(const double* x, const double* delta, double* x_plus_delta) const {
  const Eigen::VectorXd d = basis_ * Eigen::Map<const Eigen::VectorXd>(delta, basis_.cols());
  if (base_ != nullptr) return base_->Plus(x, d.data(), x_plus_delta);
  for (int i = 0; i < ambient_; ++i) x_plus_delta[i] = x[i] + d[i];
  return true;
}

bool SubspaceManifold::PlusJacobian(const double* x, double* jacobian) const {
  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  const auto n = basis_.rows();
  RowMajor lift = RowMajor::Identity(ambient_, n);
  if (base_ != nullptr && !base_->PlusJacobian(x, lift.data())) return false;
  Eigen::Map<RowMajor>(jacobian, ambient_, basis_.cols()) = lift * basis_;
  return true;
}

bool SubspaceManifold::Minus(const double* y, const double* x, double* y_minus_x) const {
  const auto n = basis_.rows();
  Eigen::VectorXd d(n);
  if (base_ != nullptr) {
    if (!base_->Minus(y, x, d.data())) return false;
  } else {
    for (int i = 0; i < n; ++i) d[i] = y[i] - x[i];
  }
  Eigen::Map<Eigen::VectorXd>(y_minus_x, basis_.cols()) = basis_.transpose() * d;
  return true;
}

bool SubspaceManifold::MinusJacobian(const double* x, double* jacobian) const {
  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  const auto n = basis_.rows();
  RowMajor minus = RowMajor::Identity(n, ambient_);
  if (base_ != nullptr && !base_->MinusJacobian(x, minus.data())) return false;
  Eigen::Map<RowMajor>(jacobian, basis_.cols(), ambient_) = basis_.transpose() * minus;
  return true;
}

}  // namespace mvis
