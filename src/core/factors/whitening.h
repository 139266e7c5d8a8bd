// The square-root information of a covariance, for whitening residuals. Private to
// src/core/factors.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>

namespace mvis {

// L^T with L L^T = P^-1, so that |L^T r|^2 = r^T P^-1 r. P must be positive definite.
template <int N>
Eigen::Matrix<double, N, N> sqrtInformation(const Eigen::Matrix<double, N, N>& covariance) {
  using Matrix = Eigen::Matrix<double, N, N>;
  const Matrix information = covariance.ldlt().solve(Matrix::Identity());
  return Eigen::LLT<Matrix>(0.5 * (information + information.transpose())).matrixL().transpose();
}

}  // namespace mvis
