#include "block_covariance.h"

#include <ceres/cost_function.h>
#include <ceres/crs_matrix.h>
#include <ceres/problem.h>

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <map>
#include <utility>

namespace mvis::estimator_internal {
namespace {

// Blocks not listed whose own information has directions without any (eigenvalues under 1e-10
// of the block's largest, or 1e-14 of H's largest diagonal element: a tag's corner seen from one
// state only, its depth along the ray) get a ridge along those directions, 1e-8 of the block's
// largest eigenvalue (at least 1e-12 of H's largest element). Such a direction v has H v = 0 (H
// is positive semi-definite and v^T H v = 0): it is coupled to nothing, so the ridge changes no
// other direction's covariance. False if no block had one. `unlisted`: offset and tangent size
// of each block not listed.
bool ridgeUnmeasured(const std::vector<std::pair<int, int>>& unlisted,
                     Eigen::SparseMatrix<double>* H) {
  const double largest = H->diagonal().cwiseAbs().maxCoeff();
  bool any = false;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen;
  for (const auto& [offset, t] : unlisted) {
    eigen.compute(Eigen::MatrixXd(H->block(offset, offset, t, t)));
    const Eigen::VectorXd& values = eigen.eigenvalues();  // ascending
    const double top = values[t - 1];
    const double ridge = std::max(1e-8 * top, 1e-12 * largest);
    for (int k = 0; k < t && values[k] <= std::max(1e-10 * top, 1e-14 * largest); ++k) {
      const Eigen::VectorXd v = eigen.eigenvectors().col(k);
      for (int i = 0; i < t; ++i) {
        for (int j = 0; j < t; ++j) H->coeffRef(offset + i, offset + j) += ridge * v[i] * v[j];
      }
      any = true;
    }
  }
  return any;
}

}  // namespace

bool BlockCovariance::compute(const std::vector<std::pair<const double*, const double*>>& blocks,
                              ceres::Problem* problem, bool joint_wanted,
                              const RowClusters* clusters) {
  blocks_.clear();
  euclidean_.clear();
  columns_.clear();
  clustered_.resize(0, 0);
  offset_.clear();
  ratio_.clear();
  model_.clear();
  show_model_ = false;
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
  evaluate.residual_blocks = residuals;
  evaluate.apply_loss_function = true;
  ceres::CRSMatrix crs;
  std::vector<double> r;
  if (!problem->Evaluate(evaluate, nullptr, clusters != nullptr ? &r : nullptr, nullptr, &crs)) {
    return false;
  }
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
  // Not positive definite (a direction without information): refused, as ceres::Covariance
  // refuses a rank-deficient Jacobian, unless all such directions are in blocks not listed
  // that nothing measures at all (ridgeUnmeasured).
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt;
  const auto factored = [&] {
    ldlt.compute(H);
    if (ldlt.info() != Eigen::Success) return false;
    const Eigen::VectorXd& d = ldlt.vectorD();
    return d.minCoeff() > 1e-14 * d.cwiseAbs().maxCoeff();
  };
  if (!factored()) {
    std::vector<std::pair<int, int>> unlisted;
    for (const double* block : variable) {
      const auto is = [block](const auto& b) { return b.first == block; };
      if (std::none_of(blocks.begin(), blocks.end(), is)) {
        unlisted.push_back(columns.at(block));
      }
    }
    if (!ridgeUnmeasured(unlisted, &H) || !factored()) return false;
  }
  const Eigen::VectorXd d = ldlt.vectorD();
  // H = P^T L D L^T P, so H^-1 = W^T W with W = D^-1/2 L^-1 P: a block's rows of the inverse
  // meet another's as W_a^T W_b. Only the forward solve, and Eigen's skips the columns of L the
  // unit vectors do not reach: a batch's pose covariances took 4x less than with full solves.
  const Eigen::VectorXd scale = d.cwiseInverse().cwiseSqrt();
  int k = 0;
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
    offset_[a] = k;
    k += t;
    if (joint_wanted || clusters != nullptr) columns_[a] = std::move(w);
  }
  if (clusters == nullptr) return true;
  // K^T = H^-1 E = P^T L^-T D^-1/2 (W E): the listed blocks' columns of the inverse.
  Eigen::MatrixXd X(n, k);
  for (const auto& [a, b] : blocks) X.middleCols(offset_.at(a), blocks_.at(a).rows()) = columns_[a];
  const Eigen::MatrixXd C = X.transpose() * X;
  X = scale.asDiagonal() * X;
  ldlt.matrixU().solveInPlace(X);
  X = ldlt.permutationPinv() * X;
  clustered_ = C + excess(*clusters, residuals, problem, crs, r, X);
  clustered_ = 0.5 * (clustered_ + clustered_.transpose());
  for (const auto& [a, b] : blocks) {
    const int o = offset_.at(a), t = static_cast<int>(blocks_.at(a).rows());
    const Eigen::MatrixXd V = clustered_.block(o, o, t, t);
    ratio_[a] = (V.diagonal().array() / blocks_[a].diagonal().array()).sqrt();
    model_[a] = std::exchange(blocks_[a], V);
  }
  if (!joint_wanted) columns_.clear();
  return true;
}

Eigen::MatrixXd BlockCovariance::excess(const RowClusters& clusters,
                                        const std::vector<ceres::ResidualBlockId>& ids,
                                        ceres::Problem* problem, const ceres::CRSMatrix& crs,
                                        const std::vector<double>& r, const Eigen::MatrixXd& X) {
  const int k = static_cast<int>(X.cols());
  // Per group: K H_g K^T, the clusters' sums of K J_i^T r_i per way, and the observations' part.
  struct Group {
    Eigen::MatrixXd model, observations;
    std::map<int, Eigen::VectorXd> a, b;
  };
  std::map<int, Group> groups;
  Eigen::MatrixXd A, Xs, G;
  Eigen::VectorXd s = Eigen::VectorXd::Zero(k), u(k);
  int row = 0;
  for (const ceres::ResidualBlockId id : ids) {
    const int m = problem->GetCostFunctionForResidualBlock(id)->num_residuals();
    const auto it = clusters.blocks.find(id);
    const int first = row;
    row += m;
    if (it == clusters.blocks.end() || static_cast<int>(it->second.rows.size()) != m) continue;
    const auto& labels = it->second.rows;
    Group& group = groups[it->second.group];
    if (group.model.size() == 0) {
      group.model = Eigen::MatrixXd::Zero(k, k);
      group.observations = Eigen::MatrixXd::Zero(k, k);
    }
    const int begin = crs.rows[first], width = crs.rows[first + 1] - begin;
    A.setZero(m, width);
    Xs.resize(width, k);
    for (int c = 0; c < width; ++c) Xs.row(c) = X.row(crs.cols[begin + c]);
    for (int i = 0; i < m; ++i) {
      // A residual block's rows share its columns.
      if (crs.rows[first + i + 1] - crs.rows[first + i] != width) continue;
      for (int c = 0; c < width; ++c) A(i, c) = crs.values[crs.rows[first + i] + c];
    }
    G.noalias() = A * Xs;  // J_i K^T, row by row
    group.model.noalias() += G.transpose() * G;
    for (int i = 0; i < m; ++i) {
      const auto [ca, cb] = labels[static_cast<std::size_t>(i)];
      u.noalias() = G.row(i).transpose() * r[static_cast<std::size_t>(first + i)];
      for (auto [sums, c] : {std::make_pair(&group.a, ca), std::make_pair(&group.b, cb)}) {
        auto [at, made] = sums->try_emplace(c, u);
        if (!made) at->second += u;
      }
      s += u;
      if (i + 1 == m || labels[static_cast<std::size_t>(i + 1)] != labels[i]) {
        group.observations.noalias() += s * s.transpose();
        s.setZero();
      }
    }
  }
  const auto way = [k](const std::map<int, Eigen::VectorXd>& sums) {
    Eigen::MatrixXd M = Eigen::MatrixXd::Zero(k, k);
    for (const auto& [c, v] : sums) M.noalias() += v * v.transpose();
    const double n = static_cast<double>(sums.size());
    return n > 1.0 ? Eigen::MatrixXd(M * (n / (n - 1.0))) : M;
  };
  // The residuals' meat beyond the model's, per group, its negative part dropped.
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(k, k);
  for (const auto& [g, group] : groups) {
    Eigen::MatrixXd D = way(group.a) + way(group.b) - group.observations - group.model;
    D = 0.5 * (D + D.transpose());
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(D);
    out += eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).asDiagonal() *
           eig.eigenvectors().transpose();
  }
  return out;
}

bool BlockCovariance::GetCovarianceBlockInTangentSpace(const double* a, const double* b,
                                                       double* out) const {
  const auto& from = show_model_ && !model_.empty() ? model_ : blocks_;
  const auto it = from.find(a);
  if (a != b || it == from.end()) return false;
  const Eigen::MatrixXd& C = it->second;
  Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(out, C.rows(),
                                                                                     C.cols()) = C;
  return true;
}

bool BlockCovariance::sigmaRatio(const double* block, Eigen::VectorXd* out) const {
  const auto it = ratio_.find(block);
  if (it == ratio_.end()) return false;
  *out = it->second;
  return true;
}

bool BlockCovariance::joint(const std::vector<const double*>& blocks, Eigen::MatrixXd* out) const {
  const bool clustered = clustered_.size() > 0 && !show_model_;
  int n = 0;
  for (const double* b : blocks) {
    const auto it = blocks_.find(b);
    if (it == blocks_.end() || (clustered ? offset_.count(b) : columns_.count(b)) == 0) {
      return false;
    }
    n += static_cast<int>(it->second.rows());
  }
  out->resize(n, n);
  int row = 0;
  for (const double* a : blocks) {
    const int ta = static_cast<int>(blocks_.at(a).rows());
    int col = 0;
    for (const double* b : blocks) {
      const int tb = static_cast<int>(blocks_.at(b).rows());
      out->block(row, col, ta, tb) =
          clustered ? Eigen::MatrixXd(clustered_.block(offset_.at(a), offset_.at(b), ta, tb))
                    : Eigen::MatrixXd(columns_.at(a).transpose() * columns_.at(b));
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
