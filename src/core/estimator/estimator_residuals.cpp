// The estimator's residuals per sensor (estimator_impl.h): the batch's summary and the online
// statistics for the report.
#include <algorithm>
#include <cmath>
#include <map>

#include "estimator_impl.h"
#include "mvis/factors/tag_reprojection_factor.h"

namespace mvis {
namespace {
constexpr std::size_t kWorstStates = 5;
}  // namespace

void Estimator::Impl::visitResiduals(
    const State& state, const std::function<void(std::size_t, const std::vector<double>&,
                                                 const TagReprojectionFactor*)>& visit) {
  const std::size_t cameras = rig.cameras.size();
  ceres::Problem* problem = window.problem();
  std::vector<double> residuals;
  for (const auto& r : state.residuals) {
    std::size_t k = cameras + rig.inertial.size();  // none: a prior
    if (r.inertial >= 0) {
      k = cameras + static_cast<std::size_t>(r.inertial);
    } else {
      for (std::size_t c = 0; c < cameras; ++c) {
        if (std::find(r.blocks.begin(), r.blocks.end(), calibration.camera(c).extrinsic) !=
            r.blocks.end()) {
          k = c;
        }
      }
    }
    if (k == cameras + rig.inertial.size()) continue;
    const auto* tag = k < cameras ? dynamic_cast<const TagReprojectionFactor*>(r.cost) : nullptr;
    if (tag != nullptr) {
      // Per corner, also when the factor's rows are compressed.
      residuals.assign(2 * tag->corners().size(), 0.0);
      if (!tag->cornerResiduals(r.blocks.data(), residuals.data())) continue;
    } else {
      residuals.assign(static_cast<std::size_t>(r.cost->num_residuals()), 0.0);
      double cost = 0.0;
      if (!problem->EvaluateResidualBlock(r.id, false, &cost, residuals.data(), nullptr)) continue;
    }
    visit(k, residuals, tag);
  }
}

std::vector<Eigen::Vector2d> Estimator::Impl::cornerErrors(
    const std::vector<double>& whitened) const {
  // The per-corner loss (when configured, on every frame's factor in a batch and online alike)
  // maps a whitened norm n > h to g = sqrt(2 h n - h^2): undone.
  const bool corner_loss = options.robust_loss == RobustLoss::kCorner && options.huber_sigma > 0.0;
  std::vector<Eigen::Vector2d> out;
  for (std::size_t i = 0; i + 1 < whitened.size(); i += 2) {
    Eigen::Vector2d e(whitened[i], whitened[i + 1]);
    const double h = options.huber_sigma, g = e.norm();
    if (corner_loss && g > h) e *= (g * g + h * h) / (2.0 * h) / g;
    out.push_back(options.pixel_sigma_px * e);
  }
  return out;
}

ResidualStatistics Estimator::Impl::emptyResidualStatistics() const {
  ResidualStatistics out;
  for (const auto& c : rig.cameras) {
    out.sensors.emplace_back();
    out.sensors.back().sensor = c.name;
    out.sensors.back().kind = "camera";
  }
  for (std::size_t i = 0; i < rig.inertial.size(); ++i) {
    out.sensors.emplace_back();
    out.sensors.back().sensor = rig.inertial[i].name;
    out.sensors.back().kind = i == 0                                             ? "base IMU"
                              : rig.inertial[i].type == InertialType::kGyroscope ? "gyroscope"
                                                                                 : "auxiliary IMU";
  }
  return out;
}

void Estimator::Impl::addResiduals(const State& state, ResidualStatistics* stats) {
  if (stats->sensors.empty()) *stats = emptyResidualStatistics();
  visitResiduals(state, [&](std::size_t k, const std::vector<double>& whitened,
                            const TagReprojectionFactor* tag) {
    SensorResidualStatistics& s = stats->sensors[k];
    s.factors += 1;
    s.residuals += static_cast<long>(whitened.size());
    if (tag == nullptr) {
      for (double e : whitened) s.chi_square += e * e;
      return;
    }
    for (const Eigen::Vector2d& e : cornerErrors(whitened)) {
      s.chi_square += e.squaredNorm() / (options.pixel_sigma_px * options.pixel_sigma_px);
      s.addCorner(e.norm());
    }
  });
}

ResidualStatistics Estimator::residualStatistics() const {
  ResidualStatistics out = impl_->left_residuals;
  if (out.sensors.empty()) out = impl_->emptyResidualStatistics();
  for (const auto& state : impl_->window.states()) impl_->addResiduals(*state, &out);
  return out;
}

void Estimator::Impl::residualSummary(BatchSummary* summary) {
  const std::size_t cameras = rig.cameras.size(), inertial = rig.inertial.size();
  std::vector<SensorResiduals> out(cameras + inertial);
  // Per sensor and window state: chi-square and residuals.
  std::vector<std::map<TimeNs, std::pair<double, long>>> by_state(out.size());
  const ResidualStatistics named = emptyResidualStatistics();
  for (std::size_t k = 0; k < out.size(); ++k) {
    out[k].sensor = named.sensors[k].sensor;
    out[k].kind = named.sensors[k].kind;
  }
  for (const auto& state : window.states()) {
    visitResiduals(*state, [&](std::size_t k, const std::vector<double>& residuals,
                               const TagReprojectionFactor* tag) {
      double chi2 = 0.0;
      for (double e : residuals) chi2 += e * e;
      out[k].factors += 1;
      out[k].residuals += static_cast<long>(residuals.size());
      out[k].chi_square += chi2;
      auto& at = by_state[k][state->t];
      at.first += chi2;
      at.second += static_cast<long>(residuals.size());
      if (k >= cameras) {
        summary->inertial.push_back(
            {state->t, static_cast<int>(k - cameras), static_cast<int>(residuals.size()), chi2});
        return;
      }
      if (tag == nullptr) return;
      const bool landmark = !rig.target;
      const std::vector<Eigen::Vector2d> errors = cornerErrors(residuals);
      for (std::size_t i = 0; i < tag->corners().size(); ++i) {
        const CornerObservation& o = tag->corners()[i];
        CornerResidual c;
        c.stamp_ns = state->t;
        c.camera = static_cast<int>(k);
        if (!landmark) c.p_G = o.p_G;
        c.corner = o.landmark;
        c.uv = o.uv;
        c.residual = errors[i];
        summary->corners.push_back(c);
      }
    });
  }
  for (std::size_t k = 0; k < out.size(); ++k) {
    SensorResiduals& s = out[k];
    if (s.residuals == 0) continue;
    s.rms = std::sqrt(s.chi_square / static_cast<double>(s.residuals));
    if (k < cameras) s.rms *= options.pixel_sigma_px;
    for (const auto& [t, v] : by_state[k]) {
      s.worst.emplace_back(t, v.first / static_cast<double>(v.second));
    }
    std::stable_sort(s.worst.begin(), s.worst.end(),
                     [](const auto& a, const auto& b) { return a.second > b.second; });
    if (s.worst.size() > kWorstStates) s.worst.resize(kWorstStates);
  }
  out.erase(std::remove_if(out.begin(), out.end(),
                           [](const SensorResiduals& s) { return s.residuals == 0; }),
            out.end());
  summary->residuals = std::move(out);
}

}  // namespace mvis
