// Prior on a rotation block (a gyroscope's extrinsic rotation): what the initial guess or the
// configuration's *_std keys say of it.
//
// Parameters: rotation [4] ([qx qy qz qw], RotationManifold in mvis/factors/state_blocks.h).
// With the prior mean q0 and standard deviations s per axis [rad]:
//   r = diag(1 / s) Log(q0^-1 q)
// Jacobian in the tangent (q Exp(dtheta)): d r / d dtheta = diag(1 / s) Jr^-1(Log(q0^-1 q)).
#pragma once

#include <ceres/sized_cost_function.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace mvis {

class RotationPriorFactor final : public ceres::SizedCostFunction<3, 4> {
 public:
  RotationPriorFactor(const Eigen::Quaterniond& mean, const Eigen::Vector3d& rotation_std);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  Eigen::Quaterniond mean_;
  Eigen::Vector3d inverse_std_;
};

}  // namespace mvis
