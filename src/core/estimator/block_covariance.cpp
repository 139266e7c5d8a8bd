#include "block_covariance.h"

#include <ceres/crs_matrix.h>
#include <ceres/problem.h>

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <utility>

namespace mvis::estimator_internal {

bool BlockCovariance::compute(const std::vector<std::pair<const double*, const double*>>& blocks,
                              ceres::Problem* problem, bool joint_wanted) {
  blocks_.clear();
  euclidean_.clear();
  columns_.clear();
  // Columns: the variable blocks in the order the residual blocks (kept by Ceres in insertion
  // order) first mention them. Problem::GetParameterBlocks would give them by address.
  std::vector<ceres::ResidualBlockId> residuals;
  problem->GetResidualBlocks(&residuals);
  std::vector<double*> variable, of_residual;
  std::unordered_map<const double*, std::pair<int, int>> columns;  // offset, tangent size
  int n = 0;
  for (const ceres::ResidualBlockId id : residuals) {
    of_residual.clear();
    problem->GetParameterBlocksForResidualBlock(id, &of_residual);
    for (double* block : of_residual) {
      if (columns.count(block) || problem->IsParameterBlockConstant(block)) continue;
      const int t = problem->ParameterBlockTangentSize(block);
      if (t == 0) continue;
      variable.push_back(block);
      columns[block] = {n, t};
      n += t;
    }
  }
  for (const auto& [a, b] : blocks) {
    if (a != b || columns.count(a) == 0) return false;
  }
  if (n == 0) return false;
  ceres::Problem::EvaluateOptions evaluate;
  evaluate.parameter_blocks = variable;
  evaluate.apply_loss_function = true;
  ceres::CRSMatrix crs;
  if (!problem->Evaluate(evaluate, nullptr, nullptr, nullptr, &crs)) return false;
  // H = J^T J, a run of rows with the same columns (a residual block's) at a time: a dense
  // product per run. Eigen's sparse J^T J took 35 s for a 20 s batch (415k rows), this 0.3 s.
  std::vector<Eigen::Triplet<double>> entries;
  const auto columnsOf = [&crs](int r) {
    return std::make_pair(crs.cols.begin() + crs.rows[r], crs.cols.begin() + crs.rows[r + 1]);
  };
  Eigen::MatrixXd A, G;
  for (int r = 0; r < crs.num_rows;) {
    const auto [first, last] = columnsOf(r);
    const int width = static_cast<int>(last - first);
    int end = r + 1;
    while (end < crs.num_rows) {
      const auto [f, l] = columnsOf(end);
      if (l - f != width || !std::equal(f, l, first)) break;
      ++end;
    }
    A.resize(end - r, width);
    for (int i = r; i < end; ++i) {
      for (int k = 0; k < width; ++k) A(i - r, k) = crs.values[crs.rows[i] + k];
    }
    G.noalias() = A.transpose() * A;
    for (int a = 0; a < width; ++a) {
      for (int b = 0; b < width; ++b) entries.emplace_back(first[a], first[b], G(a, b));
    }
    r = end;
  }
  Eigen::SparseMatrix<double> H(crs.num_cols, crs.num_cols);
  H.setFromTriplets(entries.begin(), entries.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(H);
  if (ldlt.info() != Eigen::Success) return false;
  const Eigen::VectorXd d = ldlt.vectorD();
  // Not positive definite (a direction without information): refused, as ceres::Covariance
  // refuses a rank-deficient Jacobian.
  if (!(d.minCoeff() > 1e-14 * d.cwiseAbs().maxCoeff())) return false;
  // H = P^T L D L^T P, so H^-1 = W^T W with W = D^-1/2 L^-1 P: a block's rows of the inverse
  // meet another's as W_a^T W_b. Only the forward solve, and Eigen's skips the columns of L the
  // unit vectors do not reach: a batch's pose covariances took 4x less than with full solves.
  const Eigen::VectorXd scale = d.cwiseInverse().cwiseSqrt();
  for (const auto& [a, b] : blocks) {
    const auto [offset, t] = columns.at(a);
    Eigen::MatrixXd w = Eigen::MatrixXd::Zero(n, t);
    for (int i = 0; i < t; ++i) w(offset + i, i) = 1.0;
    w = ldlt.permutationP() * w;
    ldlt.matrixL().solveInPlace(w);
    w = scale.asDiagonal() * w;
    const Eigen::MatrixXd C = w.transpose() * w;
    blocks_[a] = 0.5 * (C + C.transpose());
    euclidean_[a] = problem->ParameterBlockSize(a) == t;
    if (joint_wanted) columns_[a] = std::move(w);
  }
  return true;
}

bool BlockCovariance::GetCovarianceBlockInTangentSpace(const double* a, const double* b,
                                                       double* out) const {
  const auto it = blocks_.find(a);
  if (a != b || it == blocks_.end()) return false;
  const Eigen::MatrixXd& C = it->second;
  Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(out, C.rows(),
                                                                                     C.cols()) = C;
  return true;
}

bool BlockCovariance::joint(const std::vector<const double*>& blocks, Eigen::MatrixXd* out) const {
  int n = 0;
  for (const double* b : blocks) {
    const auto it = blocks_.find(b);
    if (it == blocks_.end() || columns_.count(b) == 0) return false;
    n += static_cast<int>(it->second.rows());
  }
  out->resize(n, n);
  int row = 0;
  for (const double* a : blocks) {
    const int ta = static_cast<int>(blocks_.at(a).rows());
    int col = 0;
    for (const double* b : blocks) {
      const Eigen::MatrixXd& wb = columns_.at(b);
      const int tb = static_cast<int>(wb.cols());
      out->block(row, col, ta, tb) = columns_.at(a).transpose() * wb;
      col += tb;
    }
    row += ta;
  }
  *out = 0.5 * (*out + out->transpose());
  return true;
}

bool BlockCovariance::GetCovarianceBlock(const double* a, const double* b, double* out) const {
  const auto e = euclidean_.find(a);
  if (e == euclidean_.end() || !e->second) return false;
  return GetCovarianceBlockInTangentSpace(a, b, out);
}

}  // namespace mvis::estimator_internal
