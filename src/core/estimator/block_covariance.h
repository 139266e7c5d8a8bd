// Diagonal blocks of the covariance of a Ceres problem's parameter blocks, in their tangent
// spaces: the inverse of the Gauss-Newton information J^T J at the current estimate (loss
// functions applied), for the variable blocks; constant blocks are conditioned on.
//
// ceres::Covariance does the same but orders the Jacobian's columns by the blocks' addresses,
// so its results move in the last digits with where the allocator put the states (measured: 7 of
// 20 numbers of a short run differed by 1e-17 after other allocations), and with them every
// decision taken on a covariance (the observability holds): one run gave two answers. Here the
// columns follow the order in which the residual blocks (which Ceres keeps in insertion order)
// first mention the blocks (Problem::GetParameterBlocks lists them by address too), and J^T J
// is factored by Eigen's sparse LDL^T with its fill-reducing ordering computed from that
// structure alone: the same sequence of operations gives the same bytes.
#pragma once

#include <Eigen/Core>
#include <unordered_map>
#include <utility>
#include <vector>

namespace ceres {
class Problem;
}

namespace mvis::estimator_internal {

class BlockCovariance {
 public:
  // Computes the diagonal blocks of the blocks listed (pairs (a, a); others are refused). False
  // if a listed block is unknown or constant, or the information is not positive definite.
  // Without `joint_wanted` only the diagonal blocks are kept (joint() refuses): for many blocks
  // (a batch's poses) the columns joint() needs would take rows x 6 numbers each.
  bool compute(const std::vector<std::pair<const double*, const double*>>& blocks,
               ceres::Problem* problem, bool joint_wanted = true);

  // The tangent-space block (tangent size squared, row-major) of a block that was computed and
  // the same for the ambient block of a Euclidean one (tangent = ambient); false otherwise.
  bool GetCovarianceBlockInTangentSpace(const double* a, const double* b, double* out) const;
  bool GetCovarianceBlock(const double* a, const double* b, double* out) const;
  // The joint tangent covariance of computed blocks, stacked in the order given (their
  // cross-covariances too); false if one was not computed.
  bool joint(const std::vector<const double*>& blocks, Eigen::MatrixXd* out) const;

 private:
  std::unordered_map<const double*, Eigen::MatrixXd> blocks_;
  // Per computed block its columns of W (H^-1 = W^T W, block_covariance.cpp), for joint().
  std::unordered_map<const double*, Eigen::MatrixXd> columns_;
  std::unordered_map<const double*, bool> euclidean_;
};

}  // namespace mvis::estimator_internal
