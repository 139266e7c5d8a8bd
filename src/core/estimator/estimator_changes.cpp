// Following a rig whose calibration changes (EstimatorOptions::detect_changes): each camera's
// and auxiliary sensor's change test (change_detector.h) before the solve, and a sensor found
// moved re-opened: set to the value the test found, its priors the defaults, what the window's
// prior and the trusted calibration knew of its old value let go.
#include <cmath>
#include <iomanip>
#include <sstream>

#include "estimator_impl.h"

namespace mvis {

using estimator_internal::ChangeDetector;

namespace {

// A quantity's step counts as moved when its own statistic passes the chi-square distribution's
// 1 - 1e-3 quantile (3 degrees of freedom for a rotation or translation, 1 for a time offset).
constexpr double kMoved3 = 16.27;
constexpr double kMoved1 = 10.83;
// An auxiliary sensor is declared moved on its rotation: the chi-square of the step's rotation
// part must pass its 1 - 1e-11 quantile (3 degrees of freedom) by itself. Its translation shows
// only through lever-arm accelerations, which take the base IMU's angular acceleration and jerk
// from differences of noisy readings: garbled and swapped readings alone once made a 46 mm
// "translation" pass the joint test.
constexpr double kAuxRotation = 54.2;

// sqrt(d^T C^-1 d) of a part of the step.
double sigmas(const Eigen::VectorXd& d, const Eigen::MatrixXd& C) {
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(C);
  if (ldlt.info() != Eigen::Success) return std::numeric_limits<double>::infinity();
  return std::sqrt(std::max(0.0, d.dot(ldlt.solve(d))));
}

}  // namespace

Estimator::Impl::ChangeSlot Estimator::Impl::changeSlot(std::size_t slot) {
  ChangeSlot s;
  if (slot < calibration.cameras()) {
    estimator_internal::CameraBlocks& cb = calibration.camera(slot);
    s.name = rig.cameras[slot].name;
    s.extrinsic = cb.extrinsic;
    s.time_offset = cb.time_offset;
    s.camera = true;
    return s;
  }
  estimator_internal::AuxCalibration& a = calibration.aux(slot - calibration.cameras());
  s.name = rig.inertial[a.sensor].name;
  s.extrinsic = a.extrinsicBlock();
  s.time_offset = a.time_offset;
  s.gyro = a.gyro;
  // An auxiliary sensor is tested against a saved calibration only (its configuration's *_std
  // keys), while it has not moved: the test carries its readings to the base IMU through the
  // extrinsic, the window integrates them with velocity and bias states, and where the model
  // does not fit (IMU intrinsics taken as identity, or linearized once) the two settle up to
  // 0.5 deg apart, which the test takes for a move (9 sigma, on runs from a rough guess).
  s.tested = rig.inertial[a.sensor].std.has_value() && !a.moved;
  return s;
}

ChangeDetector::Matrix7 Estimator::Impl::referenceCovariance(const ChangeSlot& s) const {
  // The current estimate's covariance, scaled as it is reported (reportedCalibration: each
  // part by how much more it moves than its covariance allows; a gyroscope's translation, which
  // it does not have, at 1: its step there is zero).
  ChangeDetector::Vector7 variance = ChangeDetector::Vector7::Ones();
  const Eigen::VectorXd extrinsic = calibration.latestStd(s.extrinsic);
  for (int k = 0; k < extrinsic.size(); ++k) {
    variance[k] = extrinsic[k] * extrinsic[k] * trusted.inflation(s.extrinsic, k / 3);
  }
  const double t = calibration.latestStd(s.time_offset)[0];
  variance[6] = t * t * trusted.inflation(s.time_offset, 0);
  return variance.asDiagonal();
}

bool Estimator::Impl::deferFailure(const std::string& why, TimeNs t) {
  if (!options.detect_changes || !rig.target || options.batch) return false;
  // An auxiliary sensor moved shows as its calibration stepping from the trusted one (a tight
  // saved calibration fails the step test within a fraction of a second) before its change test
  // has its second of data: the failure waits for it, the restart would throw that evidence
  // away.
  constexpr TimeNs kDeferFailureNs = ChangeDetector::kBinNs * (ChangeDetector::kMinBins + 2);
  // Auxiliary sensors only: a moved camera's frames are dropped by the frame gate before they
  // can move its calibration, and a camera's failure (a cam0 clock drifting: every state's time
  // with it) must restart before the other cameras' evidence takes the drift for a step.
  int slot = -1;
  const std::size_t slots = calibration.cameras() + calibration.auxiliaries();
  for (std::size_t i = calibration.cameras(); i < slots; ++i) {
    const ChangeSlot s = changeSlot(i);
    if (!s.tested) continue;
    if (why.find(s.name + " extrinsic") != std::string::npos ||
        why.find(s.name + " rotation") != std::string::npos) {
      slot = static_cast<int>(i);
    }
  }
  if (slot < 0) return false;
  if (slot != deferred_failure_slot) {
    deferred_failure_slot = slot;
    deferred_failure_ns = t;
  }
  // Half a second for the first bins after the step to close, longer only while they show it.
  const TimeNs waited = t - deferred_failure_ns;
  return waited < 2 * ChangeDetector::kBinNs ||
         (waited < kDeferFailureNs &&
          changes.suggests(static_cast<std::size_t>(slot), referenceCovariance(changeSlot(slot))));
}

bool Estimator::Impl::attribute(ChangeDetector::Change* change) {
  const std::size_t cameras = calibration.cameras();
  if (cameras < 2) return true;
  // Each camera's step over the same span, in the base IMU's frame (the right perturbation of
  // T_C_I): states that are off shift every camera's alike, a camera that moved only its own.
  // Camera j's own part is its step less the other cameras' (information-weighted) mean.
  using Vector7 = ChangeDetector::Vector7;
  using Matrix7 = ChangeDetector::Matrix7;
  std::vector<Vector7> d(cameras);
  std::vector<Matrix7> C(cameras), W(cameras);
  for (std::size_t j = 0; j < cameras; ++j) {
    if (!changes.step(j, change->since_ns, &d[j], &C[j])) return false;
    C[j] += referenceCovariance(changeSlot(j));
    W[j] = C[j].inverse();
  }
  std::size_t best = change->slot;
  double best_T = -1.0;
  Vector7 best_step = Vector7::Zero();
  Matrix7 best_C = Matrix7::Zero();
  for (std::size_t j = 0; j < cameras; ++j) {
    Matrix7 W_others = Matrix7::Zero();
    Vector7 Wd_others = Vector7::Zero();
    for (std::size_t o = 0; o < cameras; ++o) {
      if (o == j) continue;
      W_others += W[o];
      Wd_others += W[o] * d[o];
    }
    const Matrix7 mean_C = W_others.inverse();
    const Vector7 own = d[j] - mean_C * Wd_others;
    const Matrix7 own_C = C[j] + mean_C;
    const double T = own.dot(own_C.ldlt().solve(own));
    if (T > best_T) {
      best_T = T;
      best = j;
      best_step = own;
      best_C = own_C;
    }
  }
  if (cameras == 2) {
    // With two cameras their own parts are one difference, the same for both: the camera whose
    // step from the current estimate is the more significant is the candidate, and only when it
    // is clearly so (twice the other's statistic); else nothing is declared (cam1's clock reset by
    // 1 ms was pinned on cam0, and both ended 0.9 ms off at 50-100 sigma).
    double T[2];
    for (std::size_t j = 0; j < 2; ++j) T[j] = d[j].dot(C[j].ldlt().solve(d[j]));
    best = T[1] > T[0] ? 1 : 0;
    if (!(T[best] > 2.0 * T[1 - best])) return false;
    best_step = d[best];
    best_C = C[best];
    best_T = T[best];
  }
  if (!(best_T > ChangeDetector::kThreshold)) return false;
  // A camera held constant (by the options or the motion) cannot be re-opened: nothing then.
  if (window.problem()->IsParameterBlockConstant(changeSlot(best).extrinsic)) return false;
  if (best != change->slot) {
    change->slot = best;
    change->step = best_step;
    change->covariance = best_C;
    change->statistic = best_T;
    change->from_start = false;
  }
  return true;
}

bool Estimator::Impl::followChanges() {
  if (!options.detect_changes || !rig.target || options.batch || !initialized) return false;
  // After a restart for a fault the trusted calibration may carry what the fault did to it
  // before the checks caught it (a camera clock drifting for 3 s left two cameras' time offsets
  // 1.1-1.3 ms off at 9-10 sigma after the restarts of the fault suite's combined case): the
  // data then disagree with it by a step that is no change of the rig. The evidence is kept; no
  // change is declared for a while.
  constexpr TimeNs kSettleAfterFaultNs = 5 * kNsPerSecond;
  if (fault_restart_ns != std::numeric_limits<TimeNs>::min() && !window.empty() &&
      window.newestTime() - fault_restart_ns < kSettleAfterFaultNs) {
    return false;
  }
  const ceres::Problem& problem = *window.problem();
  const std::size_t slots = calibration.cameras() + calibration.auxiliaries();
  for (std::size_t slot = 0; slot < slots; ++slot) {
    const ChangeSlot s = changeSlot(slot);
    if (!s.tested || !problem.HasParameterBlock(s.extrinsic) ||
        problem.IsParameterBlockConstant(s.extrinsic)) {
      continue;  // held: nothing to re-open
    }
    auto change = changes.test(slot, referenceCovariance(s));
    if (!change) continue;
    if (s.camera && !attribute(&*change)) continue;
    if (!s.camera) {
      const double rotation =
          sigmas(change->step.head<3>(), change->covariance.topLeftCorner(3, 3));
      if (!(rotation * rotation > kAuxRotation)) continue;
    }
    if (reopen(*change)) return true;
  }
  return false;
}

std::string Estimator::Impl::describeChange(const ChangeDetector::Change& change,
                                            const ChangeSlot& s, bool offset_free) {
  // What moved, each quantity by its own part of the step.
  const Eigen::VectorXd& d = change.step;
  const Eigen::MatrixXd& C = change.covariance;
  struct Part {
    const char* quantity;
    double size, size_sigma, threshold;
  };
  std::vector<Part> parts = {{"rotation", d.head<3>().norm() * 180.0 / M_PI,
                              sigmas(d.head<3>(), C.topLeftCorner(3, 3)), kMoved3}};
  if (!s.gyro) {
    // An auxiliary IMU's translation is said only at the rotation's bar (see kAuxRotation).
    parts.push_back({"translation", d.segment<3>(3).norm() * 1e3,
                     sigmas(d.segment<3>(3), C.block(3, 3, 3, 3)),
                     s.camera ? kMoved3 : kAuxRotation});
  }
  if (offset_free) {
    parts.push_back({"time_offset", d[6] * 1e3, std::abs(d[6]) / std::sqrt(C(6, 6)), kMoved1});
  }
  std::vector<CalibrationChange> found;
  std::ostringstream text;
  text << std::fixed << std::setprecision(2) << s.name << " moved (its data since "
       << toSeconds(change.stamp_ns - change.since_ns) << " s before agree on a new calibration, "
       << std::setprecision(0) << change.statistic << " against " << ChangeDetector::kThreshold
       << " for nothing changed";
  if (change.noise > 1.0) text << std::setprecision(1) << ", noise " << change.noise << "x";
  text << "):";
  const auto add = [&](const Part& p) {
    CalibrationChange out;
    out.stamp_ns = change.stamp_ns;
    out.since_ns = change.since_ns;
    out.sensor = s.name;
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
  return text.str();
}

bool Estimator::Impl::reopen(const ChangeDetector::Change& change) {
  const std::size_t slot = change.slot;
  const ChangeSlot s = changeSlot(slot);
  ceres::Problem* problem = window.problem();
  // An auxiliary sensor's time offset is not tested (change_detector.h): its step is zero.
  const bool offset_free = s.camera && !problem->IsParameterBlockConstant(s.time_offset);
  std::string text = describeChange(change, s, offset_free);

  // The new values: the test's step from the current estimate.
  const Eigen::VectorXd& d = change.step;
  if (s.gyro) {
    double moved[kRotationSize];
    RotationManifold().Plus(s.extrinsic, d.data(), moved);
    std::copy(moved, moved + kRotationSize, s.extrinsic);
  } else {
    double moved[kPoseSize];
    PoseManifold().Plus(s.extrinsic, d.data(), moved);
    std::copy(moved, moved + kPoseSize, s.extrinsic);
  }
  if (offset_free) s.time_offset[0] += d[6];
  trusted.forget({s.extrinsic, s.time_offset});
  changes.forget(slot);
  if (s.camera) {
    // The other cameras' evidence was gathered against states that this camera's frames pulled
    // (with cam0 knocked before the recording, cam1 was declared moved 0.06 s after it, by
    // 0.26 deg): it is forgotten and gathered again.
    for (std::size_t c = 0; c < calibration.cameras(); ++c) changes.forget(c);
  }
  if (deferred_failure_slot == static_cast<int>(slot)) deferred_failure_slot = -1;
  if (s.camera) frames.forgetCamera(slot);
  const auto reopenIn = [&](ceres::Problem* p) {
    if (s.camera) {
      calibration.reopenCamera(slot, p);
    } else {
      calibration.reopenAux(slot - calibration.cameras(), p);
    }
  };
  if (s.camera && change.from_start) {
    // The camera's frames at the new mount entered the first batch as they were (it moved before
    // the window started): what they pulled is in the states and the window's prior (a camera
    // knocked before the recording pulled every camera's translation 4 mm off through them, 30
    // sigma). The window starts over with its new value instead, its frames held out of the
    // first batch. Later, frames the gate let through (a move too small for it) are released
    // with the camera: starting over from the trusted calibration left a camera moved by 5 mm
    // and the others 0.17-0.25 mm off at 5 sigma, released 0.04-0.05 mm (3.9 sigma). An
    // auxiliary sensor's are not (the first batch holds it, and its bias states take up what it
    // cannot explain).
    reopenIn(nullptr);
    frames.holdOutOfFirstBatch(slot);
    // The calibrations trusted since the change began rest on those frames too (a camera moved
    // by 5 mm, too little for the gate, left the others 0.17 mm off at 5 sigma through them).
    trusted.distrust(change.since_ns, ChangeDetector::kBinNs * ChangeDetector::kBins);
    restart(text, change.stamp_ns, false, true);
    return true;
  }
  // Its priors the defaults; the window's prior lets go of what it knew of the old value.
  reopenIn(problem);
  if (joint_prior_id != nullptr) {
    problem->RemoveResidualBlock(joint_prior_id);
    joint_prior_id = nullptr;
    std::vector<double*> joint_blocks;
    if (ceres::CostFunction* joint = trusted.jointPrior(&joint_blocks)) {
      joint_prior_id = problem->AddResidualBlock(joint, nullptr, joint_blocks);
    }
  }
  const Status released = prior.release(
      problem, {s.extrinsic, s.time_offset},
      [this](const double* block) { return monitor.baseManifold(*window.problem(), block); });
  if (!released.ok()) {
    // The prior cannot be rebuilt without them: drop it (the window's states and the other
    // sensors' priors hold the rest).
    prior.removeFrom(problem);
    text += " (the window's prior was dropped: " + released.message() + ")";
  }
  status_text = text;
  calibration_note += (calibration_note.empty() ? "" : "; ") + text;
  return false;
}

}  // namespace mvis
