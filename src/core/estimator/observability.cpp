#include "mvis/estimator/observability.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <cstdio>
#include <sstream>

#include "mvis/estimator/estimator.h"

namespace mvis {

std::string UnobservableCalibration::text() const {
  std::ostringstream s;
  if (!shared.empty()) {
    s << "shared direction of";
    for (std::size_t k = 0; k < shared.size(); ++k) s << (k ? ", " : " ") << shared[k];
    s << ": " << advice;
    return s.str();
  }
  s << sensor << ' ' << quantity;
  if (!elements.empty()) {
    s << " (";
    for (std::size_t k = 0; k < elements.size(); ++k) s << (k ? ", " : "") << elements[k];
    s << ')';
    if (!advice.empty()) {
      s << ": " << advice;
      return s.str();
    }
    bool rate = false, force = false;
    for (const auto& e : elements) {
      (e.rfind("dw", 0) == 0 || e.rfind("theta_g", 0) == 0 ? rate : force) = true;
    }
    s << ": vary " << (rate ? "the rate of rotation about" : "") << (rate && force ? ", and " : "")
      << (force ? "the specific force along" : "") << " each of " << sensor << "'s axes"
      << (force ? " (tilt the rig, accelerate it)" : "");
  } else if (directions_I.empty()) {
    s << ": vary the rig's rate of rotation";  // only gyroscope time offsets are checked
  } else if (directions_I.size() == 1) {
    char d[64];
    std::snprintf(d, sizeof d, "(%.2f, %.2f, %.2f)", directions_I[0].x(), directions_I[0].y(),
                  directions_I[0].z());
    s << (quantity == "rotation" ? " about " : " along ") << d << " in " << base
      << ": rotate about another axis too";
  } else {
    s << ": rotate the rig about more than one axis";
  }
  return s.str();
}

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

Eigen::MatrixXd consideredCovariance(const Eigen::MatrixXd& sigma, const Eigen::MatrixXd& U,
                                     const Eigen::VectorXd& v) {
  const Eigen::MatrixXd SU = sigma * U;
  const Eigen::MatrixXd S = U.transpose() * SU;
  const Eigen::LLT<Eigen::MatrixXd> llt(0.5 * (S + S.transpose()));
  if (U.cols() == 0 || llt.info() != Eigen::Success) return sigma;
  const Eigen::MatrixXd Linv = llt.matrixL().solve(Eigen::MatrixXd::Identity(S.rows(), S.cols()));
  const Eigen::MatrixXd X = Linv * v.asDiagonal() * Linv.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (X + X.transpose()));
  const Eigen::MatrixXd G = SU * Linv.transpose() * eig.eigenvectors();
  const Eigen::VectorXd grow = (eig.eigenvalues().array() - 1.0).cwiseMax(0.0).matrix();
  return sigma + G * grow.asDiagonal() * G.transpose();
}

}  // namespace mvis
