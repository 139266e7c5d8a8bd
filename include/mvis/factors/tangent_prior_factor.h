// Prior on chosen tangent directions of a block: what is known along them, and nothing else.
//
// Parameters: one block x of any manifold M (nullptr: Euclidean) with tangent size t. With the
// prior mean x0, k orthonormal tangent directions D (t x k) and standard deviations s (k):
//   r = diag(1 / s) D^T Minus_M(x, x0)
// Jacobian (ambient), first-estimate: diag(1 / s) D^T MinusJacobian_M(x), exact at x = x0,
// where it is diag(1 / s) D^T in the tangent (through PlusJacobian_M(x0)); the estimator only
// evaluates it there.
//
// The estimator adds it only while it computes covariances: the directions it holds (the recent
// motion does not observe them, observability.h) are then free with the uncertainty they kept,
// so that what depends on them (the pose, along a held camera translation) shows it.
#pragma once

#include <ceres/cost_function.h>
#include <ceres/manifold.h>

#include <Eigen/Core>
#include <vector>

namespace mvis {

class TangentPriorFactor final : public ceres::CostFunction {
 public:
  // `manifold` is not owned and must outlive the factor; `x0` has the block's ambient size.
  TangentPriorFactor(const ceres::Manifold* manifold, std::vector<double> x0,
                     const Eigen::MatrixXd& directions, const Eigen::VectorXd& std);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  const ceres::Manifold* manifold_;
  std::vector<double> x0_;
  int tangent_;
  Eigen::MatrixXd A_;  // diag(1 / s) D^T
};

}  // namespace mvis
