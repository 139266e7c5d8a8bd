#include "estimator_impl.h"

namespace mvis {

Camera Estimator::Impl::currentCamera(std::size_t c) const {
  Camera current = rig.cameras[c];
  const CameraBlocks& cb = *cameras[c];
  current.intrinsics = Eigen::Vector4d(cb.intrinsics);
  current.distortion_coeffs = Eigen::Vector4d(cb.intrinsics + 4);
  return current;
}

bool Estimator::Impl::boardPose(const TagFrame& frame, SE3* T_G_C) {
  if (landmarkMode()) return poseOnTag(frame, T_G_C);
  return mvis::boardPose(currentCamera(frame.camera), *rig.target, frame, options.min_tags, T_G_C);
}

void Estimator::Impl::addInitFrame(TagFrame frame, TimeNs t) {
  SE3 T_G_C;
  if (!boardPose(frame, &T_G_C)) {
    init.clear();
    status_text = "initializing: " + rig.cameras[0].name +
                  (landmarkMode() ? " sees no tag" : " sees too little of the board");
    return;
  }
  recordBoardRotation(0, frame.stamp_ns, T_G_C);
  // Consecutive frames only: a gap of more than 0.25 s starts over.
  if (!init.empty() && t - init.back().t > fromSeconds(0.25)) init.clear();
  if (landmarkMode()) {
    // One tag's rotation is ambiguous (a mirrored pose fits about as well) but not its centre:
    // keep the centre in the camera frame, in tag sides; initialize() takes the rotations from
    // the gyroscope.
    init.push_back({t, SE3(), std::move(frame), T_G_C.inverse() * tagCorner(2, 0.5)});
  } else {
    init.push_back({t, T_G_C * poseToSE3(cameras[0]->extrinsic), std::move(frame)});
  }
  std::ostringstream s;
  s << "initializing: " << init.size() << " of " << options.init_frames << " "
    << rig.cameras[0].name << " frames with a "
    << (landmarkMode() ? "pose on tag " + std::to_string(pose_tag[0]) : "board pose");
  status_text = s.str();
  if (static_cast<int>(init.size()) < options.init_frames) return;
  if (!clocks_aligned) {
    const auto& h = board_rotations[0];
    if (h.size() < 2 || h.back().first - h.front().first < kAlignSpanNs) {
      status_text += "; collecting 1.5 s of board poses to check the camera clocks";
      return;
    }
    alignClocks();
    clocks_aligned = true;
  }
  // Without a board the first batch must also place every tag and tell the extrinsics'
  // translations from where the tags are: it waits for more motion.
  if (landmarkMode() && !init.empty() && init.back().t - init.front().t < kLandmarkBatchNs) {
    std::ostringstream wait;
    wait << "; collecting " << toSeconds(kLandmarkBatchNs) << " s of motion to place the tags";
    status_text += wait.str();
    return;
  }
  // A corrected cam0 clock moves the states later than the readings may reach yet: the next
  // frame comes when they do.
  if (init.empty() || imu.back().stamp_ns < init.back().t) return;
  initialize();
}

static constexpr TimeNs kAlignSpanNs = 1500000000;  // 1.5 s of board poses
static constexpr double kAlignRange = 0.3;          // [s]

void Estimator::Impl::recordBoardRotation(std::size_t c, TimeNs stamp, const SE3& T_G_C) {
  auto& h = board_rotations[c];
  if (!h.empty() && stamp <= h.back().first) return;
  h.emplace_back(stamp, T_G_C.rotation());
  while (h.size() > 2 && h.back().first - h.front().first > 2 * kAlignSpanNs) h.pop_front();
}

double Estimator::Impl::clockCorrection(std::size_t c) const {
  if (imu.size() < 2) return 0.0;
  const Eigen::Matrix3d R_I_C = poseToSE3(cameras[c]->extrinsic).rotation().transpose();
  return mvis::clockCorrection(
      board_rotations[c], R_I_C, timeOffsetNs(c), imu.front().stamp_ns, imu.back().stamp_ns,
      [this](TimeNs t) { return readingAt(t).gyro; }, kAlignRange);
}

void Estimator::Impl::alignClocks() {
  std::ostringstream said;
  for (std::size_t c = 0; c < cameras.size(); ++c) {
    const double delta = clockCorrection(c);
    if (std::abs(delta) < 0.002) continue;  // within what the estimator refines anyway
    cameras[c]->time_offset[0] += delta;
    said << " " << rig.cameras[c].name << " " << (delta > 0 ? "+" : "") << delta * 1e3 << " ms";
    if (c == 0) {
      // The window states sit at cam0's frames: move them with its clock.
      for (auto& f : init) f.t = f.frame.stamp_ns + timeOffsetNs(0);
      if (!imu.empty() && init.front().t < imu.front().stamp_ns) init.clear();
    }
  }
  if (!said.str().empty()) {
    ++counters.clock_corrections;
    clock_message = "time offsets corrected from the gyroscope:" + said.str();
  }
}

void Estimator::Impl::initialize() {
  const std::size_t n = init.size();
  // Gravity and velocities from the board poses and the readings between them.
  std::vector<std::shared_ptr<ImuPreintegration>> pre;
  std::vector<const ImuPreintegration*> pre_ptrs;
  std::vector<TimeNs> times;
  std::vector<SE3> poses;
  for (std::size_t i = 0; i < n; ++i) {
    times.push_back(init[i].t);
    if (i + 1 < n) {
      pre.push_back(
          preintegrate(init[i].t, init[i + 1].t, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()));
      pre_ptrs.push_back(pre.back().get());
    }
  }
  // Without a board: base rotations from the gyroscope (R_G_I,0 = I), the IMU at
  //   p_G_I,i = -s R_G_C,i c_i - R_G_I,i t_I_C
  // with c_i the pose tag's centre in cam0's frame in sides and s the side; the world's origin at
  // the tag's centre until the alignment below moves it.
  std::vector<Eigen::Vector3d> scaled;
  const SE3 T_I_C = poseToSE3(cameras[0]->extrinsic).inverse();
  for (std::size_t i = 0; i < n; ++i) {
    if (!landmarkMode()) {
      poses.push_back(init[i].T_G_I);
      continue;
    }
    const Eigen::Quaterniond q =
        i == 0 ? Eigen::Quaterniond::Identity() : (poses.back().q * pre[i - 1]->deltaR());
    poses.push_back(SE3(q.normalized(), -(q * T_I_C.p)));
    scaled.push_back(-(q * (T_I_C.q * init[i].scaled)));
  }
  const GravityAlignment aligned =
      alignGravity(times, poses, pre_ptrs, landmarkMode() ? &scaled : nullptr);
  Eigen::Vector3d g = aligned.gravity;
  const bool bad_gravity =
      !g.allFinite() || std::abs(g.norm() - options.gravity_m_s2) > 0.3 * options.gravity_m_s2;
  // Without a board the tag's side comes out of the same fit: printed tags are 1 cm to 5 m.
  const bool bad_scale = !(aligned.scale > 0.01 && aligned.scale < 5.0);
  if (bad_gravity || bad_scale) {
    std::ostringstream s;
    s << "initializing: ";
    if (bad_gravity) {
      s << "gravity from the first " << n << " frames came out as " << g.norm()
        << " m/s^2 (camera extrinsic or time offset far off, or IMU units wrong?)";
    } else {
      s << "the side of tag " << pose_tag[0] << " came out as " << aligned.scale
        << " m from the first " << n << " frames (too little acceleration to tell it)";
    }
    s << "; retrying";
    status_text = s.str();
    init.erase(init.begin(), init.begin() + n / 2);
    return;
  }
  std::vector<Eigen::Vector3d> velocities = aligned.velocities;
  if (landmarkMode()) {
    // The world frame: gravity along -z, origin and heading at the first state.
    const Eigen::Quaterniond R_align =
        Eigen::Quaterniond::FromTwoVectors(g, -Eigen::Vector3d::UnitZ());
    const Eigen::Vector3d p0 = poses[0].p + aligned.scale * scaled[0];
    for (std::size_t i = 0; i < n; ++i) {
      init[i].T_G_I =
          SE3(R_align * poses[i].q, R_align * (poses[i].p + aligned.scale * scaled[i] - p0));
      velocities[i] = R_align * velocities[i];
    }
    g = R_align * g;
    initial_tag_side = aligned.scale;
  }
  g *= options.gravity_m_s2 / g.norm();
  Eigen::Map<Eigen::Vector3d>{gravity} = g;

  newProblem();
  states.clear();
  addCalibrationBlocks();
  for (std::size_t i = 0; i < n; ++i) {
    auto s = makeState(init[i].t);
    se3ToPose(init[i].T_G_I, s->pose);
    Eigen::Map<Eigen::Vector3d>(s->speed_bias) = velocities[i];
    std::fill(s->speed_bias + 3, s->speed_bias + 9, 0.0);
    states.push_back(std::move(s));
    addStateBlocks(states.back().get());
  }
  // A weak prior on the first state's velocity and biases fixes what the first seconds
  // cannot see.
  Eigen::Matrix<double, 9, 9> A_prior = Eigen::Matrix<double, 9, 9>::Zero();
  for (int i = 0; i < 3; ++i) {
    A_prior(i, i) = 1.0 / options.velocity_prior;
    A_prior(3 + i, 3 + i) = 1.0 / options.bias_gyro_prior;
    A_prior(6 + i, 6 + i) = 1.0 / options.bias_accel_prior;
  }
  const Eigen::VectorXd b_prior =
      Eigen::Map<const Eigen::Matrix<double, 9, 1>>(states.front()->speed_bias);
  addRecord(states.front().get(), new ceres::NormalPrior(A_prior, b_prior), nullptr,
            {states.front()->speed_bias});
  if (landmarkMode()) {
    // Nothing else fixes the world frame (gravity is a free direction): the first state's pose
    // is it.
    addRecord(states.front().get(),
              PosePriorFactor::fromStd(poseToSE3(states.front()->pose),
                                       Eigen::Vector3d::Constant(kGaugeStd),
                                       Eigen::Vector3d::Constant(kGaugeStd)),
              nullptr, {states.front()->pose});
  }
  // The states' biases start at zero, the preintegrations' linearization point above.
  for (std::size_t i = 0; i + 1 < n; ++i) {
    addImuFactor(i, pre[i]);
    addMotionInformation(states[i]->t, states[i + 1]->t, Eigen::Vector3d::Zero());
  }
  for (std::size_t i = 0; i < n; ++i) addFrame(init[i].frame, i);
  init.clear();
  attachOtherFrames();
  initialized = true;  // auxiliary sensors join the window from here on
  extendAux();
  // The first batch settles the states; the auxiliary sensors' calibration and the cameras' and
  // IMUs' intrinsics wait for the window (and its observability check): one short window cannot
  // tell much about them, and what it cannot observe would move on linearization noise alone.
  // (Free camera intrinsics in the batch once settled every extrinsic 0.6 deg and 10 mm off,
  // and the marginalization prior kept it there.)
  std::vector<double*> held_for_batch;
  std::vector<double*> batch_blocks;
  for (auto& a : aux) {
    batch_blocks.push_back(a->extrinsicBlock());
    batch_blocks.push_back(a->time_offset);
  }
  for (auto& cb : cameras) batch_blocks.push_back(cb->intrinsics);
  for (auto& b : imu_intrinsics) {
    if (b) batch_blocks.push_back(b->x);
  }
  for (double* b : batch_blocks) {
    if (!problem->IsParameterBlockConstant(b)) {
      problem->SetParameterBlockConstant(b);
      held_for_batch.push_back(b);
    }
  }
  std::vector<SE3> configured;
  for (auto& cb : cameras) configured.push_back(poseToSE3(cb->extrinsic));
  const auto start = Clock::now();
  const int batch_iterations = std::max(30, options.max_iterations);
  SolveSummary summary = solve(batch_iterations, options.init_solve_time_s);
  // What the batch's motion cannot observe, held from here on (the window checks before every
  // solve; holding it in this first solve already would hold each camera at its own configured
  // value, and those disagree with what the board shows of their relative positions).
  checkObservability();
  if (recentreUnobservedShift(configured)) {
    const SolveSummary again = solve(batch_iterations, options.init_solve_time_s);
    summary.iterations += again.iterations;
    summary.solve_s += again.solve_s;
    summary.cost = again.cost;
    summary.usable = again.usable;
  }
  for (double* b : held_for_batch) problem->SetParameterBlockVariable(b);
  status_text = clock_message.empty() ? "running" : "running; " + clock_message;
  while (static_cast<int>(states.size()) > options.window_size) marginalizeOldest();
  publish(summary, start);
}

bool Estimator::Impl::recentreUnobservedShift(const std::vector<SE3>& configured) {
  // Rotating about one axis (or not at all), the cameras' translations can all move together
  // along the axis (or anyhow) against imu0 without any reading changing: one common shift of
  // their positions in {I}, which the check holds per camera. The batch leaves that shift
  // wherever its linearization took it (12-15 cm counting every corner on a yaw-only start, 3 cm
  // at the default), and the window would keep it there. It goes back to the configured cameras'
  // mean; where they sit relative to each other, which the board does show, stays as solved.
  Eigen::MatrixXd A;  // the held directions of the cameras' positions in {I} (orthonormal)
  std::vector<std::size_t> held;
  for (std::size_t c = 0; c < cameras.size(); ++c) {
    const auto u = uninformative.find(cameras[c]->extrinsic);
    if (u == uninformative.end()) continue;
    // Translation rows of the held directions (p_C_I in {C}) turned to {I}.
    const Eigen::MatrixXd D = poseRotation(cameras[c]->extrinsic).toRotationMatrix().transpose() *
                              u->second.bottomRows<3>();
    if (D.cols() == 0 || D.colwise().norm().minCoeff() < 0.99) continue;  // not translations
    if (A.size() == 0) A = D;
    held.push_back(c);
  }
  if (held.empty()) return false;
  Eigen::VectorXd shift = Eigen::VectorXd::Zero(A.cols());
  for (std::size_t c : held) {
    const SE3 T = poseToSE3(cameras[c]->extrinsic);
    const Eigen::Vector3d p_I_C = -(T.q.conjugate() * T.p);
    const Eigen::Vector3d p_I_C0 = -(configured[c].q.conjugate() * configured[c].p);
    shift += A.transpose() * (p_I_C - p_I_C0) / static_cast<double>(held.size());
  }
  for (std::size_t c : held) {
    double* e = cameras[c]->extrinsic;
    Eigen::Map<Eigen::Vector3d>(e + 4) += poseRotation(e) * (A * shift);
  }
  return true;
}

}  // namespace mvis
