// The estimator's facade: data in, the main loop, solving, marginalization and output. The
// parts it wires are described in doc/architecture.md; the initialization is in
// estimator_startup.cpp.
#include <ceres/normal_prior.h>

#include <cmath>
#include <iomanip>
#include <set>
#include <sstream>
#include <utility>

#include "estimator_impl.h"
#include "mvis/factors/imu_factor.h"

namespace mvis {

using estimator_internal::State;

namespace {

// Window states closer than this to the previous one are not made (the frame is dropped).
constexpr TimeNs kMinStateIntervalNs = 5000000;  // 5 ms
// A frame or auxiliary reading stamped (in the base clock) further ahead of the base IMU's
// newest reading, or further behind it, has a clock that jumped or restarted: it is dropped.
// Not closer: a live node behind on its IMU queue (a slow solve without a board) saw frames
// 1.2 s ahead of the readings it had, and 1 s here dropped them.
constexpr TimeNs kMaxAheadNs = 10 * kNsPerSecond;
constexpr TimeNs kMaxBehindNs = 10 * kNsPerSecond;
// The failure checks' bounds on the newest state (EstimatorOptions::failure_step_sigma).
constexpr double kMaxSpeed = 50.0;         // [m/s]
constexpr double kMaxBoardDistance = 1e3;  // [m]
// A failure found after a solve: the window starts over from a calibration trusted at least
// this long before it (a slowly growing fault passes the checks for a while).
constexpr TimeNs kFailureLookbackNs = 5 * kNsPerSecond;
// Window states without any camera frame for this long: the window starts over (a camera
// silent for 5 s, or every frame dropped by the gate). Not shorter: a live node without a board,
// behind on a loaded machine, lost frames for 1.1 s and started over for nothing.
constexpr TimeNs kMaxBlindNs = 3 * kNsPerSecond;

double seconds(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

}  // namespace

Estimator::Impl::Impl(const Rig& r, const EstimatorOptions& o)
    : rig(r),
      options(o),
      calibration(rig, options),
      intrinsics(rig, options),
      imu(rig.inertial[0], options.imu_integration_step_s),
      window(options),
      monitor(rig, options, calibration, intrinsics),
      landmarks(rig.cameras.size(), options.batch ? 0 : options.carried_tags),
      aux(rig, options, imu, window, calibration, intrinsics, monitor, counters),
      frames(rig, options, window, imu, calibration, intrinsics, landmarks, counters),
      startup(rig, options, calibration, imu, counters),
      inertial_fit(rig, options, intrinsics),
      changes(rig.cameras.size() + rig.inertial.size() - 1),
      odometry(rig.inertial[0], options.imu_integration_step_s) {
  trusted.setConfigured(trustedBlocks(true));
  if (options.detect_changes && rig.target && !options.batch) {
    frames.setChangeDetector(&changes);
    aux.setChangeDetector(&changes, rig.cameras.size());
  }
}

std::vector<estimator_internal::TrustedCalibration::Block> Estimator::Impl::trustedBlocks(
    bool configured) {
  const ceres::Problem* problem = configured ? nullptr : window.problem();
  auto out = calibration.trustedBlocks(problem);
  auto more = intrinsics.trustedBlocks(problem);
  out.insert(out.end(), std::make_move_iterator(more.begin()), std::make_move_iterator(more.end()));
  return out;
}

Status Estimator::Impl::plausibleStamp(const std::string& sensor, TimeNs t) {
  if (imu.empty()) return Status::Ok();
  const TimeNs ahead = t - imu.lastStamp();
  if (ahead <= kMaxAheadNs && ahead >= -kMaxBehindNs) return Status::Ok();
  ++counters.stamps_implausible;
  std::ostringstream s;
  s << sensor << ": stamped " << std::abs(toSeconds(ahead)) << " s "
    << (ahead > 0 ? "ahead of " : "behind ") << rig.inertial[0].name
    << "'s newest reading (its clock jumped or restarted?): dropped";
  return Status::Error(s.str());
}

void Estimator::Impl::newProblem() {
  window.reset();
  joint_prior_id = nullptr;
  frames.dropBatchLosses();
  prior.clear();
  landmarks.clear();
}

Status Estimator::Impl::withWarning(Status s) {
  if (!restart_note.empty()) {
    aux.takeWarning();
    return Status::Error(std::move(restart_note));
  }
  if (!calibration_note.empty()) return Status::Error(std::exchange(calibration_note, ""));
  std::string warning = aux.takeWarning();
  if (!s.ok() || warning.empty()) return s;
  return Status::Error(warning);
}

Status Estimator::Impl::addImu(std::size_t sensor, const ImuMeasurement& raw) {
  if (sensor >= rig.inertial.size()) {
    ++counters.aux_dropped;
    return Status::Error("reading of an unknown inertial sensor " + std::to_string(sensor));
  }
  if (sensor != 0) {
    const Status plausible =
        plausibleStamp(rig.inertial[sensor].name,
                       raw.stamp_ns + fromSeconds(calibration.aux(sensor - 1).time_offset[0]));
    if (!plausible.ok()) return plausible;
    return aux.add(sensor, raw, initialized);
  }
  if (!raw.gyro.allFinite() || !raw.accel.allFinite()) {
    ++counters.imu_non_finite;
    return Status::Error(rig.inertial[0].name + ": non-finite reading dropped");
  }
  const ImuMeasurement m = intrinsics.arrivalCorrection(0).apply(raw, false);
  const TimeNs last = imu.lastStamp();
  if (last != std::numeric_limits<TimeNs>::min() && m.stamp_ns <= last) {
    if (m.stamp_ns < last - kNsPerSecond) {
      std::ostringstream s;
      s << rig.inertial[0].name << ": time jumped back by " << toSeconds(last - m.stamp_ns)
        << " s (bag restarted?)";
      restart(s.str(), m.stamp_ns);
      imu.push(m);
      return withWarning(Status::Ok());
    }
    ++counters.imu_out_of_order;
    return Status::Error(rig.inertial[0].name + ": reading out of order or repeated, dropped");
  }
  const bool gap = last != std::numeric_limits<TimeNs>::min() && imu.maxInterval() > 0.0 &&
                   toSeconds(m.stamp_ns - last) > imu.maxInterval();
  const double gap_s = gap ? toSeconds(m.stamp_ns - last) : 0.0;
  if (gap && gap_s > options.imu_max_gap_s) {
    ++counters.imu_gaps;
    std::ostringstream s;
    s << rig.inertial[0].name << ": no reading for " << gap_s << " s (longer than imu_max_gap_s "
      << options.imu_max_gap_s << " s)";
    restart(s.str(), m.stamp_ns);
    imu.push(m);
    return withWarning(Status::Ok());
  }
  imu.push(m);
  process();
  propagate(raw);
  if (gap) {
    ++counters.imu_gaps;
    std::ostringstream s;
    s << rig.inertial[0].name << ": no reading for " << gap_s
      << " s; integrated across the gap with inflated noise";
    return withWarning(Status::Error(s.str()));
  }
  return withWarning(Status::Ok());
}

Status Estimator::Impl::addTagFrame(const TagFrame& frame) {
  if (frame.camera >= rig.cameras.size()) return Status::Error("tag frame of an unknown camera");
  if (static_cast<int>(frame.tags.size()) < frames.minTags()) {
    ++counters.frames_too_few_tags;
    return Status::Ok();  // nothing wrong with the data, just nothing to use
  }
  const Status plausible = plausibleStamp(rig.cameras[frame.camera].name,
                                          frame.stamp_ns + calibration.timeOffsetNs(frame.camera));
  if (!plausible.ok()) return plausible;
  if (!frames.markNewer(frame)) {
    ++counters.frames_out_of_order;
    return Status::Error(rig.cameras[frame.camera].name +
                         ": frame out of order or repeated, dropped");
  }
  if (!initialized && frame.camera != 0) {
    SE3 T_G_C;
    if (boardPose(frame, &T_G_C)) startup.recordRotation(frame.camera, frame.stamp_ns, T_G_C);
  }
  frames.enqueue(frame);
  process();
  std::string rejected = frames.takeWarning();
  return withWarning(rejected.empty() ? Status::Ok() : Status::Error(std::move(rejected)));
}

void Estimator::Impl::process() {
  while (frames.hasBaseFrame()) {
    const TimeNs t = frames.nextBaseFrame().stamp_ns + calibration.timeOffsetNs(0);
    // Wait for the IMU to pass t, and for the cubic through the readings around t.
    if (!imu.reaches(t)) return;
    if (imu.firstStamp() > t || (!window.empty() && t <= window.newestTime())) {
      ++counters.frames_too_old;
      frames.takeBaseFrame();
      continue;
    }
    // A state right after the last one (cam0's time offset moved by about a frame period since
    // it was placed) would make an IMU factor over a fraction of a reading period, whose
    // information is near-singular and swamps the solve.
    if (!window.empty() && t - window.newestTime() < kMinStateIntervalNs) {
      ++counters.frames_too_close;
      frames.takeBaseFrame();
      continue;
    }
    // The window's newest states have seen no camera for this long (frames missing, dropped
    // or rejected): they rest on the readings alone, too long to trust.
    if (initialized && frames.lastEntered() != std::numeric_limits<TimeNs>::min() &&
        t - frames.lastEntered() > kMaxBlindNs) {
      std::ostringstream s;
      s << "no camera frame entered the window for " << toSeconds(t - frames.lastEntered()) << " s";
      restart(s.str(), t);
      continue;
    }
    TagFrame taken = frames.takeBaseFrame();
    if (!initialized) {
      addInitFrame(std::move(taken), t);
    } else {
      const auto start = Clock::now();
      window_data_s += toSeconds(t - window.newestTime());
      addState(taken, t);
      frames.attachWaiting(initialized);
      aux.extend();
      if (followChanges()) continue;  // the window started over with a moved camera
      SolveSummary summary;
      if (!options.batch && ++frames_since_solve >= options.solve_every) {
        const auto check_start = Clock::now();
        monitor.check(window.problem());  // holds what the motion cannot observe before solving
        ++counters.degeneracy_checks;
        counters.degeneracy_check_s += seconds(check_start, Clock::now());
        counters.window_checks = monitor.windowChecks();
        counters.window_check_s = monitor.windowCheckSeconds();
        summary = solve(options.max_iterations);
        frames_since_solve = 0;
        const std::string why = failure();
        if (!why.empty() && !deferFailure(why, t)) {
          ++counters.failures;
          restart(why, failure_since(t), true);
          continue;  // the frames waiting were dropped with the window
        }
        if (why.empty()) deferred_failure_slot = -1;
      } else {
        summary = window.summary();  // the new state as the IMU predicted it
        summary.usable = true;
      }
      if (!options.batch && static_cast<int>(window.size()) > options.window_size) {
        marginalizeOldest();
      }
      publish(summary, start);
      if (!covariance_failure.empty() && !deferFailure(covariance_failure, t)) {
        ++counters.failures;
        restart(std::move(covariance_failure), failure_since(t), true);
        covariance_failure.clear();
        continue;
      }
      covariance_failure.clear();
    }
    trimBuffers();
  }
}

void Estimator::Impl::addTimeOffsetInformation(TimeNs t) {
  if (information_until != std::numeric_limits<TimeNs>::min() && t > information_until &&
      t - information_until <= kMaxBlindNs) {
    time_offset_information += imu.timeOffsetInformation(information_until, t);
  }
  information_until = t;
}

std::unique_ptr<State> Estimator::Impl::makeState(TimeNs t) const {
  auto s = std::make_unique<State>();
  s->t = t;
  // Smoothed (ImuBuffer::smoothedAt): translation-only, 24 x 60 s, imu1's time offset RMS
  // error/sigma 3.98 -> 2.96, the cameras' 2.04-2.11 -> 1.77-1.80. The camera frames' anchors
  // take the fitted rate too (camera_frames.cpp).
  const ImuMeasurement at = imu.smoothedAt(t);
  s->motion.gyro = at.gyro;
  s->motion.accel = at.accel;
  s->motion.angular_acceleration = imu.angularAcceleration(t);
  s->aux.resize(aux.size());
  return s;
}

void Estimator::Impl::addImuFactor(std::size_t k, std::shared_ptr<const ImuPreintegration> pre) {
  State* a = &window.state(k);
  State* b = &window.state(k + 1);
  monitor.addReadingMoments(0, b->t, pre->samples(), Eigen::Quaterniond(poseRotation(a->pose)),
                            Eigen::Vector3d(calibration.gravity()), a->biasGyro());
  double* g = calibration.gravity();
  double* block = intrinsics.values(0);
  if (block == nullptr) {
    window.addRecord(a, new ImuFactor(std::move(pre)), nullptr,
                     {a->pose, a->speed_bias, b->pose, b->speed_bias, g}, 0);
    return;
  }
  window.addRecord(
      a,
      new ImuFactor(std::move(pre), intrinsics.block(0)->frame,
                    options.imu_intrinsics_linearization, intrinsics.block(0)->initial),
      nullptr, {a->pose, a->speed_bias, b->pose, b->speed_bias, g, block}, 0);
}

void Estimator::Impl::addState(const TagFrame& frame, TimeNs t) {
  const State& last = window.newest();
  const Eigen::Vector3d bg = last.biasGyro(), ba = last.biasAccel();
  const TimeNs last_t = last.t;
  const Eigen::Quaterniond R_last(poseRotation(last.pose));
  auto pre = imu.preintegrate(last_t, t, bg, ba);  // raw with intrinsics: the factor corrects
  auto s = makeState(t);
  addTimeOffsetInformation(t);
  // The state as it stays until the next solve (solve_every): from corrected readings, or in a
  // batch where the seed trajectory has it.
  if (!seedAt(t, s.get())) {
    Eigen::Quaterniond q;
    Eigen::Vector3d p, v;
    (intrinsics.block(0) != nullptr ? corrected(last, t) : pre)
        ->predict(poseRotation(last.pose), posePosition(last.pose),
                  Eigen::Vector3d(last.speed_bias), Eigen::Vector3d(calibration.gravity()), &q, &p,
                  &v);
    se3ToPose(SE3(q, p), s->pose);
    Eigen::Map<Eigen::Vector3d>(s->speed_bias) = v;
    std::copy(last.speed_bias + 3, last.speed_bias + 9, s->speed_bias + 3);
  }
  window.push(std::move(s));
  addImuFactor(window.size() - 2, pre);
  frames.add(frame, window.size() - 1, initialized);
  monitor.addMotion(last_t, t, imu.between(last_t, t), bg, R_last,
                    Eigen::Vector3d(calibration.gravity()));
}

void Estimator::Impl::propagate(const ImuMeasurement& raw) {
  if (!propagation_callback) return;
  if (const auto state = odometry.add(raw)) propagation_callback(*state);
}

PropagationAnchor Estimator::Impl::anchor() {
  PropagationAnchor out;
  if (!initialized || window.empty()) return out;
  const State& newest = window.newest();
  out.valid = true;
  out.state = newest.toEstimate();
  out.gravity_G = Eigen::Vector3d(calibration.gravity());
  out.correction = intrinsics.block(0) != nullptr ? intrinsics.baseCorrection()
                                                  : intrinsics.arrivalCorrection(0);
  intrinsics.baseBiases(newest.biasGyro(), newest.biasAccel(), &out.corrected_bias_gyro,
                        &out.corrected_bias_accel);
  return out;
}

std::shared_ptr<ImuPreintegration> Estimator::Impl::corrected(const State& from, TimeNs to) const {
  Eigen::Vector3d bg_c, ba_c;
  intrinsics.baseBiases(from.biasGyro(), from.biasAccel(), &bg_c, &ba_c);
  return imu.preintegrate(from.t, to, bg_c, ba_c, &intrinsics.baseCorrection());
}

SolveSummary Estimator::Impl::solve(int iterations, double max_time_s) {
  SolveSummary out =
      window.solve(iterations, max_time_s > 0 ? max_time_s : options.max_solve_time_s);
  intrinsics.refreshBase();
  ++counters.solves;
  return out;
}

void Estimator::Impl::marginalizeOldest(bool rows) {
  State& oldest = window.oldest();
  std::vector<double*> leaving = {oldest.pose, oldest.speed_bias};
  for (const auto& noise : oldest.propagation_noise) leaving.push_back(noise.get());
  const std::vector<double*> leaving_landmarks = landmarks.leaving(window.states());
  leaving.insert(leaving.end(), leaving_landmarks.begin(), leaving_landmarks.end());
  // The window's own landmarks leave with every observation of them, each eliminated alone (no
  // prior holds one: the first batch's states cut to the window took the carried tags only).
  std::set<const double*> own;
  for (const double* block : leaving_landmarks) {
    if (!landmarks.carried(block)) own.insert(block);
  }
  window.moveToOldest(own);
  addResiduals(oldest, &left_residuals);  // at its last solve, for the report
  aux.leaving(oldest, &leaving);
  inertial_fit.leaving(oldest, trusted.fromCovariance());
  const std::string misfit =
      inertial_fit.check(trusted.inflation(), &counters.held_intrinsics_misfits);
  if (!misfit.empty()) calibration_note += (calibration_note.empty() ? "" : "; ") + misfit;
  // The measurements leaving add nothing along what they cannot observe; the old prior keeps
  // what earlier motion told.
  auto made = prior.marginalize(
      oldest.residuals, leaving,
      [this](const double* block) { return monitor.baseManifold(*window.problem(), block); },
      monitor.heldDirections(), calibration.fixedBlocks(), own,
      !rig.target && options.carried_tags > 0, rows);
  // Remove the old prior and the state (with every residual on it).
  prior.removeFrom(window.problem());
  window.removeOldest(leaving);
  for (double* block : leaving_landmarks) landmarks.remove(block);
  if (!made.ok()) {
    status_text = "marginalization failed (" + made.status().message() + "); prior dropped";
    return;
  }
  prior.install(window.problem(), std::move(made).value());
}

void Estimator::Impl::publish(const SolveSummary& summary, Clock::time_point start) {
  ++solves_since_covariance;
  EstimatorUpdate u;
  u.solve = summary;
  u.solve.landmarks = landmarks.count();
  u.solve.carried_landmarks = landmarks.carriedCount();
  u.state = window.newest().toEstimate();
  u.anchor = anchor();
  if (propagation_callback) odometry.setAnchor(u.anchor);
  u.gravity_G = Eigen::Vector3d(calibration.gravity());
  u.unobservable = monitor.unobservable();
  u.changes.assign(declared_changes.begin() + static_cast<long>(changes_published),
                   declared_changes.end());
  changes_published = declared_changes.size();
  u.pose_covariance.setConstant(std::numeric_limits<double>::quiet_NaN());
  u.velocity_covariance.setConstant(std::numeric_limits<double>::quiet_NaN());
  u.gyro_bias_covariance.setConstant(std::numeric_limits<double>::quiet_NaN());
  if (!options.batch && options.covariance_every > 0 &&
      solves_since_covariance >= options.covariance_every) {
    Eigen::Matrix<double, 6, 6> pose_cov;
    Eigen::Matrix<double, 9, 9> speed_bias_cov;
    if (covariance(&pose_cov, nullptr, &speed_bias_cov).ok()) {
      u.pose_covariance = pose_cov;
      u.velocity_covariance = speed_bias_cov.topLeftCorner<3, 3>();
      u.gyro_bias_covariance = speed_bias_cov.block<3, 3>(3, 3);
      u.calibration_covariance_updated = true;
    }
  }
  u.solve.total_s = seconds(start, Clock::now());
  if (callback) callback(u);
}

void Estimator::Impl::trimBuffers() {
  // IMU readings are needed from the newest state on (or the first initialization frame).
  TimeNs keep_from = std::numeric_limits<TimeNs>::max();
  if (!window.empty()) keep_from = window.newestTime();
  // A gravity-sensitive gyroscope's chain may start at any window state, and its time offset
  // may put its readings up to a tenth of a second earlier.
  if (!window.empty() && aux.needsBaseReadings()) {
    keep_from = window.oldest().t - fromSeconds(0.1);
  }
  if (!startup.empty()) keep_from = std::min(keep_from, startup.oldestTime());
  if (!initialized && !imu.empty()) {
    // Clock alignment looks up to kAlignRange around 2 * kAlignSpanNs of board poses.
    keep_from = std::min(
        keep_from, imu.lastStamp() - 2 * estimator_internal::Startup::kAlignSpanNs - kNsPerSecond);
  }
  if (keep_from == std::numeric_limits<TimeNs>::max()) {
    // Nothing to anchor to: keep two seconds.
    if (!imu.empty()) keep_from = imu.lastStamp() - 2 * kNsPerSecond;
  }
  keep_from -= fromSeconds(0.05);
  imu.trimBefore(keep_from);
  // Auxiliary readings are needed from the oldest window state (or initialization frame) on: a
  // chain may start at any window state.
  TimeNs from = std::numeric_limits<TimeNs>::max();
  if (!window.empty()) from = window.oldest().t;
  if (!startup.empty()) from = std::min(from, startup.oldestTime());
  aux.trim(from);
}

void Estimator::Impl::restart(const std::string& why, TimeNs when, bool failure, bool for_change) {
  if (failure) {
    trusted.distrust(when, kFailureLookbackNs);
  } else {
    trusted.dropPending();
  }
  resetAll();
  trusted.restore();
  if (!trusted.fromCovariance()) frames.forgetResiduals();
  ++counters.restarts;
  std::ostringstream s;
  s << why << ": the window starts over from ";
  if (trusted.fromCovariance()) {
    s << "the trusted calibration (with its covariance";
    if (when > trusted.time()) {
      s << ", of " << std::fixed << std::setprecision(1) << toSeconds(when - trusted.time())
        << " s before";
    }
    s << ")";
  } else {
    s << "the configured calibration";
  }
  status_text = s.str();
  last_restart = restart_note = status_text;
  last_restart_ns = when;
  if (!for_change) fault_restart_ns = when;
}

std::string Estimator::Impl::failure() const {
  if (window.empty()) return "";
  const State& newest = window.newest();
  std::ostringstream s;
  const double speed = Eigen::Vector3d(newest.speed_bias).norm();
  const double distance = posePosition(newest.pose).norm();
  if (!(speed <= kMaxSpeed)) {
    s << rig.inertial[0].name << " estimated moving at " << speed << " m/s";
  } else if (rig.target && !(distance <= kMaxBoardDistance)) {
    s << rig.inertial[0].name << " estimated " << distance << " m from the board";
  } else if (options.failure_step_sigma > 0.0 && trusted.fromCovariance()) {
    std::string which;
    const double step = trusted.largestStep(&which);
    if (step > options.failure_step_sigma) {
      s << which << " moved " << step << " sigma from the trusted calibration (failure_step_sigma "
        << options.failure_step_sigma;
      if (trusted.inflation() > 1.0) {
        s << "; sigma taken " << std::sqrt(trusted.inflation()) << "x larger";
      }
      s << ")";
    }
  }
  return s.str().empty() ? "" : "estimate failed: " + s.str();
}

void Estimator::Impl::resetAll() {
  newProblem();
  imu.clear();
  frames.clear();
  startup.clear(trusted.fromCovariance());
  landmarks.resetPoseTags();
  aux.clear();
  inertial_fit.clear();
  changes.clear();
  deferred_failure_slot = -1;
  monitor.clear();  // after newProblem(): the old problem no longer uses its manifolds
  odometry.reset();
  initialized = false;
  status_text = "reset: waiting for data";
}

Estimator::Estimator(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Estimator::~Estimator() = default;

StatusOr<std::unique_ptr<Estimator>> Estimator::create(const Rig& rig,
                                                       const EstimatorOptions& options) {
  Status valid = validate(options, rig);
  if (!valid.ok()) return valid;
  return std::unique_ptr<Estimator>(new Estimator(std::make_unique<Impl>(rig, options)));
}

Status Estimator::addImu(std::size_t sensor, const ImuMeasurement& m) {
  return impl_->addImu(sensor, m);
}
Status Estimator::addTagFrame(const TagFrame& frame) { return impl_->addTagFrame(frame); }
void Estimator::setUpdateCallback(UpdateCallback callback) {
  impl_->callback = std::move(callback);
}
void Estimator::setPropagationCallback(PropagationCallback callback) {
  impl_->propagation_callback = std::move(callback);
}
Rig Estimator::calibration() const { return impl_->reportedCalibration(); }
Status Estimator::computeCovariance() {
  const Status s = impl_->covariance(nullptr);
  if (s.ok() && impl_->covariance_failure.empty() && !impl_->calibration_note.empty()) {
    return Status::Error(std::exchange(impl_->calibration_note, ""));
  }
  if (!s.ok() || impl_->covariance_failure.empty()) return s;
  // Nothing follows to restart on: say it (the standard deviations are updated all the same).
  std::string failed = std::move(impl_->covariance_failure);
  impl_->covariance_failure.clear();
  return Status::Error(failed + "; the calibration is the current estimate all the same");
}
std::vector<EstimatorState> Estimator::trajectory() const {
  std::vector<EstimatorState> out = impl_->window.past();
  for (const auto& s : impl_->window.states()) out.push_back(s->toEstimate());
  return out;
}
std::string Estimator::status() const { return impl_->status_text; }
bool Estimator::initialized() const { return impl_->initialized; }
std::map<int, std::array<Eigen::Vector3d, 4>> Estimator::landmarks() const {
  return impl_->landmarks.corners();
}
const EstimatorCounters& Estimator::counters() const { return impl_->counters; }
std::vector<CalibrationChange> Estimator::changes() const { return impl_->declared_changes; }
Estimator::Restart Estimator::lastRestart() const {
  return {impl_->last_restart, impl_->last_restart_ns};
}
double Estimator::sigmaInflation() const { return std::sqrt(impl_->trusted.inflation()); }
double Estimator::timeOffsetFloor() const {
  const double info = impl_->time_offset_information;
  return info > 0.0 ? 1.0 / std::sqrt(info) : std::numeric_limits<double>::quiet_NaN();
}
void Estimator::reset() {
  impl_->restart("reset requested", impl_->imu.empty() ? 0 : impl_->imu.lastStamp());
  impl_->restart_note.clear();  // the caller knows
  ++impl_->counters.resets;
}

}  // namespace mvis
