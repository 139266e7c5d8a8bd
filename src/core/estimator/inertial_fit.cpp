#include "inertial_fit.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

namespace mvis {
namespace estimator_internal {

using L = ImuIntrinsicsLayout;

InertialFit::InertialFit(const Rig& rig, const EstimatorOptions& options,
                         const ImuIntrinsicsBlocks& intrinsics)
    : rig_(rig), options_(options), intrinsics_(intrinsics), sensors_(rig.inertial.size()) {
  // The held entries tested: Tg's (a gyroscope's other held entries, Da and the rotation, do not
  // enter its factor or are its extrinsic's).
  for (std::size_t i = 0; i < sensors_.size(); ++i) {
    const ImuIntrinsicsBlock* b = intrinsics.block(i);
    if (b == nullptr) continue;
    for (int k = L::kTg; k < L::kTg + 9; ++k) {
      if (std::find(b->free.begin(), b->free.end(), k) == b->free.end()) {
        sensors_[i].held.push_back(k);
      }
    }
  }
}

void InertialFit::leaving(const State& oldest, bool settled) {
  if (!(options_.held_intrinsics_p > 0.0)) return;
  if (!settled) {
    clear();
    return;
  }
  const TimeNs horizon = fromSeconds(options_.held_intrinsics_horizon_s);
  for (const auto& rec : oldest.residuals) {
    if (rec.inertial < 0 || static_cast<std::size_t>(rec.inertial) >= sensors_.size()) continue;
    Sensor& s = sensors_[static_cast<std::size_t>(rec.inertial)];
    const ImuIntrinsicsBlock* b = intrinsics_.block(static_cast<std::size_t>(rec.inertial));
    if (s.held.empty() || b == nullptr || rec.blocks.empty() || rec.blocks.back() != b->x) {
      continue;
    }
    // Ambient Jacobian of the intrinsics block (the last one) only.
    const int m = rec.cost->num_residuals();
    Eigen::VectorXd r(m);
    Eigen::Matrix<double, Eigen::Dynamic, kImuIntrinsicsSize, Eigen::RowMajor> J(
        m, kImuIntrinsicsSize);
    std::vector<double*> jacobians(rec.blocks.size(), nullptr);
    jacobians.back() = J.data();
    if (!rec.cost->Evaluate(rec.blocks.data(), r.data(), jacobians.data()) || !r.allFinite() ||
        !J.allFinite()) {
      continue;
    }
    const int n = static_cast<int>(s.held.size());
    Eigen::MatrixXd Jh(m, n);
    for (int k = 0; k < n; ++k) Jh.col(k) = J.col(s.held[static_cast<std::size_t>(k)]);
    s.pieces.push_back({oldest.t, Jh.transpose() * r});
  }
  for (Sensor& s : sensors_) {
    while (!s.pieces.empty() && s.pieces.front().t < oldest.t - horizon) s.pieces.pop_front();
  }
}

double InertialFit::statistic(std::size_t sensor, int* dof) const {
  *dof = 0;
  const Sensor& s = sensors_[sensor];
  // At least 10 s of data (or the whole horizon, if shorter): its power grows with the length.
  const double least_s = std::min(10.0, 0.9 * options_.held_intrinsics_horizon_s);
  if (s.pieces.size() < 2 || s.pieces.back().t - s.pieces.front().t < fromSeconds(least_s)) {
    return 0.0;
  }
  const int n = static_cast<int>(s.held.size());
  Eigen::VectorXd g = Eigen::VectorXd::Zero(n);
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(n, n);
  for (const auto& p : s.pieces) {
    g += p.g;
    S += p.g * p.g.transpose();
  }
  // Directions the motion did not excite (yaw only: Tg's column along the vertical) carry no
  // information and no degree of freedom.
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(S);
  const Eigen::VectorXd& lambda = eig.eigenvalues();
  const double floor = 1e-6 * std::max(lambda.maxCoeff(), 0.0);
  double out = 0.0;
  for (int k = 0; k < n; ++k) {
    if (!(lambda[k] > floor) || !(lambda[k] > 0.0)) continue;
    const double projected = eig.eigenvectors().col(k).dot(g);
    out += projected * projected / lambda[k];
    ++*dof;
  }
  return out;
}

double InertialFit::chiSquareQuantile(int dof, double p) {
  // z with P(N(0,1) > z) = p, by bisection on erfc.
  double lo = 0.0, hi = 40.0;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    (0.5 * std::erfc(mid / std::sqrt(2.0)) > p ? lo : hi) = mid;
  }
  const double z = 0.5 * (lo + hi), k = dof;
  const double c = 1.0 - 2.0 / (9.0 * k) + z * std::sqrt(2.0 / (9.0 * k));
  return k * c * c * c;
}

std::string InertialFit::check(double inflation, long* misfits) {
  if (!(options_.held_intrinsics_p > 0.0)) return "";
  std::string out;
  for (std::size_t i = 0; i < sensors_.size(); ++i) {
    Sensor& s = sensors_[i];
    int dof = 0;
    const double raw = statistic(i, &dof);
    if (dof == 0) continue;
    const double stat = raw / std::max(inflation, 1.0);
    const double bound = chiSquareQuantile(dof, options_.held_intrinsics_p);
    if (stat <= bound) {
      if (stat < 0.5 * bound) s.said = false;  // said again only once clearly back under
      continue;
    }
    if (s.said) continue;
    s.said = true;
    ++*misfits;
    std::ostringstream m;
    m << rig_.inertial[i].name << ": its readings pull on its gravity sensitivity Tg, held at "
      << "its configured value, more than their noise can (score test " << std::fixed
      << std::setprecision(0) << stat;
    if (inflation > 1.0) {
      // The variance ratio: sigma_inflation squared.
      m << " after dividing by the calibration's variance inflation " << std::setprecision(1)
        << inflation << std::setprecision(0);
    }
    m << " over the last " << options_.held_intrinsics_horizon_s << " s against a bound of "
      << bound << " for " << dof << " degrees of freedom): Tg may be off (estimate it: "
      << "estimate_gravity_sensitivity) or the readings carry another effect the model lacks; "
         "until then every sensor's calibration may be off by more than its sigma says";
    if (!out.empty()) out += "; ";
    out += m.str();
  }
  return out;
}

void InertialFit::clear() {
  for (Sensor& s : sensors_) {
    s.pieces.clear();
    s.said = false;
  }
}

}  // namespace estimator_internal
}  // namespace mvis
