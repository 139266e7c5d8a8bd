#include "change_detector.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

namespace mvis {
namespace estimator_internal {
namespace {

using Matrix7 = ChangeDetector::Matrix7;
using Vector7 = ChangeDetector::Vector7;

// The chi-square distribution's quantile with n degrees of freedom at the standard normal's z
// (Wilson and Hilferty 1931; within 1% from n = 7 at z = 3.09, the 0.999 quantile).
double chiSquareQuantile(double n, double z) {
  const double a = 2.0 / (9.0 * n);
  return n * std::pow(1.0 - a + z * std::sqrt(a), 3);
}
constexpr double kStepZ = 3.09;  // the step's consistency test at 1 - 1e-3

double median(std::deque<double> v) {
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

}  // namespace

Eigen::MatrixXd pseudoInverse(const Eigen::MatrixXd& H) {
  const Eigen::Index n = H.rows();
  Eigen::VectorXd s = Eigen::VectorXd::Zero(n);
  for (Eigen::Index i = 0; i < n; ++i) s[i] = H(i, i) > 0.0 ? 1.0 / std::sqrt(H(i, i)) : 0.0;
  const Eigen::MatrixXd scaled = s.asDiagonal() * H * s.asDiagonal();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (scaled + scaled.transpose()));
  const Eigen::VectorXd l = eig.eigenvalues();
  const double floor = 1e-9 * std::max(l.maxCoeff(), 0.0);
  Eigen::VectorXd inv = Eigen::VectorXd::Zero(n);
  for (Eigen::Index i = 0; i < n; ++i) inv[i] = l[i] > floor ? 1.0 / l[i] : 0.0;
  return s.asDiagonal() * eig.eigenvectors() * inv.asDiagonal() * eig.eigenvectors().transpose() *
         s.asDiagonal();
}

Matrix7 pseudoInverse(const Matrix7& H) { return pseudoInverse(Eigen::MatrixXd(H)); }

ChangeDetector::ChangeDetector(std::size_t cameras) : cameras_(cameras) {}

void ChangeDetector::addFrame(std::size_t c, TimeNs t, const Eigen::VectorXd& r,
                              const Eigen::MatrixXd& J) {
  if (c >= cameras_.size() || J.cols() != kDim || J.rows() != r.size() || r.size() == 0) return;
  if (!r.allFinite() || !J.allFinite()) return;
  Camera& cam = cameras_[c];
  if (cam.has_open && t >= cam.open.start + kBinNs) close(cam);
  if (cam.has_open && t < cam.open.start) return;  // out of order (a restart's leftovers)
  if (!cam.has_open) {
    cam.open = Bin();
    cam.open.start = t;
    cam.has_open = true;
  }
  cam.open.H.noalias() += J.transpose() * J;
  cam.open.g.noalias() += J.transpose() * r;
  ++cam.open.frames;
}

void ChangeDetector::close(Camera& cam) {
  cam.has_open = false;
  if (cam.open.frames < kMinFramesPerBin) return;
  if (cam.first < 0) cam.first = cam.open.start;
  cam.closed.push_back(cam.open);
  if (static_cast<int>(cam.closed.size()) > kBins) cam.closed.pop_front();
  cam.tested = false;
  // The noise level: the closed bins' steps about their common one, over their model.
  if (static_cast<int>(cam.closed.size()) < kBins / 2) return;
  Matrix7 H = Matrix7::Zero();
  Vector7 g = Vector7::Zero();
  for (const Bin& b : cam.closed) {
    H += b.H;
    g += b.g;
  }
  const Vector7 d = -pseudoInverse(H) * g;
  double scatter = 0.0;
  for (const Bin& b : cam.closed) {
    // (d_b - d)^T H_b (d_b - d) with H_b d_b = -g_b (g_b is in H_b's range).
    const Vector7 db = -pseudoInverse(b.H) * b.g;
    scatter += (db - d).dot(b.H * (db - d));
  }
  const double dof = kDim * (static_cast<double>(cam.closed.size()) - 1.0);
  cam.noise.push_back(scatter / dof);
  if (cam.noise.size() > kNoiseKept) cam.noise.pop_front();
}

double ChangeDetector::noise(std::size_t c) const {
  const Camera& cam = cameras_.at(c);
  if (cam.noise.empty()) return 1.0;
  return std::max(1.0, median(cam.noise));
}

std::optional<ChangeDetector::Change> ChangeDetector::test(std::size_t c, const Matrix7& P) {
  if (c >= cameras_.size()) return std::nullopt;
  Camera& cam = cameras_[c];
  if (cam.tested || static_cast<int>(cam.closed.size()) < kMinBins) return std::nullopt;
  cam.tested = true;
  const double f = noise(c);
  std::optional<Change> best;
  Matrix7 H = Matrix7::Zero();
  Vector7 g = Vector7::Zero();
  // The windows of the last k bins, shortest first.
  for (int k = 1; k <= static_cast<int>(cam.closed.size()); ++k) {
    const Bin& newest = cam.closed[cam.closed.size() - static_cast<std::size_t>(k)];
    H += newest.H;
    g += newest.g;
    if (k < kMinBins) continue;
    const Matrix7 Hinv = pseudoInverse(H);
    const Vector7 d = -Hinv * g;
    const Matrix7 C = f * Hinv + P;
    const Eigen::LDLT<Matrix7> ldlt(C);
    if (ldlt.info() != Eigen::Success) continue;
    const double T = d.dot(ldlt.solve(d));
    if (!(T > kThreshold)) continue;
    double scatter = 0.0;
    for (int j = 1; j <= k; ++j) {
      const Bin& b = cam.closed[cam.closed.size() - static_cast<std::size_t>(j)];
      const Vector7 db = -pseudoInverse(b.H) * b.g;
      scatter += (db - d).dot(b.H * (db - d));
    }
    scatter /= f;
    if (scatter > chiSquareQuantile(kDim * (k - 1.0), kStepZ)) continue;  // not one step
    if (rampStatistic(cam, k, g, Hinv) / f > chiSquareQuantile(kDim, kStepZ)) continue;
    if (!best || T > best->statistic) {
      best = Change();
      best->camera = c;
      best->stamp_ns = cam.closed.back().start + kBinNs;
      best->since_ns = newest.start;
      best->step = d;
      best->covariance = C;
      best->statistic = T;
      best->noise = f;
      best->from_start = newest.start == cam.first;
    }
  }
  return best;
}

double ChangeDetector::rampStatistic(const Camera& cam, int k, const Vector7& g,
                                     const Matrix7& Hinv) {
  // Bins' centres about their mean [s].
  std::vector<double> tau;
  double mean = 0.0;
  for (int j = 1; j <= k; ++j) {
    tau.push_back(toSeconds(cam.closed[cam.closed.size() - static_cast<std::size_t>(j)].start));
    mean += tau.back() / k;
  }
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(2 * kDim, 2 * kDim);
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(2 * kDim);
  for (int j = 1; j <= k; ++j) {
    const Bin& b = cam.closed[cam.closed.size() - static_cast<std::size_t>(j)];
    const double t = tau[static_cast<std::size_t>(j - 1)] - mean;
    A.topLeftCorner<kDim, kDim>() += b.H;
    A.topRightCorner<kDim, kDim>() += t * b.H;
    A.bottomRightCorner<kDim, kDim>() += t * t * b.H;
    rhs.head<kDim>() -= b.g;
    rhs.tail<kDim>() -= t * b.g;
  }
  A.bottomLeftCorner<kDim, kDim>() = A.topRightCorner<kDim, kDim>().transpose();
  return std::max(0.0, rhs.dot(pseudoInverse(A) * rhs) - g.dot(Hinv * g));
}

void ChangeDetector::forget(std::size_t c, bool noise) {
  Camera& cam = cameras_.at(c);
  cam.closed.clear();
  cam.has_open = false;
  cam.tested = true;
  cam.first = -1;
  if (noise) cam.noise.clear();
}

void ChangeDetector::clear() {
  for (std::size_t c = 0; c < cameras_.size(); ++c) forget(c);
}

}  // namespace estimator_internal
}  // namespace mvis
