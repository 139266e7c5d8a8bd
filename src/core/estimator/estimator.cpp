#include "mvis/estimator/estimator.h"

#include <ceres/ceres.h>
#include <ceres/normal_prior.h>
#include <ceres/sphere_manifold.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>
#include <limits>
#include <optional>
#include <sstream>

#include "mvis/camera/camera_model.h"
#include "mvis/estimator/initialization.h"
#include "mvis/estimator/state_blocks.h"
#include "mvis/factors/imu_factor.h"
#include "mvis/factors/marginalization_factor.h"
#include "mvis/factors/pose_prior_factor.h"
#include "mvis/factors/tag_reprojection_factor.h"

namespace mvis {
namespace {

using Clock = std::chrono::steady_clock;

struct ResidualRecord {
  ceres::ResidualBlockId id = nullptr;
  const ceres::CostFunction* cost = nullptr;
  const ceres::LossFunction* loss = nullptr;
  std::vector<double*> blocks;
};

// One window state. Its residual records are the factors whose oldest state it is: they are
// marginalized with it.
struct State {
  TimeNs t = 0;
  double pose[kPoseSize];
  double speed_bias[kSpeedBiasSize];
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();  // base gyroscope reading at t
  std::vector<ResidualRecord> residuals;
  int frames = 0, corners = 0;

  EstimatorState toEstimate() const {
    EstimatorState s;
    s.stamp_ns = t;
    s.T_G_I = poseToSE3(pose);
    s.v_G = Eigen::Vector3d(speed_bias);
    s.bias_gyro = Eigen::Vector3d(speed_bias + 3);
    s.bias_accel = Eigen::Vector3d(speed_bias + 6);
    return s;
  }
};

struct CameraBlocks {
  double extrinsic[kPoseSize];  // T_C_I
  double time_offset[1];        // [s]
  double intrinsics[kIntrinsicsSize];
};

struct InitFrame {
  TimeNs t = 0;  // base clock
  SE3 T_G_I;
  TagFrame frame;
};

double seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

}  // namespace

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
  if (o.init_frames < 3) return bad("init_frames", "must be at least 3");
  if (o.min_tags < 1) return bad("min_tags", "must be at least 1");
  if (!(o.gravity_m_s2 > 0.0)) return bad("gravity_m_s2", "must be positive");
  for (const auto& [key, v] : {std::pair<const char*, double>{"extrinsic_rotation_prior_rad",
                                                              o.extrinsic_rotation_prior_rad},
                               {"extrinsic_translation_prior_m", o.extrinsic_translation_prior_m},
                               {"time_offset_prior_s", o.time_offset_prior_s},
                               {"bias_gyro_prior", o.bias_gyro_prior},
                               {"bias_accel_prior", o.bias_accel_prior},
                               {"velocity_prior", o.velocity_prior}}) {
    if (!(v > 0.0)) return bad(key, "must be positive");
  }
  if (o.covariance_every < 0) return bad("covariance_every", "must be zero or positive");
  return Status::Ok();
}

struct Estimator::Impl {
  Rig rig;
  EstimatorOptions options;
  std::vector<std::unique_ptr<CameraBlocks>> cameras;
  double gravity[kGravitySize] = {0.0, 0.0, -9.81};
  PoseManifold pose_manifold;
  ceres::SphereManifold<3> sphere_manifold;
  std::unique_ptr<ceres::LossFunction> huber;
  std::unique_ptr<ceres::Problem> problem;
  std::deque<std::unique_ptr<State>> states;
  ResidualRecord prior;  // the marginalization prior, if any (prior.id != nullptr)
  std::deque<ImuMeasurement> imu;
  std::deque<TagFrame> base_frames;
  std::vector<std::deque<TagFrame>> other_frames;  // per camera (index 0 unused)
  std::vector<InitFrame> init;
  // Before initialization: board rotations R_G_C per camera (camera-clock stamps), for aligning
  // the clocks with the gyroscope.
  std::vector<std::deque<std::pair<TimeNs, Eigen::Matrix3d>>> board_rotations;
  bool clocks_aligned = false;
  std::vector<EstimatorState> past;
  UpdateCallback callback;
  PropagationCallback propagation_callback;
  std::shared_ptr<ImuPreintegration> propagation;  // from the newest state on
  TimeNs propagation_from = std::numeric_limits<TimeNs>::min();
  EstimatorCounters counters;
  bool initialized = false;
  std::string clock_message;  // what the clock alignment changed, if anything
  std::string status_text = "waiting for data";
  TimeNs last_imu = std::numeric_limits<TimeNs>::min();
  std::vector<TimeNs> last_frame;
  std::optional<std::vector<CameraCalibrationStd>> camera_std;
  int solves_since_covariance = 0;
  int frames_since_solve = 0;

  Impl(const Rig& r, const EstimatorOptions& o) : rig(r), options(o) {
    for (const auto& cam : rig.cameras) {
      auto blocks = std::make_unique<CameraBlocks>();
      se3ToPose(cam.T_cam_imu, blocks->extrinsic);
      blocks->time_offset[0] = cam.timeshift_cam_imu;
      for (int i = 0; i < 4; ++i) {
        blocks->intrinsics[i] = cam.intrinsics[i];
        blocks->intrinsics[4 + i] = cam.distortion_coeffs[i];
      }
      cameras.push_back(std::move(blocks));
    }
    if (options.huber_sigma > 0.0) huber = std::make_unique<ceres::HuberLoss>(options.huber_sigma);
    other_frames.resize(rig.cameras.size());
    board_rotations.resize(rig.cameras.size());
    last_frame.assign(rig.cameras.size(), std::numeric_limits<TimeNs>::min());
    newProblem();
  }

  void newProblem() {
    ceres::Problem::Options po;
    po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    po.enable_fast_removal = true;
    problem = std::make_unique<ceres::Problem>(po);
    prior = ResidualRecord{};
  }

  TimeNs timeOffsetNs(std::size_t c) const { return fromSeconds(cameras[c]->time_offset[0]); }

  // ---- data in ---------------------------------------------------------------------------

  Status addImu(std::size_t sensor, const ImuMeasurement& m) {
    if (sensor != 0) return Status::Ok();  // auxiliary sensors: not used yet
    if (!m.gyro.allFinite() || !m.accel.allFinite()) {
      ++counters.imu_non_finite;
      return Status::Error(rig.inertial[0].name + ": non-finite reading dropped");
    }
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
    return Status::Ok();
  }

  Status addTagFrame(const TagFrame& frame) {
    if (frame.camera >= rig.cameras.size()) return Status::Error("tag frame of an unknown camera");
    const std::string& name = rig.cameras[frame.camera].name;
    if (static_cast<int>(frame.tags.size()) < options.min_tags) {
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
    return Status::Ok();
  }

  // ---- the main loop ---------------------------------------------------------------------

  void process() {
    while (!base_frames.empty()) {
      const TagFrame& frame = base_frames.front();
      const TimeNs t = frame.stamp_ns + timeOffsetNs(0);
      if (imu.empty() || imu.back().stamp_ns < t) return;  // wait for the IMU to pass t
      if (imu.front().stamp_ns > t || (!states.empty() && t <= states.back()->t)) {
        ++counters.frames_too_old;
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
        SolveSummary summary;
        if (++frames_since_solve >= options.solve_every) {
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

  // The reading at t, interpolated between its neighbours (the nearest one outside the buffer).
  ImuMeasurement readingAt(TimeNs t) const {
    auto it = std::lower_bound(imu.begin(), imu.end(), t,
                               [](const ImuMeasurement& m, TimeNs s) { return m.stamp_ns < s; });
    if (it == imu.end()) return imu.back();
    if (it->stamp_ns == t || it == imu.begin()) return *it;
    return interpolateMeasurement(*(it - 1), *it, t);
  }

  // IMU readings over [a, b] with interpolated readings at both ends.
  std::vector<ImuMeasurement> imuBetween(TimeNs a, TimeNs b) const {
    std::vector<ImuMeasurement> out;
    out.push_back(readingAt(a));
    auto it = std::upper_bound(imu.begin(), imu.end(), a,
                               [](TimeNs s, const ImuMeasurement& m) { return s < m.stamp_ns; });
    for (; it != imu.end() && it->stamp_ns < b; ++it) out.push_back(*it);
    out.push_back(readingAt(b));
    return out;
  }

  std::shared_ptr<ImuPreintegration> preintegrate(TimeNs a, TimeNs b, const Eigen::Vector3d& bg,
                                                  const Eigen::Vector3d& ba) const {
    auto pre = std::make_shared<ImuPreintegration>(rig.inertial[0].noise, bg, ba, maxImuInterval());
    for (const auto& m : imuBetween(a, b)) pre->add(m);
    return pre;
  }

  // Whether t falls between two readings further apart than maxImuInterval().
  bool insideImuGap(TimeNs t) const {
    const double max_interval = maxImuInterval();
    if (max_interval <= 0.0 || imu.empty()) return false;
    auto after = std::lower_bound(imu.begin(), imu.end(), t,
                                  [](const ImuMeasurement& m, TimeNs s) { return m.stamp_ns < s; });
    if (after == imu.end() || after == imu.begin()) return false;
    return toSeconds(after->stamp_ns - std::prev(after)->stamp_ns) > max_interval;
  }

  // Readings further apart than this are a gap (2.5 nominal periods).
  double maxImuInterval() const {
    const double rate = rig.inertial[0].update_rate;
    return rate > 0.0 ? 2.5 / rate : 0.0;
  }

  Eigen::Vector3d gyroAt(TimeNs t) const { return readingAt(t).gyro; }

  void addRecord(State* owner, ceres::CostFunction* cost, ceres::LossFunction* loss,
                 std::vector<double*> blocks) {
    ResidualRecord r;
    r.id = problem->AddResidualBlock(cost, loss, blocks);
    r.cost = cost;
    r.loss = loss;
    r.blocks = std::move(blocks);
    owner->residuals.push_back(std::move(r));
  }

  void addStateBlocks(State* s) {
    problem->AddParameterBlock(s->pose, kPoseSize, &pose_manifold);
    problem->AddParameterBlock(s->speed_bias, kSpeedBiasSize);
  }

  void addCalibrationBlocks() {
    problem->AddParameterBlock(gravity, kGravitySize, &sphere_manifold);
    for (std::size_t c = 0; c < cameras.size(); ++c) {
      CameraBlocks& b = *cameras[c];
      problem->AddParameterBlock(b.extrinsic, kPoseSize, &pose_manifold);
      problem->AddParameterBlock(b.time_offset, 1);
      problem->AddParameterBlock(b.intrinsics, kIntrinsicsSize);
      if (!options.estimate_extrinsics) problem->SetParameterBlockConstant(b.extrinsic);
      if (!options.estimate_time_offsets) problem->SetParameterBlockConstant(b.time_offset);
      if (!options.estimate_intrinsics) problem->SetParameterBlockConstant(b.intrinsics);
      // Priors from the configuration's *_std keys, or the options' defaults.
      const Camera& cam = rig.cameras[c];
      Eigen::Vector3d rot = Eigen::Vector3d::Constant(options.extrinsic_rotation_prior_rad);
      Eigen::Vector3d pos = Eigen::Vector3d::Constant(options.extrinsic_translation_prior_m);
      double td = options.time_offset_prior_s;
      if (cam.std) {
        for (int i = 0; i < 3; ++i) {
          if (cam.std->rotation[i] > 0) rot[i] = cam.std->rotation[i];
          if (cam.std->translation[i] > 0) pos[i] = cam.std->translation[i];
        }
        if (cam.std->timeshift_cam_imu > 0) td = cam.std->timeshift_cam_imu;
      }
      problem->AddResidualBlock(PosePriorFactor::fromStd(poseToSE3(b.extrinsic), rot, pos), nullptr,
                                b.extrinsic);
      problem->AddResidualBlock(
          new ceres::NormalPrior(Eigen::Matrix<double, 1, 1>(1.0 / td),
                                 Eigen::Matrix<double, 1, 1>(b.time_offset[0])),
          nullptr, b.time_offset);
    }
  }

  ceres::CostFunction* frameFactor(const TagFrame& frame, std::size_t k, State** owner,
                                   std::vector<double*>* blocks, int* corners) {
    const std::size_t c = frame.camera;
    CameraBlocks& cb = *cameras[c];
    auto obs = boardCorners(frame, *rig.target);
    *corners = static_cast<int>(obs.size());
    if (obs.empty()) return nullptr;
    const DistortionModel model = rig.cameras[c].distortion_model;
    State* sk = states[k].get();
    *owner = sk;
    // The frame's pose comes from the readings around it: inside a gap they are made up.
    if (insideImuGap(frame.stamp_ns + timeOffsetNs(c))) {
      ++counters.frames_in_imu_gap;
      return nullptr;
    }
    if (options.interpolation == FrameInterpolation::kImu) {
      const TimeNs t_a = std::max(sk->t, frame.stamp_ns + timeOffsetNs(c));
      auto pre = preintegrate(sk->t, t_a, Eigen::Vector3d(sk->speed_bias + 3),
                              Eigen::Vector3d(sk->speed_bias + 6));
      const ImuMeasurement at = readingAt(t_a);
      const auto anchor = TagReprojectionFactor::makeAnchor(
          *pre, toSeconds(frame.stamp_ns - t_a), at.gyro, at.accel, angularAcceleration(t_a));
      *blocks = {sk->pose, sk->speed_bias, gravity, cb.extrinsic, cb.time_offset, cb.intrinsics};
      return TagReprojectionFactor::imuPropagated(model, std::move(obs), options.pixel_sigma_px,
                                                  anchor);
    }
    if (c == 0) {
      const double dt_nominal = toSeconds(frame.stamp_ns - sk->t);
      *blocks = {sk->pose, sk->speed_bias, cb.extrinsic, cb.time_offset, cb.intrinsics};
      return TagReprojectionFactor::kinematic(model, std::move(obs), options.pixel_sigma_px,
                                              dt_nominal, sk->gyro);
    }
    State* sk1 = states[k + 1].get();
    *blocks = {sk->pose, sk1->pose, cb.extrinsic, cb.time_offset, cb.intrinsics};
    return TagReprojectionFactor::poseBased(model, std::move(obs), options.pixel_sigma_px,
                                            toSeconds(frame.stamp_ns - sk->t),
                                            toSeconds(sk1->t - sk->t));
  }

  // Angular acceleration at t: slope of a line fitted to the gyroscope readings within 10 ms.
  Eigen::Vector3d angularAcceleration(TimeNs t) const {
    const TimeNs half = fromSeconds(0.01);
    double st = 0.0, stt = 0.0;
    Eigen::Vector3d sw = Eigen::Vector3d::Zero(), stw = Eigen::Vector3d::Zero();
    int n = 0;
    for (const auto& m : imu) {
      if (m.stamp_ns < t - half) continue;
      if (m.stamp_ns > t + half) break;
      const double x = toSeconds(m.stamp_ns - t);
      st += x;
      stt += x * x;
      sw += m.gyro;
      stw += x * m.gyro;
      ++n;
    }
    const double denominator = n * stt - st * st;
    if (n < 3 || denominator <= 0.0) return Eigen::Vector3d::Zero();
    return (n * stw - st * sw) / denominator;
  }

  void addFrame(const TagFrame& frame, std::size_t k) {
    State* owner = nullptr;
    std::vector<double*> blocks;
    int corners = 0;
    ceres::CostFunction* cost = frameFactor(frame, k, &owner, &blocks, &corners);
    if (cost == nullptr) return;
    addRecord(owner, cost, huber.get(), std::move(blocks));
    owner->frames += 1;
    owner->corners += corners;
  }

  void addImuFactor(std::size_t k) {
    State* a = states[k].get();
    State* b = states[k + 1].get();
    auto pre = preintegrate(a->t, b->t, Eigen::Vector3d(a->speed_bias + 3),
                            Eigen::Vector3d(a->speed_bias + 6));
    addRecord(a, new ImuFactor(pre), nullptr,
              {a->pose, a->speed_bias, b->pose, b->speed_bias, gravity});
  }

  void addState(const TagFrame& frame, TimeNs t) {
    const State& last = *states.back();
    const Eigen::Vector3d bg(last.speed_bias + 3), ba(last.speed_bias + 6);
    auto pre = preintegrate(last.t, t, bg, ba);
    auto s = std::make_unique<State>();
    s->t = t;
    s->gyro = gyroAt(t);
    Eigen::Quaterniond q;
    Eigen::Vector3d p, v;
    pre->predict(poseRotation(last.pose), posePosition(last.pose), Eigen::Vector3d(last.speed_bias),
                 Eigen::Vector3d(gravity), &q, &p, &v);
    se3ToPose(SE3(q, p), s->pose);
    Eigen::Map<Eigen::Vector3d>(s->speed_bias) = v;
    std::copy(last.speed_bias + 3, last.speed_bias + 9, s->speed_bias + 3);
    states.push_back(std::move(s));
    addStateBlocks(states.back().get());
    addRecord(states[states.size() - 2].get(), new ImuFactor(pre), nullptr,
              {states[states.size() - 2]->pose, states[states.size() - 2]->speed_bias,
               states.back()->pose, states.back()->speed_bias, gravity});
    addFrame(frame, states.size() - 1);
  }

  // Places every waiting frame of the other cameras that falls inside the window.
  void attachOtherFrames() {
    if (states.size() < 2) return;
    for (std::size_t c = 1; c < other_frames.size(); ++c) {
      auto& q = other_frames[c];
      const TimeNs offset = timeOffsetNs(c);
      while (!q.empty()) {
        const TimeNs t = q.front().stamp_ns + offset;
        if (t < states.front()->t) {
          ++counters.frames_too_old;
          q.pop_front();
          continue;
        }
        if (t > states.back()->t) break;
        std::size_t k = 0;
        while (k + 2 < states.size() && states[k + 1]->t <= t) ++k;
        addFrame(q.front(), k);
        q.pop_front();
      }
    }
  }

  // ---- initialization --------------------------------------------------------------------

  // The camera's board pose with its current intrinsics.
  bool boardPose(const TagFrame& frame, SE3* T_G_C) const {
    Camera current = rig.cameras[frame.camera];
    const CameraBlocks& cb = *cameras[frame.camera];
    current.intrinsics = Eigen::Vector4d(cb.intrinsics);
    current.distortion_coeffs = Eigen::Vector4d(cb.intrinsics + 4);
    return mvis::boardPose(current, *rig.target, frame, options.min_tags, T_G_C);
  }

  void addInitFrame(TagFrame frame, TimeNs t) {
    SE3 T_G_C;
    if (!boardPose(frame, &T_G_C)) {
      init.clear();
      status_text = "initializing: " + rig.cameras[0].name + " sees too little of the board";
      return;
    }
    recordBoardRotation(0, frame.stamp_ns, T_G_C);
    // Consecutive frames only: a gap of more than 0.25 s starts over.
    if (!init.empty() && t - init.back().t > fromSeconds(0.25)) init.clear();
    init.push_back({t, T_G_C * poseToSE3(cameras[0]->extrinsic), std::move(frame)});
    std::ostringstream s;
    s << "initializing: " << init.size() << " of " << options.init_frames << " "
      << rig.cameras[0].name << " frames with a board pose";
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
    // A corrected cam0 clock moves the states later than the readings may reach yet: the next
    // frame comes when they do.
    if (init.empty() || imu.back().stamp_ns < init.back().t) return;
    initialize();
  }

  // ---- clock alignment -------------------------------------------------------------------
  // A camera's time offset may be far off (a driver stamping on arrival, another clock). Before
  // initializing, each camera's angular velocity from consecutive board poses, rotated into the
  // IMU frame with the extrinsic guess, is matched against the gyroscope over offsets within
  // +-kAlignRange; a clear best match replaces the configured offset.
  static constexpr TimeNs kAlignSpanNs = 1500000000;  // 1.5 s of board poses
  static constexpr double kAlignRange = 0.3;          // [s]

  void recordBoardRotation(std::size_t c, TimeNs stamp, const SE3& T_G_C) {
    auto& h = board_rotations[c];
    if (!h.empty() && stamp <= h.back().first) return;
    h.emplace_back(stamp, T_G_C.rotation());
    while (h.size() > 2 && h.back().first - h.front().first > 2 * kAlignSpanNs) h.pop_front();
  }

  // The offset correction of camera c [s], or 0 when the data do not decide it.
  double clockCorrection(std::size_t c) const {
    if (imu.size() < 2) return 0.0;
    const Eigen::Matrix3d R_I_C = poseToSE3(cameras[c]->extrinsic).rotation().transpose();
    return mvis::clockCorrection(
        board_rotations[c], R_I_C, timeOffsetNs(c), imu.front().stamp_ns, imu.back().stamp_ns,
        [this](TimeNs t) { return readingAt(t).gyro; }, kAlignRange);
  }

  void alignClocks() {
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

  void initialize() {
    const std::size_t n = init.size();
    // Gravity and velocities from the board poses and the readings between them.
    std::vector<std::shared_ptr<ImuPreintegration>> pre;
    std::vector<const ImuPreintegration*> pre_ptrs;
    std::vector<TimeNs> times;
    std::vector<SE3> poses;
    for (std::size_t i = 0; i < n; ++i) {
      times.push_back(init[i].t);
      poses.push_back(init[i].T_G_I);
      if (i + 1 < n) {
        pre.push_back(preintegrate(init[i].t, init[i + 1].t, Eigen::Vector3d::Zero(),
                                   Eigen::Vector3d::Zero()));
        pre_ptrs.push_back(pre.back().get());
      }
    }
    const GravityAlignment aligned = alignGravity(times, poses, pre_ptrs);
    Eigen::Vector3d g = aligned.gravity;
    if (!g.allFinite() || std::abs(g.norm() - options.gravity_m_s2) > 0.3 * options.gravity_m_s2) {
      std::ostringstream s;
      s << "initializing: gravity from the first " << n << " frames came out as " << g.norm()
        << " m/s^2 (camera extrinsic or time offset far off, or IMU units wrong?); retrying";
      status_text = s.str();
      init.erase(init.begin(), init.begin() + n / 2);
      return;
    }
    g *= options.gravity_m_s2 / g.norm();
    Eigen::Map<Eigen::Vector3d>{gravity} = g;

    newProblem();
    states.clear();
    addCalibrationBlocks();
    for (std::size_t i = 0; i < n; ++i) {
      auto s = std::make_unique<State>();
      s->t = init[i].t;
      s->gyro = gyroAt(s->t);
      se3ToPose(init[i].T_G_I, s->pose);
      Eigen::Map<Eigen::Vector3d>(s->speed_bias) = aligned.velocities[i];
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
    for (std::size_t i = 0; i + 1 < n; ++i) addImuFactor(i);
    for (std::size_t i = 0; i < n; ++i) addFrame(init[i].frame, i);
    init.clear();
    attachOtherFrames();
    const auto start = Clock::now();
    SolveSummary summary = solve(std::max(30, options.max_iterations), options.init_solve_time_s);
    initialized = true;
    status_text = clock_message.empty() ? "running" : "running; " + clock_message;
    while (static_cast<int>(states.size()) > options.window_size) marginalizeOldest();
    publish(summary, start);
  }

  // IMU-rate state: the newest window state carried forward with the readings since.
  void propagate(const ImuMeasurement& m) {
    if (!propagation_callback || !initialized || states.empty()) return;
    const State& newest = *states.back();
    if (m.stamp_ns <= newest.t) return;
    const Eigen::Vector3d bg(newest.speed_bias + 3), ba(newest.speed_bias + 6);
    if (!propagation || propagation_from != newest.t) {
      propagation =
          std::make_shared<ImuPreintegration>(rig.inertial[0].noise, bg, ba, maxImuInterval());
      for (const auto& r : imuBetween(newest.t, m.stamp_ns)) propagation->add(r);
      propagation_from = newest.t;
    } else {
      propagation->add(m);
    }
    EstimatorState out;
    out.stamp_ns = m.stamp_ns;
    Eigen::Quaterniond q;
    Eigen::Vector3d p, v;
    propagation->predict(poseRotation(newest.pose), posePosition(newest.pose),
                         Eigen::Vector3d(newest.speed_bias), Eigen::Vector3d(gravity), &q, &p, &v);
    out.T_G_I = SE3(q, p);
    out.v_G = v;
    out.bias_gyro = bg;
    out.bias_accel = ba;
    propagation_callback(out);
  }

  // ---- solving and marginalization -------------------------------------------------------

  SolveSummary solve(int iterations, double max_time_s = -1.0) {
    ceres::Solver::Options o;
    o.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
    o.max_num_iterations = iterations;
    o.max_solver_time_in_seconds = max_time_s > 0 ? max_time_s : options.max_solve_time_s;
    o.num_threads = options.threads;
    o.logging_type = ceres::SILENT;
    ceres::Solver::Summary s;
    ceres::Solve(o, problem.get(), &s);
    ++counters.solves;
    SolveSummary out = windowSummary();
    out.iterations = static_cast<int>(s.iterations.size());
    out.solve_s = s.total_time_in_seconds;
    out.cost = s.final_cost;
    out.usable = s.IsSolutionUsable();
    return out;
  }

  SolveSummary windowSummary() const {
    SolveSummary out;
    out.states = static_cast<int>(states.size());
    for (const auto& st : states) {
      out.frames += st->frames;
      out.corners += st->corners;
    }
    return out;
  }

  void marginalizeOldest() {
    State* oldest = states.front().get();
    Marginalizer m;
    std::vector<const ResidualRecord*> records;
    for (const auto& r : oldest->residuals) records.push_back(&r);
    if (prior.id != nullptr) records.push_back(&prior);
    for (const auto* r : records) {
      for (double* block : r->blocks) m.setManifold(block, problem->GetManifold(block));
      m.addResidual(r->cost, r->loss, r->blocks);
    }
    auto made = m.marginalize({oldest->pose, oldest->speed_bias});
    // Remove the old prior and the state (with every residual on it).
    if (prior.id != nullptr) problem->RemoveResidualBlock(prior.id);
    prior = ResidualRecord{};
    // Residual blocks one by one in their recorded order: Ceres's own removal of a parameter
    // block's dependents walks a hash set, whose order (pointer values) would make results
    // differ from run to run in the last digits, and the window amplifies that.
    for (const auto& r : oldest->residuals) problem->RemoveResidualBlock(r.id);
    problem->RemoveParameterBlock(oldest->pose);
    problem->RemoveParameterBlock(oldest->speed_bias);
    past.push_back(oldest->toEstimate());
    states.pop_front();
    if (!made.ok()) {
      status_text = "marginalization failed (" + made.status().message() + "); prior dropped";
      return;
    }
    MarginalizationFactor* factor = std::move(made).value().release();
    prior.blocks = factor->parameterBlocks();
    prior.cost = factor;
    prior.id = problem->AddResidualBlock(factor, nullptr, prior.blocks);
  }

  void publish(const SolveSummary& summary, Clock::time_point start) {
    ++solves_since_covariance;
    EstimatorUpdate u;
    u.solve = summary;
    u.state = states.back()->toEstimate();
    u.gravity_G = Eigen::Vector3d(gravity);
    u.pose_covariance.setConstant(std::numeric_limits<double>::quiet_NaN());
    if (options.covariance_every > 0 && solves_since_covariance >= options.covariance_every) {
      Eigen::Matrix<double, 6, 6> pose_cov;
      if (covariance(&pose_cov).ok()) {
        u.pose_covariance = pose_cov;
        u.calibration_covariance_updated = true;
      }
    }
    u.solve.total_s = seconds(start, Clock::now());
    if (callback) callback(u);
  }

  // Calibration standard deviations, and the newest pose's covariance.
  Status covariance(Eigen::Matrix<double, 6, 6>* pose_cov) {
    solves_since_covariance = 0;
    if (states.empty()) return Status::Error("no state yet");
    ceres::Covariance::Options co;
    co.algorithm_type = ceres::SPARSE_QR;
    co.num_threads = options.threads;
    ceres::Covariance cov(co);
    std::vector<std::pair<const double*, const double*>> blocks;
    double* newest = states.back()->pose;
    blocks.emplace_back(newest, newest);
    for (const auto& cb : cameras) {
      for (const double* b : {cb->extrinsic, cb->time_offset, cb->intrinsics}) {
        if (!problem->IsParameterBlockConstant(b)) blocks.emplace_back(b, b);
      }
    }
    if (!cov.Compute(blocks, problem.get())) return Status::Error("covariance computation failed");
    if (pose_cov != nullptr) cov.GetCovarianceBlockInTangentSpace(newest, newest, pose_cov->data());
    std::vector<CameraCalibrationStd> out(cameras.size());
    for (std::size_t c = 0; c < cameras.size(); ++c) {
      const CameraBlocks& cb = *cameras[c];
      if (!problem->IsParameterBlockConstant(cb.extrinsic)) {
        Eigen::Matrix<double, 6, 6, Eigen::RowMajor> C;
        cov.GetCovarianceBlockInTangentSpace(cb.extrinsic, cb.extrinsic, C.data());
        const Vector6d sd = C.diagonal().cwiseMax(0.0).cwiseSqrt();
        out[c].rotation = sd.head<3>();
        out[c].translation = sd.tail<3>();
      }
      if (!problem->IsParameterBlockConstant(cb.time_offset)) {
        double v = 0.0;
        cov.GetCovarianceBlock(cb.time_offset, cb.time_offset, &v);
        out[c].timeshift_cam_imu = std::sqrt(std::max(v, 0.0));
      }
      if (!problem->IsParameterBlockConstant(cb.intrinsics)) {
        Eigen::Matrix<double, 8, 8, Eigen::RowMajor> C;
        cov.GetCovarianceBlock(cb.intrinsics, cb.intrinsics, C.data());
        const Eigen::Matrix<double, 8, 1> sd = C.diagonal().cwiseMax(0.0).cwiseSqrt();
        out[c].intrinsics = sd.head<4>();
        out[c].distortion_coeffs = sd.tail<4>();
      }
    }
    camera_std = out;
    return Status::Ok();
  }

  void trimBuffers() {
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
  }

  void resetAll() {
    newProblem();
    states.clear();
    imu.clear();
    base_frames.clear();
    for (auto& q : other_frames) q.clear();
    init.clear();
    for (auto& h : board_rotations) h.clear();
    clocks_aligned = false;
    initialized = false;
    last_imu = std::numeric_limits<TimeNs>::min();
    std::fill(last_frame.begin(), last_frame.end(), std::numeric_limits<TimeNs>::min());
    status_text = "reset: waiting for data";
  }

  Rig calibration() const {
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
    return out;
  }
};

Estimator::Estimator(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Estimator::~Estimator() = default;

StatusOr<std::unique_ptr<Estimator>> Estimator::create(const Rig& rig,
                                                       const EstimatorOptions& options) {
  Status valid = validate(options);
  if (!valid.ok()) return valid;
  if (rig.inertial.empty()) return Status::Error("the rig has no base IMU");
  if (rig.cameras.empty()) return Status::Error("the rig has no camera");
  if (!rig.target) {
    return Status::Error(
        "the rig has no aprilgrid.yaml: tag corners as landmark states are not supported yet");
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
const EstimatorCounters& Estimator::counters() const { return impl_->counters; }
void Estimator::reset() {
  impl_->resetAll();
  ++impl_->counters.resets;
}

}  // namespace mvis
