#include "trusted_calibration.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "mvis/factors/tangent_prior_factor.h"

namespace mvis {
namespace estimator_internal {

namespace {

int tangentSize(const TrustedCalibration::Block& b) {
  return b.manifold != nullptr ? b.manifold->TangentSize() : b.ambient;
}

// A block's parts (TrustedCalibration::inflation): first element and size in its tangent.
std::vector<std::pair<int, int>> partsOf(int tangent) {
  if (tangent == 6) return {{0, 3}, {3, 3}};
  if (tangent == 8) return {{0, 4}, {4, 4}};
  return {{0, tangent}};
}

// The tangent difference Minus(x, x0) of a block's values x from x0 (its values in a snapshot).

Eigen::VectorXd minus(const TrustedCalibration::Block& b, const double* x, const double* x0) {
  Eigen::VectorXd d(tangentSize(b));
  if (b.manifold != nullptr) {
    if (!b.manifold->Minus(x, x0, d.data())) d.setConstant(NAN);
  } else {
    for (int i = 0; i < b.ambient; ++i) d[i] = x[i] - x0[i];
  }
  return d;
}

// C = V diag(s^2) V^T; false if C is not a finite covariance. Directions the covariance calls
// exactly known get a floor (1e-12 of the largest variance) so that whitening stays finite.
bool factor(const Eigen::MatrixXd& C, Eigen::MatrixXd* V, Eigen::VectorXd* s) {
  if (C.size() == 0 || !C.allFinite()) return false;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (C + C.transpose()));
  if (eig.info() != Eigen::Success) return false;
  const double largest = eig.eigenvalues().maxCoeff();
  if (!(largest > 0.0)) return false;
  *V = eig.eigenvectors();
  *s = eig.eigenvalues().cwiseMax(1e-12 * largest).cwiseSqrt();
  return true;
}

}  // namespace

TrustedCalibration::Block TrustedCalibration::make(std::string name, double* x, int ambient,
                                                   const ceres::Manifold* manifold,
                                                   const ceres::Problem* problem, bool intrinsic) {
  Block b;
  b.name = std::move(name);
  b.x = x;
  b.ambient = ambient;
  b.manifold = manifold;
  b.values.assign(x, x + ambient);
  b.estimated =
      problem != nullptr && problem->HasParameterBlock(x) && !problem->IsParameterBlockConstant(x);
  b.intrinsic = intrinsic;
  return b;
}

void TrustedCalibration::setConfigured(std::vector<Block> blocks) {
  configured_ = Snapshot();
  configured_.blocks = std::move(blocks);
  configured_.valid = true;
  history_.clear();
  pending_ = Snapshot();
  last_ = Snapshot();
  moves_.clear();
  span_.clear();
  long_moves_.clear();
  inflation_ = 1.0;
}

void TrustedCalibration::distrust(TimeNs t, TimeNs lookback) {
  pending_ = Snapshot();
  last_ = Snapshot();
  span_.clear();
  // The oldest stays: going back to the configured calibration would align the clocks again,
  // on whatever the fault still does to them.
  while (history_.size() > 1 && history_.back().time > t - lookback) history_.pop_back();
}

void TrustedCalibration::forget(const std::vector<const double*>& blocks) {
  pending_ = Snapshot();
  last_ = Snapshot();
  forget(blocks, &configured_);
  for (Snapshot& s : history_) forget(blocks, &s);
  for (Snapshot& s : span_) forget(blocks, &s);
  // A moved sensor's moves before are not its moves now.
  const auto moved = [&](const Move& m) {
    return std::find(blocks.begin(), blocks.end(), m.x) != blocks.end();
  };
  for (auto* moves : {&moves_, &long_moves_}) {
    for (auto& offer : *moves)
      offer.erase(std::remove_if(offer.begin(), offer.end(), moved), offer.end());
  }
}

void TrustedCalibration::forget(const std::vector<const double*>& blocks, Snapshot* s) {
  const auto forgotten = [&](const Block& b) {
    return std::find(blocks.begin(), blocks.end(), b.x) != blocks.end();
  };
  for (Block& b : s->blocks) {
    if (forgotten(b)) b.values.assign(b.x, b.x + b.ambient);
  }
  if (s->joint.empty()) return;
  // The others' joint covariance: the rows and columns of the forgotten blocks dropped.
  const Eigen::MatrixXd C =
      s->directions * s->std.cwiseAbs2().asDiagonal() * s->directions.transpose();
  std::vector<int> rows;
  std::vector<std::size_t> joint;
  std::vector<Eigen::MatrixXd> marginal_directions, marginal;
  std::vector<Eigen::VectorXd> marginal_std;
  for (std::size_t k = 0, offset = 0; k < s->joint.size(); ++k) {
    const Block& b = s->blocks[s->joint[k]];
    const int n = tangentSize(b);
    if (!forgotten(b)) {
      for (int i = 0; i < n; ++i) rows.push_back(static_cast<int>(offset) + i);
      joint.push_back(s->joint[k]);
      marginal_directions.push_back(s->marginal_directions[k]);
      marginal_std.push_back(s->marginal_std[k]);
      marginal.push_back(s->marginal[k]);
    }
    offset += static_cast<std::size_t>(n);
  }
  if (joint.size() == s->joint.size()) return;
  Eigen::MatrixXd kept(rows.size(), rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    for (std::size_t j = 0; j < rows.size(); ++j) kept(i, j) = C(rows[i], rows[j]);
  }
  s->joint = std::move(joint);
  s->marginal_directions = std::move(marginal_directions);
  s->marginal_std = std::move(marginal_std);
  s->marginal = std::move(marginal);
  if (s->joint.empty() || !factor(kept, &s->directions, &s->std)) {
    s->joint.clear();
    s->directions.resize(0, 0);
    s->std.resize(0);
    s->marginal_directions.clear();
    s->marginal_std.clear();
    s->marginal.clear();
  }
}

TrustedCalibration::Verdict TrustedCalibration::offer(std::vector<Block> blocks,
                                                      const Eigen::MatrixXd& C, TimeNs t) {
  Snapshot p;
  p.blocks = std::move(blocks);
  p.time = t;
  int n = 0;
  for (std::size_t i = 0; i < p.blocks.size(); ++i) {
    if (!p.blocks[i].estimated) continue;
    p.joint.push_back(i);
    n += tangentSize(p.blocks[i]);
  }
  p.valid = n > 0 && C.rows() == n && C.cols() == n && factor(C, &p.directions, &p.std);
  for (int offset = 0, k = 0; p.valid && k < static_cast<int>(p.joint.size()); ++k) {
    const int t_k = tangentSize(p.blocks[p.joint[k]]);
    Eigen::MatrixXd V;
    Eigen::VectorXd s;
    p.valid = factor(C.block(offset, offset, t_k, t_k), &V, &s);
    p.marginal_directions.push_back(V);
    p.marginal_std.push_back(s);
    p.marginal.push_back(C.block(offset, offset, t_k, t_k));
    offset += t_k;
  }
  // The pending calibration is trusted if this one is where it said it would be: an estimate
  // still converging (an early covariance is taken at a linearization point far from the
  // solution, and is overconfident) or being pulled by a fault is not.
  if (pending_.valid && step(pending_, &p.blocks, nullptr, true) <= kSettledSigma) {
    history_.push_back(std::move(pending_));
    if (history_.size() > 20) history_.pop_front();
  }
  pending_ = Snapshot();
  if (!p.valid) {  // nothing to trust
    last_ = Snapshot();
    return {};
  }
  // The largest whitened innovation of the extrinsics and time offsets (0) and of the
  // intrinsics (1), and what to say about it.
  Verdict said;
  double worst[2] = {0.0, 0.0};
  for (const Innovation& i :
       fromCovariance() ? innovations(trusted(), p) : std::vector<Innovation>{}) {
    const double m = i.largest / std::sqrt(inflation_);
    if (m <= worst[i.intrinsic]) continue;
    worst[i.intrinsic] = m;
    std::ostringstream out;
    out << i.name << " moved " << m << " sigma of what the data since the trusted calibration ("
        << toSeconds(t - trusted().time) << " s before) can explain";
    if (inflation_ > 1.0) {
      out << " (sigma taken " << std::sqrt(inflation_)
          << "x larger: on this data the calibration moves that much more than its covariance "
             "allows)";
    }
    if (i.intrinsic) {
      out << ": its standard deviations are not to be trusted on this data (intrinsics move "
             "with the images' coverage when the model does not fit the lens or the sensor; "
             "not a failure, the window goes on)";
    }
    (i.intrinsic ? said.inconsistent : said.failure) = out.str();
  }
  if (worst[0] <= kInnovationSigma) said.failure.clear();
  if (worst[1] <= kInnovationSigma) said.inconsistent.clear();
  if (said.failure.empty() && last_.valid) {
    std::vector<Move> offer;
    for (const Innovation& i : innovations(last_, p)) {
      offer.push_back({i.x, i.ratio, i.part_variance});
    }
    moves_.push_back(std::move(offer));
    if (moves_.size() > kMovesKept) moves_.pop_front();
    // The lower median of every block's ratios over the offers kept.
    std::vector<double> pooled;
    for (const auto& kept : moves_) {
      for (const Move& m : kept) pooled.push_back(m.ratio);
    }
    if (!pooled.empty()) {
      std::nth_element(pooled.begin(), pooled.begin() + (pooled.size() - 1) / 2, pooled.end());
      inflation_ = std::clamp(pooled[(pooled.size() - 1) / 2], 1.0, kMaxInflation);
    }
  }
  if (said.failure.empty()) {
    if (!span_.empty()) {
      std::vector<Move> offer;
      for (const Innovation& i : innovations(span_.front(), p)) {
        offer.push_back({i.x, i.ratio, i.part_variance});
      }
      long_moves_.push_back(std::move(offer));
      if (long_moves_.size() > kMovesKept) long_moves_.pop_front();
    }
    span_.push_back(p);
    if (span_.size() > kMovesKept) span_.pop_front();
  }
  // A failed offer is neither trusted nor counted; it is the next one's reference all the same
  // (a restart, if there is one, forgets it).
  last_ = p;
  if (said.failure.empty()) pending_ = std::move(p);
  return said;
}

double TrustedCalibration::inflation(const double* x, int part) const {
  const auto mean = [x, part](const std::deque<std::vector<Move>>& moves) {
    double sum = 0.0;
    int n = 0;
    for (const auto& offer : moves) {
      for (const Move& m : offer) {
        if (m.x != x || part >= static_cast<int>(m.variance.size())) continue;
        if (std::isfinite(m.variance[part])) sum += m.variance[part], ++n;
      }
    }
    return n == 0 ? 0.0 : sum / n;
  };
  return std::clamp(std::max(mean(moves_), mean(long_moves_)), inflation_, kMaxInflation);
}

std::vector<TrustedCalibration::Innovation> TrustedCalibration::innovations(const Snapshot& from,
                                                                            const Snapshot& to) {
  std::vector<Innovation> out;
  for (std::size_t k = 0; k < from.joint.size(); ++k) {
    const Block& b = from.blocks[from.joint[k]];
    std::size_t j = 0;
    while (j < to.joint.size() && to.blocks[to.joint[j]].x != b.x) ++j;
    if (j == to.joint.size()) continue;
    const Eigen::MatrixXd& C0 = from.marginal[k];
    const Eigen::MatrixXd& C1 = to.marginal[j];
    if (C0.rows() != C1.rows()) continue;
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> gain(0.5 * ((C0 - C1) + (C0 - C1).transpose()));
    if (gain.info() != Eigen::Success) continue;
    const Eigen::MatrixXd S = gain.eigenvectors() * gain.eigenvalues().cwiseMax(0.0).asDiagonal() *
                                  gain.eigenvectors().transpose() +
                              kInnovationFloor * C0;
    Eigen::MatrixXd V;
    Eigen::VectorXd sd;
    if (!factor(S, &V, &sd)) continue;
    const Eigen::VectorXd d = minus(b, to.blocks[to.joint[j]].values.data(), b.values.data());
    const Eigen::VectorXd w = (V.transpose() * d).cwiseQuotient(sd).cwiseAbs();
    Innovation i;
    i.intrinsic = b.intrinsic;
    i.name = b.name;
    i.x = b.x;
    if (w.allFinite()) {
      // The chi-square distribution's median for n degrees of freedom (Wilson-Hilferty).
      const double n = static_cast<double>(w.size());
      const double median = n * std::pow(1.0 - 2.0 / (9.0 * n), 3);
      i.largest = w.maxCoeff();
      i.ratio = w.squaredNorm() / median;
      for (const auto& [first, size] : partsOf(static_cast<int>(d.size()))) {
        const Eigen::MatrixXd Sp = S.block(first, first, size, size);
        const Eigen::VectorXd dp = d.segment(first, size);
        i.part_variance.push_back(dp.dot(Sp.ldlt().solve(dp)) / size);
      }
    } else {
      i.largest = i.ratio = std::numeric_limits<double>::infinity();
      i.part_variance.assign(partsOf(static_cast<int>(d.size())).size(), i.ratio);
    }
    out.push_back(std::move(i));
  }
  return out;
}

double TrustedCalibration::step(const Snapshot& from, const std::vector<Block>* to,
                                std::string* which, bool intrinsics) const {
  double largest = 0.0;
  for (std::size_t k = 0; k < from.joint.size(); ++k) {
    const Block& b = from.blocks[from.joint[k]];
    if (b.intrinsic && !intrinsics) continue;
    const double* x = b.x;  // the current values
    if (to != nullptr) {
      const auto it =
          std::find_if(to->begin(), to->end(), [&](const Block& other) { return other.x == b.x; });
      if (it == to->end()) continue;
      x = it->values.data();
    }
    const Eigen::VectorXd w =
        (from.marginal_directions[k].transpose() * minus(b, x, b.values.data()))
            .cwiseQuotient(from.marginal_std[k])
            .cwiseAbs();
    const double m = w.allFinite() ? w.maxCoeff() / std::sqrt(inflation_)
                                   : std::numeric_limits<double>::infinity();
    if (m > largest) {
      largest = m;
      if (which != nullptr) *which = b.name;
    }
  }
  return largest;
}

double TrustedCalibration::largestStep(std::string* which) const {
  return step(trusted(), nullptr, which, false);
}

void TrustedCalibration::restore() const {
  for (const Block& b : trusted().blocks) std::copy(b.values.begin(), b.values.end(), b.x);
}

bool TrustedCalibration::covers(const double* x) const {
  const Snapshot& trusted_ = trusted();
  for (std::size_t i : trusted_.joint) {
    if (trusted_.blocks[i].x == x) return true;
  }
  return false;
}

ceres::CostFunction* TrustedCalibration::jointPrior(std::vector<double*>* blocks) const {
  const Snapshot& trusted_ = trusted();
  blocks->clear();
  if (trusted_.joint.empty()) return nullptr;
  std::vector<TangentPriorFactor::Block> prior;
  for (std::size_t i : trusted_.joint) {
    const Block& b = trusted_.blocks[i];
    prior.push_back({b.manifold, b.values});
    blocks->push_back(b.x);
  }
  return new TangentPriorFactor(std::move(prior), trusted().directions, trusted().std);
}

}  // namespace estimator_internal
}  // namespace mvis
