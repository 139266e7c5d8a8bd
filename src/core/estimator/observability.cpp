#include "mvis/estimator/observability.h"

#include <Eigen/Eigenvalues>
#include <Eigen/QR>

namespace mvis {

WeakDirections weakDirections(const Eigen::MatrixXd& W, const Eigen::VectorXd& prior_std,
                              double ratio) {
  const auto n = W.rows();
  const Eigen::MatrixXd S = prior_std.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(0.5 * (W + W.transpose()));
  int k = 0;
  while (k < n && es.eigenvalues()[k] < ratio) ++k;  // ascending
  WeakDirections out;
  out.gains = es.eigenvalues().head(k);
  if (k == 0) {
    out.directions.resize(n, 0);
    return out;
  }
  const Eigen::MatrixXd D = S * es.eigenvectors().leftCols(k);
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(D);
  out.directions = qr.householderQ() * Eigen::MatrixXd::Identity(n, k);
  return out;
}

}  // namespace mvis
