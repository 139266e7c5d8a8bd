#include "mvis/factors/pose_prior_factor.h"

#include "mvis/factors/state_blocks.h"

namespace mvis {

PosePriorFactor::PosePriorFactor(const SE3& mean, const Matrix6d& sqrt_information)
    : mean_(mean), sqrt_information_(sqrt_information) {}

PosePriorFactor* PosePriorFactor::fromStd(const SE3& mean, const Eigen::Vector3d& rotation_std,
                                          const Eigen::Vector3d& position_std) {
  Vector6d inv;
  inv << rotation_std.cwiseInverse(), position_std.cwiseInverse();
  return new PosePriorFactor(mean, inv.asDiagonal());
}

bool PosePriorFactor::Evaluate(double const* const* parameters, double* residuals,
                               double** jacobians) const {
  const Eigen::Quaterniond q(poseRotation(parameters[0]));
  const Eigen::Vector3d e = lie::logQuat(mean_.q.conjugate() * q);
  Vector6d r;
  r << e, posePosition(parameters[0]) - mean_.p;
  Eigen::Map<Vector6d>{residuals} = sqrt_information_ * r;
  if (jacobians != nullptr && jacobians[0] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 6, 7, Eigen::RowMajor>> J(jacobians[0]);
    J.setZero();
    J.leftCols<3>() = sqrt_information_.leftCols<3>() * lie::rightJacobianInvSO3(e);
    J.middleCols<3>(3) = sqrt_information_.rightCols<3>();
  }
  return true;
}

}  // namespace mvis
