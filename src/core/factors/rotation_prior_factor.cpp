#include "mvis/factors/rotation_prior_factor.h"

#include "mvis/common/lie.h"
#include "mvis/factors/state_blocks.h"

namespace mvis {

RotationPriorFactor::RotationPriorFactor(const Eigen::Quaterniond& mean,
                                         const Eigen::Vector3d& rotation_std)
    : mean_(mean.normalized()), inverse_std_(rotation_std.cwiseInverse()) {}

bool RotationPriorFactor::Evaluate(double const* const* parameters, double* residuals,
                                   double** jacobians) const {
  const Eigen::Vector3d e = lie::logQuat(mean_.conjugate() * poseRotation(parameters[0]));
  Eigen::Map<Eigen::Vector3d>{residuals} = inverse_std_.asDiagonal() * e;
  if (jacobians != nullptr && jacobians[0] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 3, 4, Eigen::RowMajor>> J(jacobians[0]);
    J.setZero();
    J.leftCols<3>() = inverse_std_.asDiagonal() * lie::rightJacobianInvSO3(e);
  }
  return true;
}

}  // namespace mvis
