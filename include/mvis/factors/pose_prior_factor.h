// Prior on a pose block (window state or camera extrinsic): what the initial guess or the
// configuration's *_std keys say of it.
//
// Parameters: pose [7] (layout and right perturbation in mvis/factors/state_blocks.h). With
// the prior mean T0 = (q0, p0) and square-root information L (L^T L = Sigma^-1, Sigma the 6x6
// covariance of [dtheta, dp]):
//   r = L [Log(q0^-1 q); p - p0]
// Jacobian in the tangent (q Exp(dtheta), p + dp):
//   d r / d dtheta = L_(:,0:3) Jr^-1(Log(q0^-1 q)),   d r / d dp = L_(:,3:6)
#pragma once

#include <ceres/sized_cost_function.h>

#include "mvis/common/lie.h"

namespace mvis {

class PosePriorFactor final : public ceres::SizedCostFunction<6, 7> {
 public:
  PosePriorFactor(const SE3& mean, const Matrix6d& sqrt_information);
  // Independent standard deviations [rad] per rotation axis and [m] per position axis.
  static PosePriorFactor* fromStd(const SE3& mean, const Eigen::Vector3d& rotation_std,
                                  const Eigen::Vector3d& position_std);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  SE3 mean_;
  Matrix6d sqrt_information_;
};

}  // namespace mvis
