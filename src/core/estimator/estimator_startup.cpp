// The estimator's initialization: cam0's first frames with a pose, gravity and velocities from
// them (initialization.h), the window built from them and solved as a batch.
#include <ceres/normal_prior.h>

#include <algorithm>
#include <set>
#include <sstream>

#include "estimator_impl.h"
#include "mvis/estimator/initialization.h"
#include "mvis/factors/pose_prior_factor.h"

namespace mvis {

using estimator_internal::State;

namespace {

// Without a board the first state's pose defines the world frame: a prior this tight [rad, m].
constexpr double kGaugeStd = 1e-6;

}  // namespace

bool Estimator::Impl::boardPose(const TagFrame& frame, SE3* T_G_C) {
  const Camera camera = calibration.currentCamera(frame.camera);
  if (rig.target) return mvis::boardPose(camera, *rig.target, frame, options.min_tags, T_G_C);
  bool restarted = false;
  const bool ok = landmarks.poseOnTag(camera, frame, T_G_C, &restarted);
  if (restarted) startup.restartCamera(frame.camera);
  return ok;
}

void Estimator::Impl::addInitFrame(TagFrame frame, TimeNs t) {
  SE3 T_G_C;
  if (!boardPose(frame, &T_G_C)) {
    startup.noPose();
    status_text = "initializing: " + rig.cameras[0].name +
                  (!rig.target ? " sees no tag" : " sees too little of the board");
    return;
  }
  if (startup.add(std::move(frame), t, T_G_C, landmarks.poseTag(0), &status_text)) initialize();
}

void Estimator::Impl::initialize() {
  auto& init = startup.frames();
  const bool landmark_mode = !rig.target;
  const std::size_t n = init.size();
  // Gravity and velocities from the board poses and the readings between them.
  std::vector<std::shared_ptr<ImuPreintegration>> pre;
  std::vector<const ImuPreintegration*> pre_ptrs;
  std::vector<TimeNs> times;
  std::vector<SE3> poses;
  for (std::size_t i = 0; i < n; ++i) {
    times.push_back(init[i].t);
    if (i + 1 < n) {
      pre.push_back(imu.preintegrate(init[i].t, init[i + 1].t, Eigen::Vector3d::Zero(),
                                     Eigen::Vector3d::Zero()));
      pre_ptrs.push_back(pre.back().get());
    }
  }
  // Without a board: base rotations from the gyroscope (R_G_I,0 = I), the IMU at
  //   p_G_I,i = -s R_G_C,i c_i - R_G_I,i t_I_C
  // with c_i the pose tag's centre in cam0's frame in sides and s the side; the world's origin at
  // the tag's centre until the alignment below moves it.
  std::vector<Eigen::Vector3d> scaled;
  const SE3 T_I_C = poseToSE3(calibration.camera(0).extrinsic).inverse();
  for (std::size_t i = 0; i < n; ++i) {
    if (!landmark_mode) {
      poses.push_back(init[i].T_G_I);
      continue;
    }
    const Eigen::Quaterniond q =
        i == 0 ? Eigen::Quaterniond::Identity() : (poses.back().q * pre[i - 1]->deltaR());
    poses.push_back(SE3(q.normalized(), -(q * T_I_C.p)));
    scaled.push_back(-(q * (T_I_C.q * init[i].scaled)));
  }
  const GravityAlignment aligned =
      alignGravity(times, poses, pre_ptrs, landmark_mode ? &scaled : nullptr);
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
      s << "the side of tag " << landmarks.poseTag(0) << " came out as " << aligned.scale
        << " m from the first " << n << " frames (too little acceleration to tell it)";
    }
    s << "; retrying";
    status_text = s.str();
    startup.dropOlderHalf();
    return;
  }
  std::vector<Eigen::Vector3d> velocities = aligned.velocities;
  if (landmark_mode) {
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
    landmarks.setInitialSide(aligned.scale);
  }
  g *= options.gravity_m_s2 / g.norm();
  Eigen::Map<Eigen::Vector3d>{calibration.gravity()} = g;

  newProblem();
  calibration.addTo(window.problem(), trusted);
  intrinsics.addTo(window.problem(), trusted);
  // A batch's starting calibration (the priors, made above, stay the configured ones).
  applyStart();
  std::vector<double*> trusted_blocks;
  if (ceres::CostFunction* prior = trusted.jointPrior(&trusted_blocks)) {
    joint_prior_id = window.problem()->AddResidualBlock(prior, nullptr, trusted_blocks);
  }
  for (std::size_t i = 0; i < n; ++i) {
    auto s = makeState(init[i].t);
    addTimeOffsetInformation(init[i].t);
    se3ToPose(init[i].T_G_I, s->pose);
    Eigen::Map<Eigen::Vector3d>(s->speed_bias) = velocities[i];
    std::fill(s->speed_bias + 3, s->speed_bias + 9, 0.0);
    window.push(std::move(s));
  }
  State& first = window.state(0);
  // A weak prior on the first state's velocity and biases fixes what the first seconds
  // cannot see.
  Eigen::Matrix<double, 9, 9> A_prior = Eigen::Matrix<double, 9, 9>::Zero();
  for (int i = 0; i < 3; ++i) {
    A_prior(i, i) = 1.0 / options.velocity_prior;
    A_prior(3 + i, 3 + i) = 1.0 / options.bias_gyro_prior;
    A_prior(6 + i, 6 + i) = 1.0 / options.bias_accel_prior;
  }
  const Eigen::VectorXd b_prior = Eigen::Map<const Eigen::Matrix<double, 9, 1>>(first.speed_bias);
  window.addRecord(&first, new ceres::NormalPrior(A_prior, b_prior), nullptr, {first.speed_bias});
  if (landmark_mode) {
    // Nothing else fixes the world frame (gravity is a free direction): the first state's pose
    // is it.
    window.addRecord(
        &first,
        PosePriorFactor::fromStd(poseToSE3(first.pose), Eigen::Vector3d::Constant(kGaugeStd),
                                 Eigen::Vector3d::Constant(kGaugeStd)),
        nullptr, {first.pose});
  }
  // The states' biases start at zero, the preintegrations' linearization point above.
  for (std::size_t i = 0; i + 1 < n; ++i) {
    addImuFactor(i, pre[i]);
    const TimeNs a = window.state(i).t, b = window.state(i + 1).t;
    monitor.addMotion(a, b, imu.between(a, b), Eigen::Vector3d::Zero(),
                      Eigen::Quaterniond(poseRotation(window.state(i).pose)),
                      Eigen::Vector3d(calibration.gravity()));
  }
  // Without a board the states the batch is cut to the window below take the carried tags'
  // corners only: the others' would enter the prior through them and tie every tag of the batch
  // into it (its dense part then had 36 or 100 tags instead of at most carried_tags, and the
  // batch cost most of a short run: 100 tags, 4 s, 11.6 s against 1.2 s). The window's states
  // keep every tag.
  if (landmark_mode && !options.batch && static_cast<int>(n) > options.window_size) {
    frames.carriedTagsOnlyBefore(n - static_cast<std::size_t>(options.window_size));
  }
  for (std::size_t i = 0; i < n; ++i) frames.add(init[i].frame, i, initialized);
  init.clear();
  frames.attachWaiting(initialized);
  frames.carriedTagsOnlyBefore(0);
  initialized = true;  // auxiliary sensors join the window from here on
  // They join after the batch (below): in the batch their calibration is held at its configured
  // value, and states fitted to it would keep its error in the prior. Without a board the first
  // state is the world frame, so every later pose kept it (imu1 5.6 deg off left the pose NEES
  // at 11, against 2.7 with it configured right). With a board the poses are seen against it
  // again, but the first states still carry it: the hand-held runs end slightly better without
  // them in the batch (ATE 1.0-2.1 mm against 1.4-2.6, calibration as good) and the batch, most
  // of a short run's cost with many of them, is cheaper (eight aux IMUs, 15 s: 5.5x against
  // 4.1-4.4x real time, ATE 2.6 against 5.2 mm). Not with every IMU's intrinsics estimated and a
  // board: there the same change left the cameras 0.1-0.2 deg off at 15 sigma (not understood
  // yet), so the auxiliary sensors stay in.
  std::vector<double*> imu_intrinsics;  // the estimated IMU intrinsics' blocks
  for (std::size_t i = 0; i < intrinsics.sensors(); ++i) {
    if (intrinsics.values(i) != nullptr) imu_intrinsics.push_back(intrinsics.values(i));
  }
  const bool aux_after_batch = landmark_mode || imu_intrinsics.empty();
  if (!aux_after_batch) aux.extend();
  // The first batch settles the states; the auxiliary sensors' calibration and the cameras' and
  // IMUs' intrinsics wait for the window (and its observability check): one short window cannot
  // tell much about them, and what it cannot observe would move on linearization noise alone.
  // (Free camera intrinsics in the batch once settled every extrinsic 0.6 deg and 10 mm off,
  // and the marginalization prior kept it there.)
  ceres::Problem* problem = window.problem();
  std::vector<double*> held_for_batch;
  // After a restart from a trusted calibration the batch settles the states only: ten frames
  // cannot improve that calibration, and a fault still going on (a camera clock drifting) would
  // pull it (a base-camera clock drifting by 0.5% left its time offset 4 sigma off).
  std::vector<double*> batch_blocks = calibration.batchHeldBlocks(trusted.fromCovariance());
  batch_blocks.insert(batch_blocks.end(), imu_intrinsics.begin(), imu_intrinsics.end());
  for (double* b : batch_blocks) {
    if (!problem->IsParameterBlockConstant(b)) {
      problem->SetParameterBlockConstant(b);
      held_for_batch.push_back(b);
    }
  }
  std::vector<SE3> configured;
  for (std::size_t c = 0; c < calibration.cameras(); ++c) {
    configured.push_back(poseToSE3(calibration.camera(c).extrinsic));
  }
  const auto start = Clock::now();
  const int batch_iterations = std::max(30, options.max_iterations);
  SolveSummary summary = solve(batch_iterations, options.init_solve_time_s);
  // What the batch's motion cannot observe, held from here on (the window checks before every
  // solve; holding it in this first solve already would hold each camera at its own configured
  // value, and those disagree with what the board shows of their relative positions).
  monitor.check(problem);
  const auto solveAgain = [&] {
    const SolveSummary again = solve(batch_iterations, options.init_solve_time_s);
    summary.iterations += again.iterations;
    summary.solve_s += again.solve_s;
    summary.cost = again.cost;
    summary.usable = again.usable;
  };
  if (recentreUnobservedShift(configured)) solveAgain();
  // Without a board the batch's clean frames then count as every later frame, per corner, and
  // it is solved once more from where the loss per frame took it, before its states leave into
  // the prior.
  if (frames.settleFirstBatch() > 0) solveAgain();
  // With the auxiliary sensors in the batch (every IMU's intrinsics estimated, a board) the
  // states were fitted to their configured calibration (2 deg and 5 ms off in the simulated
  // guess) and would enter the prior so: their calibration is freed and, when the batch's motion
  // observes all of it (the check holds none of it), the batch is solved once more before its
  // states leave; the IMUs' and cameras' intrinsics wait for the window, as said above. Without
  // it the cameras' rotations ended overconfident by about as much as their start was off (12
  // hand-held runs with every IMU's intrinsics: RMS error/sigma 1.15-1.20 from the simulated
  // guess, 1.07-1.12 from the truth, 1.03-1.08 in the batch over the recording; 24 runs: 1.20-1.23
  // before, 1.16-1.19 with it). Solved again on one-axis rotation, what those ten frames cannot
  // tell moved the cameras' tilt 0.5 deg. Not
  // after a restart from a trusted calibration (the batch settles the states only, above), nor
  // in a batch over the recording (no state leaves; it starts from the given calibration).
  if (!options.batch && !aux_after_batch && !trusted.fromCovariance()) {
    std::set<const double*> wait(imu_intrinsics.begin(), imu_intrinsics.end());
    for (std::size_t c = 0; c < calibration.cameras(); ++c) {
      wait.insert(calibration.camera(c).intrinsics);
    }
    std::vector<double*> freed;
    for (double* b : held_for_batch) {
      if (wait.count(b)) continue;
      problem->SetParameterBlockVariable(b);
      freed.push_back(b);
    }
    if (!freed.empty()) {
      monitor.check(problem);
      const bool observed = std::none_of(freed.begin(), freed.end(),
                                         [&](const double* b) { return monitor.holds(b); });
      if (observed) solveAgain();
    }
  }
  for (double* b : held_for_batch) {
    if (problem->IsParameterBlockConstant(b) && !monitor.holds(b)) {
      problem->SetParameterBlockVariable(b);
    }
  }
  const std::string& clock = startup.clockMessage();
  status_text = clock.empty() ? "running" : "running; " + clock;
  while (!options.batch && static_cast<int>(window.size()) > options.window_size) {
    // Without a board each intermediate prior is kept as information only: only the last one,
    // which the solves use, is factored (with a board each is, as before).
    marginalizeOldest(rig.target || static_cast<int>(window.size()) == options.window_size + 1);
  }
  if (aux_after_batch) aux.extend();  // after the batch (above)
  publish(summary, start);
}

bool Estimator::Impl::recentreUnobservedShift(const std::vector<SE3>& configured) {
  // Rotating about one axis (or not at all), the cameras' translations can all move together
  // along the axis (or anyhow) against imu0 without any reading changing: one common shift of
  // their positions in {I}, which the check holds per camera. The batch leaves that shift
  // wherever its linearization took it (12-15 cm counting every corner on a yaw-only start, 3 cm
  // at the default), and the window would keep it there. It goes back to the configured cameras'
  // mean; where they sit relative to each other, which the board does show, stays as solved.
  // The check holds the first camera's (and those whose distance trades with their focal
  // lengths), the others follow it: the shift is every estimated camera's.
  Eigen::MatrixXd A;  // the held directions of the cameras' positions in {I} (orthonormal)
  bool any = false;
  const auto& uninformative = monitor.uninformative();
  for (std::size_t c = 0; c < calibration.cameras(); ++c) {
    const double* extrinsic = calibration.camera(c).extrinsic;
    const auto u = uninformative.find(extrinsic);
    if (u == uninformative.end()) continue;
    // Translation rows of the held directions (p_C_I in {C}) turned to {I}.
    const Eigen::MatrixXd D =
        poseRotation(extrinsic).toRotationMatrix().transpose() * u->second.bottomRows<3>();
    if (D.cols() == 0 || D.colwise().norm().minCoeff() < 0.99) continue;  // not translations
    if (A.size() == 0) A = D;
    any = true;
  }
  if (!any) return false;
  std::vector<std::size_t> moved;  // every estimated camera
  for (std::size_t c = 0; c < calibration.cameras(); ++c) {
    if (monitor.estimated(*window.problem(), calibration.camera(c).extrinsic)) moved.push_back(c);
  }
  Eigen::VectorXd shift = Eigen::VectorXd::Zero(A.cols());
  for (std::size_t c : moved) {
    const SE3 T = poseToSE3(calibration.camera(c).extrinsic);
    const Eigen::Vector3d p_I_C = -(T.q.conjugate() * T.p);
    const Eigen::Vector3d p_I_C0 = -(configured[c].q.conjugate() * configured[c].p);
    shift += A.transpose() * (p_I_C - p_I_C0) / static_cast<double>(moved.size());
  }
  for (std::size_t c : moved) {
    double* e = calibration.camera(c).extrinsic;
    Eigen::Map<Eigen::Vector3d>(e + 4) += poseRotation(e) * (A * shift);
  }
  return true;
}

}  // namespace mvis
