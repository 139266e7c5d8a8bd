// The square-root information of a covariance, for whitening residuals. Private to
// src/core/factors.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace mvis {

// L^T with L L^T = P^-1, so that |L^T r|^2 = r^T P^-1 r. P must be positive definite.
template <int N>
Eigen::Matrix<double, N, N> sqrtInformation(const Eigen::Matrix<double, N, N>& covariance) {
  using Matrix = Eigen::Matrix<double, N, N>;
  const Matrix information = covariance.ldlt().solve(Matrix::Identity());
  return Eigen::LLT<Matrix>(0.5 * (information + information.transpose())).matrixL().transpose();
}

// Whitens evaluated residuals and Jacobians in place: r <- S r and each requested block's rows
// J_b <- S J_b (row-major, N rows, `sizes` the blocks' ambient sizes), S upper triangular (as
// sqrtInformation gives). Done on doubles after the jets rather than on them: a product of jets
// carries every derivative through each multiply-add.
template <int N>
void whiten(const Eigen::Matrix<double, N, N>& S, const std::vector<int32_t>& sizes,
            double* residuals, double** jacobians) {
  Eigen::Map<Eigen::Matrix<double, N, 1>> r(residuals);
  r = S.template triangularView<Eigen::Upper>() * r;
  if (jacobians == nullptr) return;
  for (std::size_t b = 0; b < sizes.size(); ++b) {
    if (jacobians[b] == nullptr) continue;
    Eigen::Map<Eigen::Matrix<double, N, Eigen::Dynamic, Eigen::RowMajor>> J(jacobians[b], N,
                                                                            sizes[b]);
    J = S.template triangularView<Eigen::Upper>() * J;
  }
}

}  // namespace mvis
