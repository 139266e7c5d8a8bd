// Following a rig whose calibration changes (EstimatorOptions::detect_changes): each camera's
// change test (change_detector.h) after its frames are added, and a camera found moved
// re-opened: set to the value the test found, its priors the defaults, what the window's prior
// and the trusted calibration knew of its old value let go.
#include <cmath>
#include <iomanip>
#include <set>
#include <sstream>

#include "estimator_impl.h"

namespace mvis {

using estimator_internal::ChangeDetector;

namespace {

// A quantity's step counts as moved when its own statistic passes the chi-square distribution's
// 1 - 1e-3 quantile (3 degrees of freedom for a rotation or translation, 1 for a time offset).
constexpr double kMoved3 = 16.27;
constexpr double kMoved1 = 10.83;

// sqrt(d^T C^-1 d) of a part of the step.
double sigmas(const Eigen::VectorXd& d, const Eigen::MatrixXd& C) {
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(C);
  if (ldlt.info() != Eigen::Success) return std::numeric_limits<double>::infinity();
  return std::sqrt(std::max(0.0, d.dot(ldlt.solve(d))));
}

}  // namespace

bool Estimator::Impl::followChanges() {
  if (!options.detect_changes || !rig.target || options.batch || !initialized) return false;
  const ceres::Problem& problem = *window.problem();
  for (std::size_t c = 0; c < calibration.cameras(); ++c) {
    estimator_internal::CameraBlocks& cb = calibration.camera(c);
    if (!problem.HasParameterBlock(cb.extrinsic) ||
        problem.IsParameterBlockConstant(cb.extrinsic)) {
      continue;  // held: nothing to re-open
    }
    // The current estimate's covariance, scaled as the failure checks scale it.
    ChangeDetector::Vector7 sd = ChangeDetector::Vector7::Zero();
    sd.head<6>() = calibration.latestStd(cb.extrinsic);
    sd[6] = calibration.latestStd(cb.time_offset)[0];
    const ChangeDetector::Matrix7 P = (sd.cwiseAbs2() * trusted.inflation()).asDiagonal();
    const auto change = changes.test(c, P);
    if (change && reopenCamera(*change)) return true;
  }
  return false;
}

bool Estimator::Impl::reopenCamera(const ChangeDetector::Change& change) {
  const std::size_t c = change.camera;
  const std::string& name = rig.cameras[c].name;
  estimator_internal::CameraBlocks& cb = calibration.camera(c);
  ceres::Problem* problem = window.problem();
  const bool offset_free = !problem->IsParameterBlockConstant(cb.time_offset);
  // What moved, each quantity by its own part of the step.
  const Eigen::VectorXd& d = change.step;
  const Eigen::MatrixXd& C = change.covariance;
  struct Part {
    const char* quantity;
    double size, size_sigma, threshold;
  };
  std::vector<Part> parts = {{"rotation", d.head<3>().norm() * 180.0 / M_PI,
                              sigmas(d.head<3>(), C.topLeftCorner(3, 3)), kMoved3},
                             {"translation", d.segment<3>(3).norm() * 1e3,
                              sigmas(d.segment<3>(3), C.block(3, 3, 3, 3)), kMoved3}};
  if (offset_free) {
    parts.push_back({"time_offset", d[6] * 1e3, std::abs(d[6]) / std::sqrt(C(6, 6)), kMoved1});
  }
  std::vector<CalibrationChange> found;
  std::ostringstream text;
  text << std::fixed << std::setprecision(2) << name << " moved (its frames since "
       << toSeconds(change.stamp_ns - change.since_ns) << " s before agree on a new calibration, "
       << std::setprecision(0) << change.statistic << " against " << ChangeDetector::kThreshold
       << " for nothing changed";
  if (change.noise > 1.0) text << std::setprecision(1) << ", noise " << change.noise << "x";
  text << "):";
  const auto add = [&](const Part& p) {
    CalibrationChange out;
    out.stamp_ns = change.stamp_ns;
    out.since_ns = change.since_ns;
    out.sensor = name;
    out.quantity = p.quantity;
    out.size = p.size;
    out.size_sigma = p.size_sigma;
    text << (found.empty() ? " " : ", ") << p.quantity << " " << std::setprecision(2) << p.size
         << (out.quantity == "rotation"      ? " deg"
             : out.quantity == "translation" ? " mm"
                                             : " ms")
         << " (" << std::setprecision(0) << p.size_sigma << " sigma)";
    found.push_back(std::move(out));
  };
  for (const Part& p : parts) {
    if (p.size_sigma * p.size_sigma > p.threshold) add(p);
  }
  if (found.empty()) {  // jointly, not one by one: the largest
    const Part* largest = &parts[0];
    for (const Part& p : parts) {
      if (p.size_sigma * p.size_sigma / p.threshold >
          largest->size_sigma * largest->size_sigma / largest->threshold) {
        largest = &p;
      }
    }
    add(*largest);
  }
  text << "; re-calibrating it from there, the other sensors keep theirs";
  for (CalibrationChange& f : found) f.text = text.str();
  declared_changes.insert(declared_changes.end(), found.begin(), found.end());
  ++counters.calibration_changes;

  // The new values: the test's step from the current estimate.
  double moved[kPoseSize];
  estimator_internal::CameraBlocks* blocks = &cb;
  PoseManifold().Plus(blocks->extrinsic, d.data(), moved);
  std::copy(moved, moved + kPoseSize, blocks->extrinsic);
  if (offset_free) blocks->time_offset[0] += d[6];
  trusted.forget({cb.extrinsic, cb.time_offset});
  changes.forget(c);
  frames.forgetCamera(c);
  if (change.from_start || frames.lastMisfitEntered(c) >= change.since_ns) {
    // The camera's frames at the new mount entered the window as they were (the first batch
    // when it moved before the window started, or frames the gate let through): what they
    // pulled is in the states and the window's prior (a camera knocked before the recording
    // pulled every camera's translation 4 mm off through them, 30 sigma). The window starts over
    // with its new value instead, its frames held out of the first batch.
    calibration.reopenCamera(c, nullptr);
    frames.holdOutOfFirstBatch(c);
    restart(text.str(), change.stamp_ns);
    return true;
  }
  // Its priors the defaults; the window's prior lets go of what it knew of the old value.
  calibration.reopenCamera(c, problem);
  if (joint_prior_id != nullptr) {
    problem->RemoveResidualBlock(joint_prior_id);
    joint_prior_id = nullptr;
    std::vector<double*> joint_blocks;
    if (ceres::CostFunction* joint = trusted.jointPrior(&joint_blocks)) {
      joint_prior_id = problem->AddResidualBlock(joint, nullptr, joint_blocks);
    }
  }
  const Status released = prior.release(
      problem, {cb.extrinsic, cb.time_offset},
      [this](const double* block) { return monitor.baseManifold(*window.problem(), block); });
  if (!released.ok()) {
    // The prior cannot be rebuilt without them: drop it (the window's states and the other
    // sensors' priors hold the rest).
    prior.removeFrom(problem);
    text << " (the window's prior was dropped: " << released.message() << ")";
  }
  status_text = text.str();
  calibration_note += (calibration_note.empty() ? "" : "; ") + text.str();
  return false;
}

}  // namespace mvis
