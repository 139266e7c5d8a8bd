#include "estimator_impl.h"

namespace mvis {

static Status validateHolds(const Rig& rig, const std::vector<std::string>& hold) {
  for (const std::string& entry : hold) {
    const auto dot = entry.rfind('.');
    const std::string sensor = entry.substr(0, dot == std::string::npos ? 0 : dot);
    const std::string quantity = dot == std::string::npos ? "" : entry.substr(dot + 1);
    std::string names;
    bool camera = false, aux = false, base = false;
    for (const auto& c : rig.cameras) {
      names += (names.empty() ? "" : ", ") + c.name;
      camera = camera || c.name == sensor;
    }
    for (std::size_t i = 0; i < rig.inertial.size(); ++i) {
      names += ", " + rig.inertial[i].name;
      (i == 0 ? base : aux) |= rig.inertial[i].name == sensor;
    }
    const std::string where = "estimator option hold: '" + entry + "': ";
    if (!camera && !aux && !base) {
      return Status::Error(where + "expected <sensor>.<quantity> with a sensor of the rig (" +
                           names + ")");
    }
    const bool spatial = quantity == "extrinsic" || quantity == "time_offset";
    const bool imu = quantity == "intrinsics" || quantity == "gravity_sensitivity";
    const bool known = camera ? spatial || quantity == "intrinsics" : base ? imu : spatial || imu;
    if (!known) {
      const char* allowed = camera ? "extrinsic, time_offset or intrinsics"
                            : base ? "intrinsics or gravity_sensitivity (the base IMU defines "
                                     "the rig's frame and clock)"
                                   : "extrinsic, time_offset, intrinsics or gravity_sensitivity";
      return Status::Error(where + "quantity must be " + allowed + ", got '" + quantity + "'");
    }
  }
  return Status::Ok();
}

Status validate(const EstimatorOptions& o) {
  auto bad = [](const std::string& key, const std::string& why) {
    return Status::Error("estimator option " + key + ": " + why);
  };
  if (o.window_size < 3) return bad("window_size", "must be at least 3");
  if (o.max_iterations < 1) return bad("max_iterations", "must be at least 1");
  if (o.solve_every < 1 || o.solve_every >= o.window_size) {
    return bad("solve_every",
               "must be at least 1 and less than window_size (every state must "
               "be solved before it is marginalized)");
  }
  if (!(o.max_solve_time_s > 0.0)) return bad("max_solve_time_s", "must be positive");
  if (!(o.init_solve_time_s > 0.0)) return bad("init_solve_time_s", "must be positive");
  if (o.threads < 1) return bad("threads", "must be at least 1");
  if (!(o.pixel_sigma_px > 0.0)) return bad("pixel_sigma_px", "must be positive");
  if (!(o.huber_sigma >= 0.0)) return bad("huber_sigma", "must be zero or positive");
  if (!(o.imu_integration_step_s >= 0.0))
    return bad("imu_integration_step_s", "must be zero (off) or positive");
  if (o.init_frames < 3) return bad("init_frames", "must be at least 3");
  if (o.min_tags < 1) return bad("min_tags", "must be at least 1");
  if (!(o.gravity_m_s2 > 0.0)) return bad("gravity_m_s2", "must be positive");
  for (const auto& [key, v] : {std::pair<const char*, double>{"extrinsic_rotation_prior_rad",
                                                              o.extrinsic_rotation_prior_rad},
                               {"extrinsic_translation_prior_m", o.extrinsic_translation_prior_m},
                               {"time_offset_prior_s", o.time_offset_prior_s},
                               {"intrinsics_focal_prior_px", o.intrinsics_focal_prior_px},
                               {"intrinsics_centre_prior_px", o.intrinsics_centre_prior_px},
                               {"distortion_prior", o.distortion_prior},
                               {"bias_gyro_prior", o.bias_gyro_prior},
                               {"bias_accel_prior", o.bias_accel_prior},
                               {"velocity_prior", o.velocity_prior},
                               {"aux_rotation_prior_rad", o.aux_rotation_prior_rad},
                               {"aux_translation_prior_m", o.aux_translation_prior_m},
                               {"aux_time_offset_prior_s", o.aux_time_offset_prior_s},
                               {"aux_velocity_prior", o.aux_velocity_prior},
                               {"aux_timeout_s", o.aux_timeout_s},
                               {"aux_max_gap_s", o.aux_max_gap_s},
                               {"observability_horizon_s", o.observability_horizon_s},
                               {"imu_scale_misalignment_prior", o.imu_scale_misalignment_prior},
                               {"imu_gravity_sensitivity_prior", o.imu_gravity_sensitivity_prior},
                               {"imu_acc_rotation_prior_rad", o.imu_acc_rotation_prior_rad}}) {
    if (!(v > 0.0)) return bad(key, "must be positive");
  }
  if (o.covariance_every < 0) return bad("covariance_every", "must be zero or positive");
  if (!(o.imu_intrinsics_observability_ratio >= 0.0)) {
    return bad("imu_intrinsics_observability_ratio", "must be zero (off) or positive");
  }
  if (!(o.observability_ratio >= 0.0)) {
    return bad("observability_ratio", "must be zero (off) or positive");
  }
  return Status::Ok();
}

void Estimator::Impl::newProblem() {
  ceres::Problem::Options po;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.enable_fast_removal = true;
  problem = std::make_unique<ceres::Problem>(po);
  prior.clear();
  prior_whole.reset();
  landmarks.clear();
  landmark_ids.clear();
}

Status Estimator::Impl::withWarning(Status s) {
  if (!s.ok() || warning.empty()) return s;
  Status out = Status::Error(warning);
  warning.clear();
  return out;
}

Status Estimator::Impl::addImu(std::size_t sensor, const ImuMeasurement& raw) {
  if (sensor >= rig.inertial.size()) {
    ++counters.aux_dropped;
    return Status::Error("reading of an unknown inertial sensor " + std::to_string(sensor));
  }
  if (sensor != 0) return addAuxReading(sensor, raw);
  if (!raw.gyro.allFinite() || !raw.accel.allFinite()) {
    ++counters.imu_non_finite;
    return Status::Error(rig.inertial[0].name + ": non-finite reading dropped");
  }
  const ImuMeasurement m = imu_corrections[0].apply(raw, false);
  if (last_imu != std::numeric_limits<TimeNs>::min() && m.stamp_ns <= last_imu) {
    if (m.stamp_ns < last_imu - kNsPerSecond) {
      const double back = toSeconds(last_imu - m.stamp_ns);
      resetAll();
      ++counters.resets;
      last_imu = m.stamp_ns;
      imu.push_back(m);
      std::ostringstream s;
      s << rig.inertial[0].name << ": time jumped back by " << back
        << " s (bag restarted?): estimator reset";
      return Status::Error(s.str());
    }
    ++counters.imu_out_of_order;
    return Status::Error(rig.inertial[0].name + ": reading out of order or repeated, dropped");
  }
  const bool gap = last_imu != std::numeric_limits<TimeNs>::min() && maxImuInterval() > 0.0 &&
                   toSeconds(m.stamp_ns - last_imu) > maxImuInterval();
  const double gap_s = gap ? toSeconds(m.stamp_ns - last_imu) : 0.0;
  last_imu = m.stamp_ns;
  imu.push_back(m);
  if (imu.size() > 1) imu.back().span_ns = m.stamp_ns - imu[imu.size() - 2].stamp_ns;
  process();
  propagate(m);
  if (gap) {
    ++counters.imu_gaps;
    std::ostringstream s;
    s << rig.inertial[0].name << ": no reading for " << gap_s
      << " s; integrated across the gap with inflated noise";
    return Status::Error(s.str());
  }
  return withWarning(Status::Ok());
}

Status Estimator::Impl::addTagFrame(const TagFrame& frame) {
  if (frame.camera >= rig.cameras.size()) return Status::Error("tag frame of an unknown camera");
  const std::string& name = rig.cameras[frame.camera].name;
  // Without a board one tag is a frame's worth: four corners of a landmark (a rig among
  // scattered tags often sees only one).
  const int min_tags = landmarkMode() ? 1 : options.min_tags;
  if (static_cast<int>(frame.tags.size()) < min_tags) {
    ++counters.frames_too_few_tags;
    return Status::Ok();  // nothing wrong with the data, just nothing to use
  }
  if (frame.stamp_ns <= last_frame[frame.camera]) {
    ++counters.frames_out_of_order;
    return Status::Error(name + ": frame out of order or repeated, dropped");
  }
  last_frame[frame.camera] = frame.stamp_ns;
  if (!initialized && frame.camera != 0) {
    SE3 T_G_C;
    if (boardPose(frame, &T_G_C)) recordBoardRotation(frame.camera, frame.stamp_ns, T_G_C);
  }
  if (frame.camera == 0) {
    base_frames.push_back(frame);
    // Frames wait for the IMU to pass them; if it stops, they must not pile up without bound.
    while (base_frames.size() > 300) {
      base_frames.pop_front();
      ++counters.frames_too_old;
    }
  } else {
    auto& q = other_frames[frame.camera];
    q.push_back(frame);
    // A camera whose frames cannot be placed (cam0 stopped) must not grow without bound.
    while (q.size() > 300) {
      q.pop_front();
      ++counters.frames_too_old;
    }
  }
  process();
  return withWarning(Status::Ok());
}

void Estimator::Impl::process() {
  while (!base_frames.empty()) {
    const TagFrame& frame = base_frames.front();
    const TimeNs t = frame.stamp_ns + timeOffsetNs(0);
    if (imu.empty() || imu.back().stamp_ns < t) return;  // wait for the IMU to pass t
    // and, for the cubic through the readings around t (readingIn), for the one after that
    // unless a gap follows t.
    const std::size_t n = imu.size();
    if (n > 1 && imu[n - 2].stamp_ns < t &&
        imu.back().stamp_ns - imu[n - 2].stamp_ns <= integrationIntervalNs(0))
      return;
    if (imu.front().stamp_ns > t || (!states.empty() && t <= states.back()->t)) {
      ++counters.frames_too_old;
      base_frames.pop_front();
      continue;
    }
    // A state right after the last one (cam0's time offset moved by about a frame period since
    // it was placed) would make an IMU factor over a fraction of a reading period, whose
    // information is near-singular and swamps the solve.
    if (!states.empty() && t - states.back()->t < kMinStateIntervalNs) {
      ++counters.frames_too_close;
      base_frames.pop_front();
      continue;
    }
    TagFrame taken = std::move(base_frames.front());
    base_frames.pop_front();
    if (!initialized) {
      addInitFrame(std::move(taken), t);
    } else {
      const auto start = Clock::now();
      addState(taken, t);
      attachOtherFrames();
      extendAux();
      SolveSummary summary;
      if (++frames_since_solve >= options.solve_every) {
        checkObservability();  // holds what the motion cannot observe before solving
        summary = solve(options.max_iterations);
        frames_since_solve = 0;
      } else {
        summary = windowSummary();  // the new state as the IMU predicted it
        summary.usable = true;
      }
      if (static_cast<int>(states.size()) > options.window_size) marginalizeOldest();
      publish(summary, start);
    }
    trimBuffers();
  }
}

ImuMeasurement Estimator::Impl::readingAt(TimeNs t) const {
  return readingIn(imu, t, integrationIntervalNs(0));
}

std::vector<ImuMeasurement> Estimator::Impl::imuBetween(TimeNs a, TimeNs b) const {
  return readingsBetween(imu, a, b);
}

std::vector<ImuMeasurement> Estimator::Impl::imuToIntegrate(TimeNs a, TimeNs b) const {
  return readingsBetween(imu, a, b, fromSeconds(options.imu_integration_step_s),
                         integrationIntervalNs(0));
}

TimeNs Estimator::Impl::integrationIntervalNs(std::size_t sensor) const {
  const double rate = rig.inertial[sensor].update_rate;
  if (!(options.imu_integration_step_s > 0.0) || !(rate > 0.0)) return 0;
  return fromSeconds(2.5 / rate);
}

std::shared_ptr<ImuPreintegration> Estimator::Impl::preintegrate(TimeNs a, TimeNs b,
                                                                 const Eigen::Vector3d& bg,
                                                                 const Eigen::Vector3d& ba,
                                                                 bool corrected) const {
  auto pre = std::make_shared<ImuPreintegration>(rig.inertial[0].noise, bg, ba, maxImuInterval());
  for (const auto& m : imuToIntegrate(a, b)) pre->add(corrected ? propagationReading(m) : m);
  return pre;
}

bool Estimator::Impl::insideImuGap(TimeNs t) const {
  const double max_interval = maxImuInterval();
  if (max_interval <= 0.0 || imu.empty()) return false;
  auto after = std::lower_bound(imu.begin(), imu.end(), t,
                                [](const ImuMeasurement& m, TimeNs s) { return m.stamp_ns < s; });
  if (after == imu.end() || after == imu.begin()) return false;
  return toSeconds(after->stamp_ns - std::prev(after)->stamp_ns) > max_interval;
}

double Estimator::Impl::maxImuInterval() const {
  const double rate = rig.inertial[0].update_rate;
  return rate > 0.0 ? 2.5 / rate : 0.0;
}

void Estimator::Impl::trimBuffers() {
  // IMU readings are needed from the newest state on (or the first initialization frame).
  TimeNs keep_from = std::numeric_limits<TimeNs>::max();
  if (!states.empty()) keep_from = states.back()->t;
  if (!init.empty()) keep_from = std::min(keep_from, init.front().t);
  if (!initialized && !imu.empty()) {
    // Clock alignment looks up to kAlignRange around 2 * kAlignSpanNs of board poses.
    keep_from = std::min(keep_from, imu.back().stamp_ns - 2 * kAlignSpanNs - kNsPerSecond);
  }
  if (keep_from == std::numeric_limits<TimeNs>::max()) {
    // Nothing to anchor to: keep two seconds.
    if (!imu.empty()) keep_from = imu.back().stamp_ns - 2 * kNsPerSecond;
  }
  keep_from -= fromSeconds(0.05);
  while (imu.size() > 2 && imu[1].stamp_ns < keep_from) imu.pop_front();
  trimAuxBuffers();
}

void Estimator::Impl::resetAll() {
  newProblem();
  states.clear();
  imu.clear();
  base_frames.clear();
  for (auto& q : other_frames) q.clear();
  init.clear();
  for (auto& h : board_rotations) h.clear();
  std::fill(pose_tag.begin(), pose_tag.end(), -1);
  for (auto& a : aux) {
    a->readings.clear();
    a->last = std::numeric_limits<TimeNs>::min();
    a->stopped = false;
  }
  warning.clear();
  unobservable.clear();
  uninformative.clear();
  motion_information.clear();
  for (auto& m : reading_moments) m.clear();
  holds.clear();  // after newProblem(): the old problem no longer uses their manifolds
  clocks_aligned = false;
  initialized = false;
  last_imu = std::numeric_limits<TimeNs>::min();
  std::fill(last_frame.begin(), last_frame.end(), std::numeric_limits<TimeNs>::min());
  status_text = "reset: waiting for data";
}

Rig Estimator::Impl::calibration() const {
  Rig out = rig;
  for (std::size_t c = 0; c < cameras.size(); ++c) {
    const CameraBlocks& cb = *cameras[c];
    Camera& cam = out.cameras[c];
    cam.T_cam_imu = poseToSE3(cb.extrinsic);
    cam.timeshift_cam_imu = cb.time_offset[0];
    cam.intrinsics = Eigen::Vector4d(cb.intrinsics);
    cam.distortion_coeffs = Eigen::Vector4d(cb.intrinsics + 4);
    if (camera_std) cam.std = (*camera_std)[c];
  }
  for (const auto& a : aux) {
    InertialSensor& s = out.inertial[a->sensor];
    if (a->gyro) {
      s.T_i_b.q = Eigen::Quaterniond(poseRotation(a->rotation)).normalized();
    } else {
      s.T_i_b = poseToSE3(a->extrinsic);
    }
    s.time_offset = a->time_offset[0];
    if (a->std) {
      // Keep what the configuration says of the intrinsics' uncertainty.
      InertialCalibrationStd sd = s.std ? *s.std : InertialCalibrationStd{};
      sd.rotation = a->std->rotation;
      sd.translation = a->std->translation;
      sd.time_offset = a->std->time_offset;
      s.std = sd;
    }
  }
  writeImuIntrinsics(&out);
  return out;
}

Estimator::Estimator(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Estimator::~Estimator() = default;

StatusOr<std::unique_ptr<Estimator>> Estimator::create(const Rig& rig,
                                                       const EstimatorOptions& options) {
  Status valid = validate(options);
  if (!valid.ok()) return valid;
  if (rig.inertial.empty()) return Status::Error("the rig has no base IMU");
  if (rig.cameras.empty()) return Status::Error("the rig has no camera");
  Status holds_valid = validateHolds(rig, options.hold);
  if (!holds_valid.ok()) return holds_valid;
  for (const auto& sensor : rig.inertial) {
    if (sensor.type == InertialType::kGyroscope && !sensor.intrinsics.Tg.isZero(0.0)) {
      return Status::Error(sensor.name +
                           ": Tg (gravity sensitivity) of a gyroscope is not supported: it has "
                           "no accelerometer to read the specific force with; set it to zero");
    }
  }
  if (options.estimate_imu_intrinsics && options.aux_imu_model == AuxImuModel::kRigidVelocity) {
    return Status::Error(
        "estimator options: estimate_imu_intrinsics needs aux_imu_model velocity_state (the "
        "rigid-velocity model reads the aux gyroscope uncorrected)");
  }
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
Rig Estimator::calibration() const { return impl_->calibration(); }
Status Estimator::computeCovariance() { return impl_->covariance(nullptr); }
std::vector<EstimatorState> Estimator::trajectory() const {
  std::vector<EstimatorState> out = impl_->past;
  for (const auto& s : impl_->states) out.push_back(s->toEstimate());
  return out;
}
std::string Estimator::status() const { return impl_->status_text; }
bool Estimator::initialized() const { return impl_->initialized; }
std::map<int, std::array<Eigen::Vector3d, 4>> Estimator::landmarks() const {
  std::map<int, std::array<Eigen::Vector3d, 4>> out;
  for (const auto& [id, landmark] : impl_->landmarks) {
    for (int k = 0; k < 4; ++k) out[id][k] = Eigen::Vector3d(landmark->x + 3 * k);
  }
  return out;
}
const EstimatorCounters& Estimator::counters() const { return impl_->counters; }
void Estimator::reset() {
  impl_->resetAll();
  ++impl_->counters.resets;
}

}  // namespace mvis
