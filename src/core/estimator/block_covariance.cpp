#include "block_covariance.h"

#include <ceres/crs_matrix.h>
#include <ceres/problem.h>

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

namespace mvis::estimator_internal {

bool BlockCovariance::compute(const std::vector<std::pair<const double*, const double*>>& blocks,
                              ceres::Problem* problem) {
  blocks_.clear();
  euclidean_.clear();
  columns_.clear();
  offset_.clear();
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
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(crs.values.size());
  for (int r = 0; r < crs.num_rows; ++r) {
    for (int k = crs.rows[r]; k < crs.rows[r + 1]; ++k) {
      entries.emplace_back(r, crs.cols[k], crs.values[k]);
    }
  }
  Eigen::SparseMatrix<double> J(crs.num_rows, crs.num_cols);
  J.setFromTriplets(entries.begin(), entries.end());
  const Eigen::SparseMatrix<double> H = (J.transpose() * J).pruned();
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(H);
  if (ldlt.info() != Eigen::Success) return false;
  const Eigen::VectorXd d = ldlt.vectorD();
  // Not positive definite (a direction without information): refused, as ceres::Covariance
  // refuses a rank-deficient Jacobian.
  if (!(d.minCoeff() > 1e-14 * d.cwiseAbs().maxCoeff())) return false;
  for (const auto& [a, b] : blocks) {
    const auto [offset, t] = columns.at(a);
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(n, t);
    for (int i = 0; i < t; ++i) rhs(offset + i, i) = 1.0;
    const Eigen::MatrixXd x = ldlt.solve(rhs);
    Eigen::MatrixXd C = x.middleRows(offset, t);
    blocks_[a] = 0.5 * (C + C.transpose());
    euclidean_[a] = problem->ParameterBlockSize(a) == t;
    columns_[a] = x;
    offset_[a] = offset;
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
    if (it == blocks_.end()) return false;
    n += static_cast<int>(it->second.rows());
  }
  out->resize(n, n);
  int row = 0;
  for (const double* a : blocks) {
    const int ta = static_cast<int>(blocks_.at(a).rows());
    int col = 0;
    for (const double* b : blocks) {
      const Eigen::MatrixXd& xb = columns_.at(b);
      const int tb = static_cast<int>(xb.cols());
      out->block(row, col, ta, tb) = xb.middleRows(offset_.at(a), ta);
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
