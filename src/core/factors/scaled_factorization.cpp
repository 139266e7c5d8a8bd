#include "scaled_factorization.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <cmath>

namespace mvis {
namespace scaled_factorization {

Eigen::VectorXd inverseOrZero(const Eigen::VectorXd& v) {
  return v.unaryExpr([](double x) { return x > 0 ? 1.0 / x : 0.0; });
}

ScaledEigen scaledEigen(const Eigen::MatrixXd& A, double eps) {
  ScaledEigen out;
  out.sqrt_d = A.diagonal().cwiseMax(0.0).cwiseSqrt();
  const Eigen::VectorXd inv = inverseOrZero(out.sqrt_d);
  const Eigen::MatrixXd B = inv.asDiagonal() * A * inv.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(0.5 * (B + B.transpose()));
  out.l = es.eigenvalues();
  out.V = es.eigenvectors();
  for (int i = 0; i < out.l.size(); ++i) {
    if (out.l[i] > eps) out.kept.push_back(i);
  }
  return out;
}

bool scaledCholesky(const Eigen::MatrixXd& A, ScaledCholesky* out) {
  const Eigen::VectorXd d = A.diagonal();
  if ((d.array() <= 0.0).any()) return false;
  out->sqrt_d = d.cwiseSqrt();
  const Eigen::VectorXd inv = out->sqrt_d.cwiseInverse();
  Eigen::MatrixXd B = inv.asDiagonal() * A * inv.asDiagonal();
  Eigen::LLT<Eigen::MatrixXd> llt(0.5 * (B + B.transpose()));
  if (llt.info() != Eigen::Success) return false;
  out->L = llt.matrixL();
  return out->L.diagonal().cwiseAbs2().minCoeff() > kPivot;
}

bool scaledSemidefiniteFactor(const Eigen::MatrixXd& A, double eps, Eigen::VectorXd* sqrt_d,
                              Eigen::MatrixXd* J, std::vector<int>* pivots) {
  const Eigen::Index n = A.rows();
  *sqrt_d = A.diagonal().cwiseMax(0.0).cwiseSqrt();
  const Eigen::VectorXd inv = inverseOrZero(*sqrt_d);
  const Eigen::MatrixXd S = inv.asDiagonal() * A * inv.asDiagonal();
  Eigen::MatrixXd L = Eigen::MatrixXd::Zero(n, n);  // column j: L_:j sqrt(d_j)
  pivots->clear();
  for (Eigen::Index j = 0; j < n; ++j) {
    // L_:j sqrt(d_j) = (S_:j - sum over earlier kept p of L_:p sqrt(d_p) L_jp sqrt(d_p)) / ...
    Eigen::VectorXd c = S.col(j).tail(n - j);
    for (int p : *pivots) c.noalias() -= L.col(p).tail(n - j) * L(j, p);
    if (!(c[0] > eps)) continue;
    const Eigen::VectorXd col = c / std::sqrt(c[0]);
    if (!(col.cwiseAbs().maxCoeff() < kLargest)) return false;
    L.col(j).tail(n - j) = col;
    pivots->push_back(static_cast<int>(j));
  }
  J->resize(static_cast<Eigen::Index>(pivots->size()), n);
  for (std::size_t i = 0; i < pivots->size(); ++i) J->row(i) = L.col((*pivots)[i]).transpose();
  return true;
}

Eigen::MatrixXd pseudoInverse(const Eigen::MatrixXd& A, double eps) {
  ScaledCholesky c;
  if (scaledCholesky(A, &c)) {
    // A^-1 = D^-1/2 L^-T L^-1 D^-1/2.
    Eigen::MatrixXd Li = Eigen::MatrixXd::Identity(A.rows(), A.cols());
    c.L.triangularView<Eigen::Lower>().solveInPlace(Li);
    const Eigen::MatrixXd M = Li * c.sqrt_d.cwiseInverse().asDiagonal();
    return M.transpose() * M;
  }
  const ScaledEigen e = scaledEigen(A, eps);
  const Eigen::VectorXd inv_d = inverseOrZero(e.sqrt_d);
  Eigen::MatrixXd inner = Eigen::MatrixXd::Zero(A.rows(), A.cols());
  for (int i : e.kept) inner += e.V.col(i) * e.V.col(i).transpose() / e.l[i];
  return inv_d.asDiagonal() * inner * inv_d.asDiagonal();
}

}  // namespace scaled_factorization
}  // namespace mvis
