// Factorizations of a symmetric positive semi-definite matrix after Jacobi scaling, for the
// marginalization prior (marginalization_factor.h): the information of its blocks spans many
// orders of magnitude (biases ~1e10, gravity ~1), and scaling by D = diag(A) makes every
// threshold relative to each direction's own scale. Private to the core (src/core/factors, and
// the estimator's change test, change_detector.cpp).
#pragma once

#include <Eigen/Core>
#include <vector>

namespace mvis {
namespace scaled_factorization {

// 1 / v per element, 0 where v is not positive (a scale D^1/2 with a zero on the diagonal).
Eigen::VectorXd inverseOrZero(const Eigen::VectorXd& v);

// A = D^1/2 (V diag(l) V^T) D^1/2; eigenvalues l <= eps count as zero.
struct ScaledEigen {
  Eigen::VectorXd sqrt_d;  // D^1/2
  Eigen::VectorXd l;
  Eigen::MatrixXd V;
  std::vector<int> kept;  // indices of l > eps
};
ScaledEigen scaledEigen(const Eigen::MatrixXd& A, double eps);

// Cholesky factor of the scaled matrix, D^-1/2 A D^-1/2 = L L^T, when A is clearly positive
// definite: every pivot L_ii^2 above kPivot (the scaled diagonal is 1, so pivots are relative; a
// rank-deficient matrix leaves round-off pivots near 1e-16). Otherwise false, and the
// eigen-decomposition decides what counts as zero.
constexpr double kPivot = 1e-10;
struct ScaledCholesky {
  Eigen::VectorXd sqrt_d;  // D^1/2
  Eigen::MatrixXd L;       // lower triangular
};
bool scaledCholesky(const Eigen::MatrixXd& A, ScaledCholesky* out);

// Rows of a factor J of the scaled D^-1/2 A D^-1/2 = J^T J, by LDL^T in the given order with
// pivots at or below `eps` skipped (their column is what the earlier ones already explain: for
// a semi-definite matrix a zero pivot has a zero column): J = D_p^1/2 L^T over the kept pivots
// (`pivots`, ascending), upper triangular like the Cholesky factor, at a third of an
// eigen-decomposition's cost. False if a kept column grows beyond kLargest (round-off behind a
// small pivot: the eigen-decomposition is the safe way then).
constexpr double kLargest = 1e6;
bool scaledSemidefiniteFactor(const Eigen::MatrixXd& A, double eps, Eigen::VectorXd* sqrt_d,
                              Eigen::MatrixXd* J, std::vector<int>* pivots);

// Pseudo-inverse of a symmetric positive semi-definite matrix (Cholesky when clearly positive
// definite, else the eigenvalues above eps).
Eigen::MatrixXd pseudoInverse(const Eigen::MatrixXd& A, double eps);

}  // namespace scaled_factorization
}  // namespace mvis
