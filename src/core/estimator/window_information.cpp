#include "mvis/estimator/window_information.h"

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <set>

namespace mvis {

StatusOr<Eigen::MatrixXd> windowInformation(ceres::Problem* problem,
                                            const std::vector<double*>& chosen) {
  const std::set<const double*> is_chosen(chosen.begin(), chosen.end());
  // Columns: every other variable block first (in the problem's order), the chosen ones last.
  std::vector<double*> all;
  problem->GetParameterBlocks(&all);
  ceres::Problem::EvaluateOptions eval;
  int nx = 0;
  for (double* block : all) {
    if (is_chosen.count(block) || problem->IsParameterBlockConstant(block)) continue;
    eval.parameter_blocks.push_back(block);
    nx += problem->ParameterBlockTangentSize(block);
  }
  int nc = 0;
  for (double* block : chosen) {
    if (problem->IsParameterBlockConstant(block)) {
      return Status::Error("window information: a chosen block is constant");
    }
    eval.parameter_blocks.push_back(block);
    nc += problem->ParameterBlockTangentSize(block);
  }
  // Rows: every residual but the chosen blocks' priors (those on chosen blocks only).
  std::vector<ceres::ResidualBlockId> residuals;
  problem->GetResidualBlocks(&residuals);
  std::vector<double*> on;
  for (ceres::ResidualBlockId id : residuals) {
    problem->GetParameterBlocksForResidualBlock(id, &on);
    const bool prior =
        std::all_of(on.begin(), on.end(), [&](const double* b) { return is_chosen.count(b) > 0; });
    if (!prior) eval.residual_blocks.push_back(id);
  }
  ceres::CRSMatrix crs;
  if (!problem->Evaluate(eval, nullptr, nullptr, nullptr, &crs)) {
    return Status::Error("window information: the problem did not evaluate");
  }
  const int n = nx + nc;
  if (crs.num_cols != n) return Status::Error("window information: unexpected Jacobian size");
  using Sparse = Eigen::SparseMatrix<double>;
  const Eigen::Map<const Eigen::SparseMatrix<double, Eigen::RowMajor>> J(
      crs.num_rows, crs.num_cols, static_cast<Eigen::Index>(crs.values.size()), crs.rows.data(),
      crs.cols.data(), crs.values.data());
  const Sparse Jc(J);
  const Sparse H = (Jc.transpose() * Jc).pruned();
  const Eigen::MatrixXd Hcc = Eigen::MatrixXd(H.bottomRightCorner(nc, nc));
  if (nx == 0) return Eigen::MatrixXd(0.5 * (Hcc + Hcc.transpose()));
  Sparse Hxx = H.topLeftCorner(nx, nx);
  double largest = 0.0;
  for (int k = 0; k < nx; ++k) largest = std::max(largest, Hxx.coeff(k, k));
  Sparse damping(nx, nx);
  damping.setIdentity();
  Hxx += (1e-10 * std::max(largest, 1.0)) * damping;
  Eigen::SimplicialLDLT<Sparse> ldlt(Hxx);
  if (ldlt.info() != Eigen::Success) {
    return Status::Error("window information: the other blocks' information did not factor");
  }
  const Eigen::MatrixXd Hxc = Eigen::MatrixXd(H.topRightCorner(nx, nc));
  const Eigen::MatrixXd X = ldlt.solve(Hxc);
  if (ldlt.info() != Eigen::Success || !X.allFinite()) {
    return Status::Error("window information: the Schur complement failed");
  }
  const Eigen::MatrixXd S = Hcc - Hxc.transpose() * X;
  return Eigen::MatrixXd(0.5 * (S + S.transpose()));
}

}  // namespace mvis
