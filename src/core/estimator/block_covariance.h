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
//
// Clustered (a batch's calibration on real data, EstimatorOptions::batch_covariance): the
// inverse information trusts every residual's noise model. Where the data say otherwise (real
// corners: a board corner's error stays with it over hundreds of frames, a frame's corners share
// a little of theirs; inertial errors correlated over seconds), the sandwich H^-1 M H^-1 (Huber
// 1967, White 1980) takes a group of rows' errors from their residuals r (whitened, after the
// loss) instead of their model. Per group g (the corners, each inertial sensor):
//   M_g = G_A/(G_A-1) sum_a s_a s_a^T + G_B/(G_B-1) sum_b s_b s_b^T - sum_ab s_ab s_ab^T,
//   s = sum of J_i^T r_i over the group's rows in a cluster,
// the two-way clustering of Cameron, Gelbach & Miller (2011): errors correlated within a cluster
// of either way (a corner's track over the recording or a second of an inertial sensor's
// factors; a second of frames or one inertial factor) count as they are, clusters of different
// ids in both ways are taken as independent; G_A, G_B the group's clusters per way. The model is a floor: a
// fit's residuals are smaller than its errors (by the leverage the states take, large for
// inertial factors whose 15 rows per state meet 15 state parameters), and a noise model the
// residuals undercut (real corners' RMS 0.2-0.3 px against the configured 1 px) is the user's
// statement of the sensor. So each group adds only what its M_g exceeds its model information:
//   V = C + sum_g (K M_g K^T - K H_g K^T)^+,   H_g = sum over the group's rows of J_i^T J_i,
// (.)^+ dropping negative eigenvalues, in the listed blocks' space: only their rows K of H^-1
// are needed, K^T = H^-1 E = P^T L^-T D^-1/2 (W E) (k backward solves), and K J_i^T =
// (J_i K^T)^T is formed per residual block. V >= C always; on residuals that fit their model
// (white, unit variance) V stays near C (measured in test_estimator_batch).
#pragma once

#include <Eigen/Core>
#include <unordered_map>
#include <utility>
#include <vector>

namespace ceres {
class Problem;
struct CRSMatrix;
namespace internal {
class ResidualBlock;
}
using ResidualBlockId = internal::ResidualBlock*;
}  // namespace ceres

namespace mvis::estimator_internal {

// Rows whose errors the covariance takes from their residuals (see above): per residual block
// (its ceres::ResidualBlockId) its group (e.g. the corners, each inertial sensor: each group's
// excess over its model is taken separately) and per row its cluster id in each of two ways
// (>= 0). Consecutive rows with the same pair form one observation.
struct RowClusters {
  struct Block {
    int group = 0;
    std::vector<std::pair<int, int>> rows;
  };
  std::unordered_map<const void*, Block> blocks;
};

class BlockCovariance {
 public:
  // Computes the diagonal blocks of the blocks listed (pairs (a, a); others are refused). False
  // if a listed block is unknown or constant, or the information is not positive definite.
  // Without `joint_wanted` only the diagonal blocks are kept (joint() refuses): for many blocks
  // (a batch's poses) the columns joint() needs would take rows x 6 numbers each.
  // With `clusters` the listed blocks' covariance is the clustered one (above).
  bool compute(const std::vector<std::pair<const double*, const double*>>& blocks,
               ceres::Problem* problem, bool joint_wanted = true,
               const RowClusters* clusters = nullptr);

  // The tangent-space block (tangent size squared, row-major) of a block that was computed and
  // the same for the ambient block of a Euclidean one (tangent = ambient); false otherwise.
  bool GetCovarianceBlockInTangentSpace(const double* a, const double* b, double* out) const;
  bool GetCovarianceBlock(const double* a, const double* b, double* out) const;
  // The joint tangent covariance of computed blocks, stacked in the order given (their
  // cross-covariances too); false if one was not computed.
  bool joint(const std::vector<const double*>& blocks, Eigen::MatrixXd* out) const;
  // After a clustered compute: a block's standard deviations over the inverse information's,
  // per tangent direction; false otherwise.
  bool sigmaRatio(const double* block, Eigen::VectorXd* out) const;
  // After a clustered compute, what the getters above return: the inverse information (true)
  // or the clustered covariance (false, the default).
  void showModel(bool model) { show_model_ = model; }

 private:
  // sum_g (K M_g K^T - K H_g K^T)^+ (above) from the residuals `r` and Jacobian `crs` of the blocks
  // `ids`, X = K^T.
  static Eigen::MatrixXd excess(const RowClusters& clusters,
                                const std::vector<ceres::ResidualBlockId>& ids,
                                ceres::Problem* problem, const ceres::CRSMatrix& crs,
                                const std::vector<double>& r, const Eigen::MatrixXd& X);

  std::unordered_map<const double*, Eigen::MatrixXd> blocks_;
  // Per computed block its columns of W (H^-1 = W^T W, block_covariance.cpp), for joint().
  std::unordered_map<const double*, Eigen::MatrixXd> columns_;
  std::unordered_map<const double*, bool> euclidean_;
  // Clustered: the listed blocks' joint covariance and each block's offset in it.
  Eigen::MatrixXd clustered_;
  std::unordered_map<const double*, int> offset_;
  std::unordered_map<const double*, Eigen::VectorXd> ratio_;
  std::unordered_map<const double*, Eigen::MatrixXd> model_;  // the model's blocks, clustered
  bool show_model_ = false;
};

}  // namespace mvis::estimator_internal
