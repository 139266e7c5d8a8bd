// Prior on chosen tangent directions of one or more blocks jointly: what is known along them,
// and nothing else.
//
// Parameters: blocks x_1..x_m of any manifolds M_i (nullptr: Euclidean) with tangent sizes t_i.
// With the prior means x0_i, the stacked tangent difference d = [Minus_M1(x_1, x0_1); ...;
// Minus_Mm(x_m, x0_m)] (size t = sum t_i), k orthonormal directions D (t x k) of that stacked
// tangent and standard deviations s (k):
//   r = diag(1 / s) D^T d
// With all t directions of a covariance S = D diag(s^2) D^T this is the Gaussian prior
// r^T r = d^T S^-1 d, cross-covariances between the blocks included.
// Jacobian of block i (ambient), first-estimate: A_i MinusJacobian_Mi(x_i), with A_i the
// columns of A = diag(1 / s) D^T that d_i multiplies; exact at x = x0, where it is A_i in the
// tangent (through PlusJacobian_M(x0)); a distance |d| from x0 changes it by a factor
// 1 + O(|d|) (for rotations Jr^-1(d)), negligible within a few sigma.
//
// The estimator adds it while it computes covariances: the directions it holds (the recent
// motion does not observe them, observability.h) are then free with the uncertainty they kept,
// so that what depends on them (the pose, along a held camera translation) shows it. And after
// a restart, with every direction, as the joint prior of the calibration blocks: the trusted
// calibration's values and covariance (trusted_calibration.h).
#pragma once

#include <ceres/cost_function.h>
#include <ceres/manifold.h>

#include <Eigen/Core>
#include <vector>

namespace mvis {

class TangentPriorFactor final : public ceres::CostFunction {
 public:
  struct Block {
    const ceres::Manifold* manifold;  // not owned, must outlive the factor; null: Euclidean
    std::vector<double> x0;           // the block's ambient size
  };
  // One block.
  TangentPriorFactor(const ceres::Manifold* manifold, std::vector<double> x0,
                     const Eigen::MatrixXd& directions, const Eigen::VectorXd& std);
  // Several, `directions` in their stacked tangent.
  TangentPriorFactor(std::vector<Block> blocks, const Eigen::MatrixXd& directions,
                     const Eigen::VectorXd& std);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  std::vector<Block> blocks_;
  std::vector<int> tangent_, offset_;
  Eigen::MatrixXd A_;  // diag(1 / s) D^T
};

}  // namespace mvis
