#include "change_detector.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

#include "../factors/scaled_factorization.h"

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
constexpr double kStepZ = 3.09;  // the bins' scatter about the step at 1 - 1e-3
constexpr double kRampZ = 2.33;  // the ramp's fit against the step's at 1 - 1e-2
// Both allow this share of T more: the bins' steps are linearized about the old calibration, and
// after a large step they scatter by its second order (cam1 turned by 2 deg: S 60-85 and R 8-31 at
// T = 1.5-1.9e5, 4e-4 of it, which held the declaration back by 2 s; a drifting clock's S and R
// are 0.3 of its T).
constexpr double kLinearization = 1e-3;

// The pseudo-inverse of a Jacobi-scaled H: directions with a scaled eigenvalue under kZero carry
// nothing (a time offset on a rig that does not move).
constexpr double kZero = 1e-9;
Eigen::MatrixXd pseudoInverse(const Eigen::MatrixXd& H) {
  return scaled_factorization::pseudoInverse(H, kZero);
}

double median(std::deque<double> v) {
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

}  // namespace

Matrix7 pseudoInverse(const Matrix7& H) { return pseudoInverse(Eigen::MatrixXd(H)); }

void eliminateNuisance(const ChangeDetector::MatrixA& H, const ChangeDetector::VectorA& g,
                       Matrix7* H7, Vector7* g7) {
  constexpr int n = ChangeDetector::kDim, m = ChangeDetector::kNuisance;
  const Eigen::MatrixXd Hnn_inv = pseudoInverse(Eigen::MatrixXd(H.bottomRightCorner<m, m>()));
  const Eigen::Matrix<double, n, m> Hxn = H.topRightCorner<n, m>();
  *H7 = H.topLeftCorner<n, n>() - Hxn * Hnn_inv * Hxn.transpose();
  *H7 = 0.5 * (*H7 + H7->transpose());
  *g7 = g.head<n>() - Hxn * Hnn_inv * g.tail<m>();
}

ChangeDetector::ChangeDetector(std::size_t slots) : slots_(slots) {}

void ChangeDetector::add(std::size_t c, TimeNs t, const Eigen::VectorXd& r,
                         const Eigen::MatrixXd& J) {
  if (c >= slots_.size() || (J.cols() != kDim && J.cols() != kAll) || J.rows() != r.size() ||
      r.size() == 0) {
    return;
  }
  if (!r.allFinite() || !J.allFinite()) return;
  Slot& cam = slots_[c];
  if (cam.has_open && t >= cam.open.start + kBinNs) close(cam);
  if (cam.has_open && t < cam.open.start) return;  // out of order (a restart's leftovers)
  if (!cam.has_open) {
    cam.open = Bin();
    cam.open.start = t;
    cam.has_open = true;
  }
  const Eigen::Index n = J.cols();
  cam.open.H.topLeftCorner(n, n).noalias() += J.transpose() * J;
  cam.open.g.head(n).noalias() += J.transpose() * r;
  ++cam.open.frames;
}

void ChangeDetector::close(Slot& cam) {
  cam.has_open = false;
  if (cam.open.frames < kMinFramesPerBin) return;
  if (cam.first < 0) cam.first = cam.open.start;
  cam.closed.push_back(cam.open);
  if (static_cast<int>(cam.closed.size()) > kBins) cam.closed.pop_front();
  cam.tested = false;
  // The noise level: the closed bins' steps about their common one, over their model.
  if (static_cast<int>(cam.closed.size()) < kBins / 2) return;
  cam.noise.push_back(scatter(cam, static_cast<int>(cam.closed.size())) /
                      (kDim * (static_cast<double>(cam.closed.size()) - 1.0)));
  if (cam.noise.size() > kNoiseKept) cam.noise.pop_front();
}

double ChangeDetector::oneStep(const Slot& cam, int k) {
  MatrixA H = MatrixA::Zero();
  VectorA g = VectorA::Zero();
  for (int j = 1; j <= k; ++j) {
    const Bin& b = cam.closed[cam.closed.size() - static_cast<std::size_t>(j)];
    H += b.H;
    g += b.g;
  }
  return g.dot(pseudoInverse(Eigen::MatrixXd(H)) * g);
}

double ChangeDetector::scatter(const Slot& cam, int k) {
  // Each bin its own step, the nuisance parameters common: each step eliminated in its bin, then
  // the nuisance parameters from what is left of every bin.
  constexpr int n = kDim, m = kNuisance;
  double drop = 0.0;
  Eigen::Matrix<double, m, m> N = Eigen::Matrix<double, m, m>::Zero();
  Eigen::Matrix<double, m, 1> gn = Eigen::Matrix<double, m, 1>::Zero();
  for (int j = 1; j <= k; ++j) {
    const Bin& b = cam.closed[cam.closed.size() - static_cast<std::size_t>(j)];
    const Matrix7 Hxx_inv = pseudoInverse(Matrix7(b.H.topLeftCorner<n, n>()));
    const Eigen::Matrix<double, m, n> Hnx = b.H.bottomLeftCorner<m, n>();
    drop += b.g.head<n>().dot(Hxx_inv * b.g.head<n>());
    N += b.H.bottomRightCorner<m, m>() - Hnx * Hxx_inv * Hnx.transpose();
    gn += b.g.tail<m>() - Hnx * Hxx_inv * b.g.head<n>();
  }
  drop += gn.dot(pseudoInverse(Eigen::MatrixXd(N)) * gn);
  return std::max(0.0, drop - oneStep(cam, k));
}

double ChangeDetector::noise(std::size_t c) const {
  const Slot& cam = slots_.at(c);
  if (cam.noise.empty()) return 1.0;
  return std::max(1.0, median(cam.noise));
}

std::optional<ChangeDetector::Change> ChangeDetector::test(std::size_t c, const Matrix7& P) {
  if (c >= slots_.size()) return std::nullopt;
  Slot& cam = slots_[c];
  if (cam.tested || static_cast<int>(cam.closed.size()) < kMinBins) return std::nullopt;
  cam.tested = true;
  const double f = noise(c);
  std::optional<Change> best;
  MatrixA H_all = MatrixA::Zero();
  VectorA g_all = VectorA::Zero();
  // The windows of the last k bins, shortest first.
  for (int k = 1; k <= static_cast<int>(cam.closed.size()); ++k) {
    const Bin& newest = cam.closed[cam.closed.size() - static_cast<std::size_t>(k)];
    H_all += newest.H;
    g_all += newest.g;
    if (k < kMinBins) continue;
    Matrix7 H;
    Vector7 g;
    eliminateNuisance(H_all, g_all, &H, &g);
    const Matrix7 Hinv = pseudoInverse(H);
    const Vector7 d = -Hinv * g;
    const Matrix7 C = f * Hinv + P;
    const Eigen::LDLT<Matrix7> ldlt(C);
    if (ldlt.info() != Eigen::Success) continue;
    const double T = d.dot(ldlt.solve(d));
    if (!(T > kThreshold)) continue;
    const double allowance = kLinearization * T;
    if (scatter(cam, k) / f > chiSquareQuantile(kDim * (k - 1.0), kStepZ) + allowance) continue;
    if (rampStatistic(cam, k) / f > chiSquareQuantile(kDim, kRampZ) + allowance) continue;
    if (!best || T > best->statistic) {
      best = Change();
      best->slot = c;
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

bool ChangeDetector::step(std::size_t c, TimeNs since, Vector7* d, Matrix7* covariance) const {
  if (c >= slots_.size()) return false;
  const Slot& cam = slots_[c];
  MatrixA H_all = MatrixA::Zero();
  VectorA g_all = VectorA::Zero();
  int bins = 0;
  for (auto b = cam.closed.rbegin(); b != cam.closed.rend() && (bins == 0 || b->start >= since);
       ++b, ++bins) {
    H_all += b->H;
    g_all += b->g;
  }
  if (bins == 0) return false;
  Matrix7 H;
  Vector7 g;
  eliminateNuisance(H_all, g_all, &H, &g);
  const Matrix7 Hinv = pseudoInverse(H);
  *d = -Hinv * g;
  *covariance = noise(c) * Hinv;
  return true;
}

bool ChangeDetector::suggests(std::size_t c, const Matrix7& P) const {
  if (c >= slots_.size()) return false;
  const Slot& cam = slots_[c];
  const double f = noise(c);
  MatrixA H_all = MatrixA::Zero();
  VectorA g_all = VectorA::Zero();
  for (int k = 1; k < kMinBins && k <= static_cast<int>(cam.closed.size()); ++k) {
    const Bin& newest = cam.closed[cam.closed.size() - static_cast<std::size_t>(k)];
    H_all += newest.H;
    g_all += newest.g;
    Matrix7 H;
    Vector7 g;
    eliminateNuisance(H_all, g_all, &H, &g);
    const Matrix7 Hinv = pseudoInverse(H);
    const Vector7 d = -Hinv * g;
    const Eigen::LDLT<Matrix7> ldlt(f * Hinv + P);
    if (ldlt.info() == Eigen::Success && d.dot(ldlt.solve(d)) > kThreshold) return true;
  }
  return false;
}

double ChangeDetector::rampStatistic(const Slot& cam, int k) {
  // The step a + b (t - mean t) with the nuisance parameters common: [a, b, nuisance].
  constexpr int n = kDim, m = kNuisance;
  std::vector<double> tau;
  double mean = 0.0;
  for (int j = 1; j <= k; ++j) {
    tau.push_back(toSeconds(cam.closed[cam.closed.size() - static_cast<std::size_t>(j)].start));
    mean += tau.back() / k;
  }
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(2 * n + m, 2 * n + m);
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(2 * n + m);
  for (int j = 1; j <= k; ++j) {
    const Bin& b = cam.closed[cam.closed.size() - static_cast<std::size_t>(j)];
    const double t = tau[static_cast<std::size_t>(j - 1)] - mean;
    Eigen::Matrix<double, n + m, 2 * n + m> E = Eigen::Matrix<double, n + m, 2 * n + m>::Zero();
    E.topLeftCorner<n, n>().setIdentity();  // [a, b, nuisance] -> [a + t b, nuisance]
    E.block<n, n>(0, n) = t * Matrix7::Identity();
    E.bottomRightCorner<m, m>().setIdentity();
    A += E.transpose() * b.H * E;
    rhs += E.transpose() * b.g;
  }
  return std::max(0.0, rhs.dot(pseudoInverse(A) * rhs) - oneStep(cam, k));
}

void ChangeDetector::forget(std::size_t c, bool noise) {
  Slot& cam = slots_.at(c);
  cam.closed.clear();
  cam.has_open = false;
  cam.tested = true;
  cam.first = -1;
  if (noise) cam.noise.clear();
}

void ChangeDetector::clear() {
  for (std::size_t c = 0; c < slots_.size(); ++c) forget(c);
}

}  // namespace estimator_internal
}  // namespace mvis
