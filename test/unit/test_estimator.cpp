// The sliding-window estimator on simulated tag detections with a perturbed initial
// calibration: calibration and trajectory errors against the truth, honesty of the reported
// standard deviations, and recovery from bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <functional>
#include <limits>

#include "mvis/estimator/estimator.h"
#include "mvis/estimator/evaluation.h"
#include "mvis/rig/rig_io.h"
#include "mvis/sim/simulation.h"

namespace mvis {
namespace {

// Everything a simulated run produced, in arrival order (sensor-clock stamps).
struct Recorded final : SimulationSink {
  struct Event {
    TimeNs stamp;
    int kind;  // 0 imu, 1 frame
    std::size_t index;
  };
  std::vector<std::pair<std::size_t, ImuSample>> imu_samples;
  std::vector<TagFrame> frames;
  void imu(std::size_t sensor, const ImuSample& s) override { imu_samples.emplace_back(sensor, s); }
  void tagFrame(const TagFrame& f) override { frames.push_back(f); }
  void image(std::size_t, TimeNs, const cv::Mat&) override {}

  std::vector<Event> events() const {
    std::vector<Event> out;
    for (std::size_t i = 0; i < imu_samples.size(); ++i) {
      out.push_back({imu_samples[i].second.stamp_ns, 0, i});
    }
    for (std::size_t i = 0; i < frames.size(); ++i) out.push_back({frames[i].stamp_ns, 1, i});
    std::stable_sort(out.begin(), out.end(),
                     [](const Event& a, const Event& b) { return a.stamp < b.stamp; });
    return out;
  }
};

struct SimRun {
  Rig truth, guess;
  std::vector<StampedPose> truth_trajectory;
  Recorded data;
};

SimRun simulate(const std::string& rig_dir, double duration_s, std::uint64_t seed,
                MotionKind motion = MotionKind::kHandheld, bool perturb_intrinsics = false,
                const std::function<void(Rig*)>& edit_truth = nullptr) {
  SimRun run;
  auto truth = loadRig(std::string(MVIS_SOURCE_DIR) + "/config/" + rig_dir);
  EXPECT_TRUE(truth.ok()) << truth.status().message();
  run.truth = truth.value();
  if (edit_truth) edit_truth(&run.truth);
  SimulationConfig config;
  config.duration_s = duration_s;
  config.seed = seed;
  config.camera_output = CameraOutput::kDetections;
  config.motion.kind = motion;
  config.pixel_noise_px = 0.5;
  config.camera_rate_hz.clear();
  for (const auto& cam : run.truth.cameras) {
    config.camera_rate_hz.push_back(cam.name == "cam1" && run.truth.cameras.size() == 3 ? 25.0
                                                                                        : 30.0);
  }
  auto trajectory = runSimulation(run.truth, config, &run.data);
  EXPECT_TRUE(trajectory.ok()) << trajectory.status().message();
  run.truth_trajectory = trajectory.value();
  if (perturb_intrinsics) {  // report Table 4
    config.perturbation.camera_focal_px = 1.0;
    config.perturbation.camera_centre_px = 1.0;
    config.perturbation.camera_distortion = 0.002;
  }
  run.guess = perturbRig(run.truth, config.perturbation, seed);
  return run;
}

// The solver's time budget makes results depend on the machine's load; tests lift it.
EstimatorOptions deterministic() {
  EstimatorOptions o;
  o.max_solve_time_s = 1e3;
  o.init_solve_time_s = 1e3;
  return o;
}

void feed(const SimRun& run, Estimator* estimator) {
  for (const auto& e : run.data.events()) {
    if (e.kind == 0) {
      const auto& [sensor, s] = run.data.imu_samples[e.index];
      estimator->addImu(sensor, {s.stamp_ns, s.gyro, s.accel});
    } else {
      estimator->addTagFrame(run.data.frames[e.index]);
    }
  }
}

// The estimator from `guess` over the whole run, with its calibration covariance computed;
// null (and a test failure) if it did not start or initialize.
std::unique_ptr<Estimator> runFrom(const Rig& guess, const SimRun& run,
                                   const EstimatorOptions& options) {
  auto created = Estimator::create(guess, options);
  EXPECT_TRUE(created.ok()) << created.status().message();
  if (!created.ok()) return nullptr;
  std::unique_ptr<Estimator> estimator = std::move(created).value();
  feed(run, estimator.get());
  EXPECT_TRUE(estimator->initialized()) << estimator->status();
  EXPECT_TRUE(estimator->computeCovariance().ok());
  if (!estimator->initialized()) return nullptr;
  return estimator;
}

struct CameraErrors {
  double rotation_deg, translation_mm, time_offset_ms;
  Eigen::Vector3d rotation_sigma_ratio, translation_sigma_ratio;  // |error| / std per axis
  double time_offset_sigma_ratio;
};

CameraErrors errors(const Camera& truth, const Camera& estimate) {
  CameraErrors e;
  const CameraCalibrationError err = cameraError(truth, estimate);
  const Eigen::Vector3d& dtheta = err.rotation;
  const Eigen::Vector3d& dp = err.translation;
  const double dt = err.time_offset;
  e.rotation_deg = dtheta.norm() * 180.0 / M_PI;
  e.translation_mm = dp.norm() * 1e3;
  e.time_offset_ms = std::abs(dt) * 1e3;
  if (estimate.std) {
    e.rotation_sigma_ratio = dtheta.cwiseAbs().cwiseQuotient(estimate.std->rotation);
    e.translation_sigma_ratio = dp.cwiseAbs().cwiseQuotient(estimate.std->translation);
    e.time_offset_sigma_ratio = std::abs(dt) / estimate.std->timeshift_cam_imu;
  }
  return e;
}

// An auxiliary sensor's errors, as CameraErrors (a gyroscope's translation: zero, not calibrated).
CameraErrors inertialErrors(const InertialSensor& truth, const InertialSensor& estimate) {
  const CameraCalibrationError err = inertialError(truth, estimate);
  const bool gyro = truth.type == InertialType::kGyroscope;
  CameraErrors e;
  e.rotation_deg = err.rotation.norm() * 180.0 / M_PI;
  e.translation_mm = gyro ? 0.0 : err.translation.norm() * 1e3;
  e.time_offset_ms = std::abs(err.time_offset) * 1e3;
  e.rotation_sigma_ratio.setZero();
  e.translation_sigma_ratio.setZero();
  e.time_offset_sigma_ratio = 0.0;
  if (estimate.std) {
    e.rotation_sigma_ratio = err.rotation.cwiseAbs().cwiseQuotient(estimate.std->rotation);
    if (!gyro) {
      e.translation_sigma_ratio =
          err.translation.cwiseAbs().cwiseQuotient(estimate.std->translation);
    }
    e.time_offset_sigma_ratio = std::abs(err.time_offset) / estimate.std->time_offset;
  }
  return e;
}

// The checks every auxiliary sensor passes after a run: the absolute bounds and every error
// inside 3 sigma.
void expectInertialCalibrated(const CameraErrors& e, const std::string& name, double rotation_deg,
                              double translation_mm, double time_offset_ms) {
  EXPECT_LT(e.rotation_deg, rotation_deg) << name;
  EXPECT_LT(e.translation_mm, translation_mm) << name;
  EXPECT_LT(e.time_offset_ms, time_offset_ms) << name;
  EXPECT_LT(e.rotation_sigma_ratio.maxCoeff(), 3.0) << name;
  EXPECT_LT(e.translation_sigma_ratio.maxCoeff(), 3.0) << name;
  EXPECT_LT(e.time_offset_sigma_ratio, 3.0) << name;
}

TEST(Estimator, CalibratesEveryCameraOfTheViRig) {
  const SimRun run = simulate("sim_vi_rig", 20.0, 3);
  EstimatorOptions options = deterministic();
  options.pixel_sigma_px = 0.5;  // the simulated detections' noise
  auto created = Estimator::create(run.guess, options);
  ASSERT_TRUE(created.ok()) << created.status().message();
  auto& estimator = *created.value();
  int updates = 0;
  std::vector<double> total_ms;
  std::vector<EstimatorState> propagated;
  estimator.setPropagationCallback([&](const EstimatorState& s) { propagated.push_back(s); });
  estimator.setUpdateCallback([&](const EstimatorUpdate& u) {
    ++updates;
    total_ms.push_back(u.solve.total_s * 1e3);
  });
  feed(run, &estimator);
  ASSERT_TRUE(estimator.initialized()) << estimator.status();
  ASSERT_TRUE(estimator.computeCovariance().ok());
  const Rig estimate = estimator.calibration();
  for (std::size_t c = 0; c < run.truth.cameras.size(); ++c) {
    const CameraErrors before = errors(run.truth.cameras[c], run.guess.cameras[c]);
    const CameraErrors after = errors(run.truth.cameras[c], estimate.cameras[c]);
    std::printf(
        "%s: rotation %.4f -> %.4f deg, translation %.3f -> %.3f mm, time offset "
        "%.4f -> %.4f ms; error/sigma rot %.2f %.2f %.2f pos %.2f %.2f %.2f dt %.2f\n",
        run.truth.cameras[c].name.c_str(), before.rotation_deg, after.rotation_deg,
        before.translation_mm, after.translation_mm, before.time_offset_ms, after.time_offset_ms,
        after.rotation_sigma_ratio[0], after.rotation_sigma_ratio[1], after.rotation_sigma_ratio[2],
        after.translation_sigma_ratio[0], after.translation_sigma_ratio[1],
        after.translation_sigma_ratio[2], after.time_offset_sigma_ratio);
    // The bounds (measured with seed 3, the aux IMU and gyroscope in the window:
    // <= 0.015 deg, 0.41 mm, 0.045 ms).
    EXPECT_LT(after.rotation_deg, 0.05);
    EXPECT_LT(after.translation_mm, 1.0);
    EXPECT_LT(after.time_offset_ms, 0.05);
    // Honest uncertainty: every error inside 3 sigma.
    EXPECT_LT(after.rotation_sigma_ratio.maxCoeff(), 3.0);
    EXPECT_LT(after.translation_sigma_ratio.maxCoeff(), 3.0);
    EXPECT_LT(after.time_offset_sigma_ratio, 3.0);
  }
  // Auxiliary IMU (imu1) and gyroscope (imu2), the aux issue's bounds for 60 s met in 20 s
  // (measured with seed 3: imu1 0.004 deg, 0.59 mm, 0.035 ms; imu2 0.003 deg, 0.065 ms).
  for (std::size_t i = 1; i < run.truth.inertial.size(); ++i) {
    const InertialSensor& truth = run.truth.inertial[i];
    const InertialSensor& est = estimate.inertial[i];
    ASSERT_TRUE(est.std.has_value()) << truth.name;
    const CameraErrors before = inertialErrors(truth, run.guess.inertial[i]);
    const CameraErrors after = inertialErrors(truth, est);
    std::printf(
        "%s: rotation %.4f -> %.4f deg, translation %.3f -> %.3f mm, time offset %.4f -> %.4f ms; "
        "error/sigma rot %.2f %.2f %.2f pos %.2f %.2f %.2f dt %.2f\n",
        truth.name.c_str(), before.rotation_deg, after.rotation_deg, before.translation_mm,
        after.translation_mm, before.time_offset_ms, after.time_offset_ms,
        after.rotation_sigma_ratio[0], after.rotation_sigma_ratio[1], after.rotation_sigma_ratio[2],
        after.translation_sigma_ratio[0], after.translation_sigma_ratio[1],
        after.translation_sigma_ratio[2], after.time_offset_sigma_ratio);
    expectInertialCalibrated(after, truth.name, 0.05, 2.0, 0.1);
  }
  // Trajectory: the online estimate of every state as it left the window. The first seconds
  // carry the initial calibration error (cm) until the estimate converges.
  const auto trajectory = estimator.trajectory();
  std::vector<EstimatorState> converged;
  for (const auto& s : trajectory) {
    if (s.stamp_ns - trajectory.front().stamp_ns > fromSeconds(5.0)) converged.push_back(s);
  }
  const double ate = positionRmse(trajectory, run.truth_trajectory);
  const double ate_converged = positionRmse(converged, run.truth_trajectory);
  std::sort(total_ms.begin(), total_ms.end());
  std::printf("ATE RMSE %.2f mm (after 5 s: %.2f mm) over %zu states; %d updates, median %.1f ms\n",
              ate * 1e3, ate_converged * 1e3, trajectory.size(), updates,
              total_ms[total_ms.size() / 2]);
  // IMU-rate states between solves: every base-IMU reading after initialization, as accurate.
  std::vector<EstimatorState> propagated_converged;
  for (const auto& s : propagated) {
    if (s.stamp_ns - trajectory.front().stamp_ns > fromSeconds(5.0))
      propagated_converged.push_back(s);
  }
  EXPECT_GT(propagated.size(), 9000u);  // 500 Hz over the ~18 s after initialization
  const double propagated_rmse = positionRmse(propagated_converged, run.truth_trajectory);
  std::printf("IMU-rate states: %zu, position RMSE after 5 s %.2f mm\n", propagated.size(),
              propagated_rmse * 1e3);
  EXPECT_LT(propagated_rmse, 0.002);
  // Measured 2.6 mm and 0.8 mm (seed 3); the bounds leave room for other seeds' convergence.
  EXPECT_LT(ate, 0.008);
  EXPECT_LT(ate_converged, 0.002);
}

}  // namespace
}  // namespace mvis

namespace mvis {
namespace {

// Max errors over a rig's cameras.
struct WorstErrors {
  double rotation_deg = 0.0, translation_mm = 0.0, time_offset_ms = 0.0;
};
WorstErrors worst(const Rig& truth, const Rig& estimate) {
  WorstErrors w;
  for (std::size_t c = 0; c < truth.cameras.size(); ++c) {
    const CameraErrors e = errors(truth.cameras[c], estimate.cameras[c]);
    w.rotation_deg = std::max(w.rotation_deg, e.rotation_deg);
    w.translation_mm = std::max(w.translation_mm, e.translation_mm);
    w.time_offset_ms = std::max(w.time_offset_ms, e.time_offset_ms);
  }
  return w;
}

// The small rig's camera after a disturbed 10 s run: every error inside 3 sigma, and within
// bounds a few times the small camera's uncertainty (0.2 deg, 5 mm, 0.5 ms).
void expectSmallRigCalibrated(const SimRun& run, const Rig& estimate, const char* label) {
  const WorstErrors w = worst(run.truth, estimate);
  const CameraErrors e = errors(run.truth.cameras[0], estimate.cameras[0]);
  std::printf("%s: %.4f deg, %.3f mm, %.4f ms; error/sigma rot %.2f pos %.2f dt %.2f\n", label,
              w.rotation_deg, w.translation_mm, w.time_offset_ms, e.rotation_sigma_ratio.maxCoeff(),
              e.translation_sigma_ratio.maxCoeff(), e.time_offset_sigma_ratio);
  EXPECT_LT(e.rotation_sigma_ratio.maxCoeff(), 3.0) << label;
  EXPECT_LT(e.translation_sigma_ratio.maxCoeff(), 3.0) << label;
  EXPECT_LT(e.time_offset_sigma_ratio, 3.0) << label;
  EXPECT_LT(w.rotation_deg, 0.2) << label;
  EXPECT_LT(w.translation_mm, 5.0) << label;
  EXPECT_LT(w.time_offset_ms, 0.5) << label;
}

TEST(Estimator, DropsAndCountsBadInputAndKeepsCalibrating) {
  const SimRun run = simulate("sim_small_rig", 10.0, 11);
  auto created = Estimator::create(run.guess, deterministic());
  ASSERT_TRUE(created.ok());
  Estimator& estimator = *created.value();
  const TimeNs t0 = run.truth_trajectory.front().first;
  long duplicates_imu = 0, nans = 0, duplicates_frames = 0, gap_skipped = 0, too_close = 0;
  std::size_t imu_count = 0, frame_count = 0;
  for (const auto& e : run.data.events()) {
    if (e.kind == 0) {
      const auto& [sensor, s] = run.data.imu_samples[e.index];
      if (sensor != 0) continue;
      // A 0.1 s hole in the base IMU's stream.
      if (s.stamp_ns >= t0 + fromSeconds(4.0) && s.stamp_ns < t0 + fromSeconds(4.1)) {
        ++gap_skipped;
        continue;
      }
      const ImuMeasurement m{s.stamp_ns, s.gyro, s.accel};
      if (++imu_count % 101 == 0) {  // a NaN reading just before this one
        ImuMeasurement bad = m;
        bad.stamp_ns -= 1000;
        bad.accel.x() = std::numeric_limits<double>::quiet_NaN();
        EXPECT_FALSE(estimator.addImu(0, bad).ok());
        ++nans;
      }
      const Status added = estimator.addImu(0, m);
      // The first reading after the hole reports it; every other good reading is taken.
      EXPECT_EQ(added.ok(), s.stamp_ns != t0 + fromSeconds(4.1)) << added.message();
      if (imu_count % 97 == 0) {  // the same reading again
        EXPECT_FALSE(estimator.addImu(0, m).ok());
        ++duplicates_imu;
      }
    } else {
      const TagFrame& f = run.data.frames[e.index];
      EXPECT_TRUE(estimator.addTagFrame(f).ok());
      if (++frame_count % 13 == 0) {
        EXPECT_FALSE(estimator.addTagFrame(f).ok());
        ++duplicates_frames;
      }
      if (f.camera == 0 && estimator.initialized() && frame_count % 17 == 0) {
        // A cam0 frame 2 ms after this one: its state would sit 2 ms after this one's. (Made,
        // such states wrecked this run: translation 11 mm off at 65 sigma.)
        TagFrame close = f;
        close.stamp_ns += 2000000;
        EXPECT_TRUE(estimator.addTagFrame(close).ok());
        ++too_close;
      }
    }
  }
  ASSERT_TRUE(estimator.initialized()) << estimator.status();
  EXPECT_GT(gap_skipped, 10);
  EXPECT_EQ(estimator.counters().imu_non_finite, nans);
  EXPECT_EQ(estimator.counters().imu_out_of_order, duplicates_imu);
  EXPECT_EQ(estimator.counters().frames_out_of_order, duplicates_frames);
  EXPECT_GT(too_close, 3);
  EXPECT_EQ(estimator.counters().frames_too_close, too_close);
  EXPECT_EQ(estimator.counters().resets, 0);
  EXPECT_EQ(estimator.counters().imu_gaps, 1);
  ASSERT_TRUE(estimator.computeCovariance().ok());
  const Rig estimate = estimator.calibration();
  // One small camera (376x240) for 10 s: errors of a few mm are what its uncertainty allows;
  // the test is that bad input neither stops nor biases it.
  expectSmallRigCalibrated(run, estimate, "small rig with bad input");
}

TEST(Estimator, RestartedBagResetsAndRecovers) {
  const SimRun run = simulate("sim_small_rig", 10.0, 12);
  auto created = Estimator::create(run.guess, deterministic());
  ASSERT_TRUE(created.ok());
  Estimator& estimator = *created.value();
  const TimeNs t0 = run.truth_trajectory.front().first;
  const auto events = run.data.events();
  bool reset_said = false;
  for (int pass = 0; pass < 2; ++pass) {
    for (const auto& e : events) {
      if (e.kind == 0) {
        const auto& [sensor, s] = run.data.imu_samples[e.index];
        if (pass == 0 && s.stamp_ns > t0 + fromSeconds(4.0)) break;  // the first play stops
        const Status st = estimator.addImu(sensor, {s.stamp_ns, s.gyro, s.accel});
        if (!st.ok() && st.message().find("reset") != std::string::npos) reset_said = true;
      } else {
        estimator.addTagFrame(run.data.frames[e.index]);
      }
    }
    if (pass == 0) {
      ASSERT_TRUE(estimator.initialized());
    }
  }
  EXPECT_TRUE(reset_said);
  EXPECT_EQ(estimator.counters().resets, 1);
  ASSERT_TRUE(estimator.initialized()) << estimator.status();
  const auto trajectory = estimator.trajectory();
  ASSERT_FALSE(trajectory.empty());
  // After the reset the trajectory starts over from the bag's beginning.
  EXPECT_LT(trajectory.front().stamp_ns, t0 + fromSeconds(1.0));
  ASSERT_TRUE(estimator.computeCovariance().ok());
  const Rig estimate = estimator.calibration();
  // Measured 0.035 deg, 0.76 mm, 0.025 ms (imu1 in the window): inside 3 sigma; the
  // absolute bounds catch a restart that loses the calibration.
  expectSmallRigCalibrated(run, estimate, "small rig after a restart");
}

}  // namespace
}  // namespace mvis

namespace mvis {
namespace {

// A camera clock 0.2 s off the configured offset (a driver stamping on arrival): the gyroscope
// match corrects it before the window starts, and the estimate then converges as usual.
TEST(Estimator, CorrectsATimeOffsetFarFromTheConfiguredOne) {
  SimRun run = simulate("sim_small_rig", 10.0, 13);
  // The truth has cam0 0.2 s late; the guess still believes the configured (perturbed) value.
  run.truth.cameras[0].timeshift_cam_imu = 0.2;
  Recorded shifted;
  for (const auto& [sensor, s] : run.data.imu_samples) shifted.imu(sensor, s);
  for (TagFrame f : run.data.frames) {
    f.stamp_ns -= fromSeconds(0.2);  // t_cam = t_imu0 - timeshift
    shifted.tagFrame(f);
  }
  run.data = shifted;
  auto created = Estimator::create(run.guess, deterministic());
  ASSERT_TRUE(created.ok());
  Estimator& estimator = *created.value();
  feed(run, &estimator);
  ASSERT_TRUE(estimator.initialized()) << estimator.status();
  EXPECT_EQ(estimator.counters().clock_corrections, 1);
  EXPECT_NE(estimator.status().find("corrected from the gyroscope"), std::string::npos)
      << estimator.status();
  const CameraErrors e = errors(run.truth.cameras[0], estimator.calibration().cameras[0]);
  std::printf("0.2 s offset: %.4f deg, %.3f mm, %.4f ms\n", e.rotation_deg, e.translation_mm,
              e.time_offset_ms);
  // As the small rig without the clock error (DropsAndCounts...): well under a millisecond.
  EXPECT_LT(e.time_offset_ms, 0.5);
  EXPECT_LT(e.rotation_deg, 0.2);
  EXPECT_LT(e.translation_mm, 5.0);
}

}  // namespace
}  // namespace mvis

namespace mvis {
namespace {

// Report Table 2: rotating about one axis only, an auxiliary IMU's translation along the axis and
// a gyroscope's rotation about it are unobservable, while the rest still converges.
TEST(Estimator, YawOnlyMotionLeavesTheAxisDirectionsUncertain) {
  const SimRun run = simulate("sim_vi_rig", 20.0, 4, MotionKind::kYawOnly);
  EstimatorOptions options = deterministic();
  options.pixel_sigma_px = 0.5;
  auto created = Estimator::create(run.guess, options);
  ASSERT_TRUE(created.ok());
  Estimator& estimator = *created.value();
  EstimatorUpdate last, with_covariance;
  estimator.setUpdateCallback([&](const EstimatorUpdate& u) {
    last = u;
    if (u.pose_covariance.allFinite()) with_covariance = u;
  });
  feed(run, &estimator);
  ASSERT_TRUE(estimator.initialized()) << estimator.status();
  ASSERT_TRUE(estimator.computeCovariance().ok());
  const Rig estimate = estimator.calibration();

  // The cameras' translations along the axis are held too, and imu0's position along the axis
  // in the board frame rests on them: its covariance has to carry their kept uncertainty
  // instead of treating them as known (which gave a position NEES of ~1e4 on this motion).
  {
    ASSERT_TRUE(with_covariance.pose_covariance.allFinite());
    const TimeNs t = with_covariance.state.stamp_ns;
    const auto& truth = run.truth_trajectory;
    auto after = std::lower_bound(truth.begin(), truth.end(), t,
                                  [](const StampedPose& p, TimeNs s) { return p.first < s; });
    ASSERT_TRUE(after != truth.begin() && after != truth.end());
    const auto before = after - 1;
    const double a = static_cast<double>(t - before->first) / (after->first - before->first);
    const Eigen::Vector3d p_true = (1 - a) * before->second.p + a * after->second.p;
    const double error_z = p_true.z() - with_covariance.state.T_G_I.p.z();
    const double std_z = std::sqrt(with_covariance.pose_covariance(5, 5));
    std::printf("imu0 position along the axis: error %.2f mm, std %.2f mm\n", error_z * 1e3,
                std_z * 1e3);
    // Measured (seed 4): error 30 mm, std 35 mm. With the held directions taken as known the
    // std was under a millimetre (mean position NEES 40-11000 over six yaw-only runs).
    EXPECT_LT(std::abs(error_z), 3.0 * std_z);
    EXPECT_GT(std_z, 0.02);
  }
  // The rotation axis in {I}: world z seen from the base IMU (constant: yaw only).
  const Eigen::Vector3d axis_I =
      run.truth_trajectory.front().second.q.conjugate() * Eigen::Vector3d::UnitZ();
  int axis_index = 0;
  axis_I.cwiseAbs().maxCoeff(&axis_index);
  ASSERT_GT(std::abs(axis_I[axis_index]), 0.99);  // a frame axis, so per-axis stds tell
  for (std::size_t i = 1; i < run.truth.inertial.size(); ++i) {
    const InertialSensor& truth = run.truth.inertial[i];
    const InertialSensor& guess = run.guess.inertial[i];
    const InertialSensor& est = estimate.inertial[i];
    ASSERT_TRUE(est.std.has_value());
    const CameraCalibrationError e = inertialError(truth, est);
    const bool gyro = truth.type == InertialType::kGyroscope;
    // The unobservable direction and its per-axis std: the gyroscope's rotation about the axis
    // (right perturbation, {I} coordinates); the aux IMU's translation along the axis in {A}.
    int index = axis_index;
    const Eigen::Vector3d* stds = &est.std->rotation;
    // How far the estimate moved along the unobservable direction from the initial guess.
    double moved = 0.0;
    if (gyro) {
      moved = std::abs(lie::logQuat(guess.T_i_b.q.conjugate() * est.T_i_b.q).dot(axis_I));
    } else {
      (truth.T_i_b.q * axis_I).cwiseAbs().maxCoeff(&index);
      stds = &est.std->translation;
      const Eigen::Vector3d p_guess = -(guess.T_i_b.q.conjugate() * guess.T_i_b.p);
      const Eigen::Vector3d p_est = -(est.T_i_b.q.conjugate() * est.T_i_b.p);
      moved = std::abs((p_est - p_guess).dot(axis_I));
    }
    double others = 0.0;
    for (int k = 0; k < 3; ++k) {
      if (k != index) others = std::max(others, (*stds)[k]);
    }
    std::printf(
        "%s yaw only: rotation %.4f deg, translation %.2f mm, time offset %.4f ms; along the "
        "axis: std %.4g (prior 0.1), moved %.3g; largest other std %.4g\n",
        truth.name.c_str(), e.rotation.norm() * 180 / M_PI, gyro ? 0.0 : e.translation.norm() * 1e3,
        std::abs(e.time_offset) * 1e3, (*stds)[index], moved, others);
    // Measured (seed 4): along the axis std 0.091 m (imu1) and 0.099 rad (imu2) against a
    // prior of 0.1, and no movement; across it <= 2 mm / 2 mrad. Without the observability
    // check the stds shrank to 0.0036 m and 0.05 rad and the estimates drifted by 84 mm and
    // 6.7 deg (5.9 sigma).
    EXPECT_GT((*stds)[index], 0.07) << truth.name;
    EXPECT_LT(moved, 1e-3) << truth.name;
    EXPECT_GT((*stds)[index], 20.0 * others) << truth.name;
    // What stays observable converges: time offsets, and the aux IMU's rotation.
    EXPECT_LT(std::abs(e.time_offset) * 1e3, 0.1) << truth.name;
    EXPECT_LT(std::abs(e.time_offset), 3.0 * est.std->time_offset) << truth.name;
    if (!gyro) {
      for (int k = 0; k < 3; ++k) {
        EXPECT_LT(std::abs(e.rotation[k]), 3.0 * est.std->rotation[k]) << truth.name << k;
      }
      EXPECT_LT(e.rotation.norm() * 180 / M_PI, 0.05) << truth.name;
    }
    // And said so, in words, with the axis.
    const std::string quantity = gyro ? "rotation" : "translation";
    const UnobservableCalibration* said = nullptr;
    for (const auto& u : last.unobservable) {
      if (u.sensor == truth.name && u.quantity == quantity) said = &u;
    }
    ASSERT_NE(said, nullptr) << truth.name;
    std::printf("  said: %s\n", said->text().c_str());
    ASSERT_EQ(said->directions_I.size(), 1u);
    EXPECT_GT(std::abs(said->directions_I[0].dot(axis_I)), 0.99);
    EXPECT_NE(said->text().find("rotate about another axis"), std::string::npos);
  }
  for (const auto& u : last.unobservable) std::printf("  unobservable: %s\n", u.text().c_str());
}

// Camera intrinsics online (report Table 4 perturbations: 1 px focal lengths and centre, 0.002
// per distortion coefficient) next to everything else of the VI-Rig.
TEST(Estimator, CalibratesCameraIntrinsics) {
  const SimRun run = simulate("sim_vi_rig", 20.0, 2, MotionKind::kHandheld, true);
  EstimatorOptions options = deterministic();
  options.pixel_sigma_px = 0.5;
  options.estimate_intrinsics = true;
  const auto estimator = runFrom(run.guess, run, options);
  ASSERT_NE(estimator, nullptr);
  const Rig estimate = estimator->calibration();
  for (std::size_t c = 0; c < run.truth.cameras.size(); ++c) {
    const Camera& truth = run.truth.cameras[c];
    const Camera& guess = run.guess.cameras[c];
    const Camera& est = estimate.cameras[c];
    ASSERT_TRUE(est.std.has_value());
    const Eigen::Vector4d e0 = truth.intrinsics - guess.intrinsics;
    const Eigen::Vector4d e = truth.intrinsics - est.intrinsics;
    const Eigen::Vector4d d = truth.distortion_coeffs - est.distortion_coeffs;
    std::printf(
        "%s intrinsics error [px] %.3f %.3f %.3f %.3f (initial %.3f %.3f %.3f %.3f), "
        "distortion error %.5f %.5f %.5f %.5f (std %.5f %.5f %.5f %.5f)\n",
        truth.name.c_str(), e[0], e[1], e[2], e[3], e0[0], e0[1], e0[2], e0[3], d[0], d[1], d[2],
        d[3], est.std->distortion_coeffs[0], est.std->distortion_coeffs[1],
        est.std->distortion_coeffs[2], est.std->distortion_coeffs[3]);
    // Measured (seed 2): focal lengths and centre within 0.15 px (from up to 1.7 px), radtan
    // (cam1) distortion within 8e-4. The equidistant cameras' higher coefficients stay near
    // their prior (std 0.01-0.03): the board never reaches the fisheye's rim, where they act.
    for (int i = 0; i < 4; ++i) {
      EXPECT_LT(std::abs(e[i]), 0.5) << truth.name << " " << i;
      EXPECT_LT(std::abs(e[i]), 3.0 * est.std->intrinsics[i]) << truth.name << " " << i;
      EXPECT_LT(std::abs(d[i]), 3.0 * est.std->distortion_coeffs[i]) << truth.name << " " << i;
      if (truth.distortion_model == DistortionModel::kRadtan) {
        EXPECT_LT(std::abs(d[i]), 1.5e-3) << truth.name << " " << i;
      }
    }
    // The extrinsics still converge.
    const CameraErrors x = errors(truth, est);
    EXPECT_LT(x.rotation_deg, 0.05) << truth.name;
    EXPECT_LT(x.translation_mm, 1.5) << truth.name;
    EXPECT_LT(x.time_offset_ms, 0.1) << truth.name;
  }
}

// IMUs with scale, misalignment, gravity sensitivity and accelerometer rotation (report Table 4
// sizes) whose intrinsics the configuration gives: their readings are corrected by them, and
// the calibration is as good as with calibrated IMUs. Measured (seed 5, 20 s): largest
// calibration error/sigma 2.45 over every camera and aux axis, ATE after 5 s 1.25 mm; with the
// intrinsics taken as identity instead (what mvis did before), 17.4 and 3.8 mm.
TEST(Estimator, UsesTheConfiguredImuIntrinsics) {
  const auto with_intrinsics = [](Rig* rig) {
    for (auto& s : rig->inertial) {
      s.model = ImuModel::kRpng;
      s.intrinsics.Tw << 1.003, -0.002, 0.003, 0, 0.997, 0.002, 0, 0, 1.002;
      s.intrinsics.Ta << 0.998, 0.003, -0.002, 0, 1.003, 0.001, 0, 0, 0.997;
      if (s.type != InertialType::kGyroscope) {
        s.intrinsics.Tg << 1e-3, -1e-3, 5e-4, 5e-4, 1e-3, -5e-4, -1e-3, 5e-4, 1e-3;
        s.intrinsics.R_IMUtoACC = lie::expSO3(Eigen::Vector3d(0.003, -0.003, 0.002));
      }
    }
  };
  const SimRun run = simulate("sim_vi_rig", 20.0, 5, MotionKind::kHandheld, false, with_intrinsics);
  for (const bool known : {true, false}) {
    Rig guess = run.guess;  // carries the true intrinsics (no intrinsics perturbation)
    if (!known) {
      for (auto& s : guess.inertial) s.intrinsics = ImuIntrinsics();
    }
    EstimatorOptions options = deterministic();
    options.pixel_sigma_px = 0.5;
    const auto estimator = runFrom(guess, run, options);
    ASSERT_NE(estimator, nullptr);
    const Rig estimate = estimator->calibration();
    double worst = 0.0;
    for (std::size_t c = 0; c < run.truth.cameras.size(); ++c) {
      const CameraErrors e = errors(run.truth.cameras[c], estimate.cameras[c]);
      worst = std::max({worst, e.rotation_sigma_ratio.maxCoeff(),
                        e.translation_sigma_ratio.maxCoeff(), e.time_offset_sigma_ratio});
      if (known) {
        EXPECT_LT(e.rotation_deg, 0.05) << run.truth.cameras[c].name;
        EXPECT_LT(e.translation_mm, 1.5) << run.truth.cameras[c].name;
        EXPECT_LT(e.time_offset_ms, 0.1) << run.truth.cameras[c].name;
      }
    }
    for (std::size_t i = 1; i < run.truth.inertial.size(); ++i) {
      const CameraErrors e = inertialErrors(run.truth.inertial[i], estimate.inertial[i]);
      worst = std::max({worst, e.rotation_sigma_ratio.maxCoeff(),
                        e.translation_sigma_ratio.maxCoeff(), e.time_offset_sigma_ratio});
    }
    // ATE after the first 5 s (before, the initial calibration's error dominates).
    std::vector<EstimatorState> converged;
    const auto trajectory = estimator->trajectory();
    for (const auto& st : trajectory) {
      if (st.stamp_ns - trajectory.front().stamp_ns > fromSeconds(5.0)) converged.push_back(st);
    }
    const double ate = positionRmse(converged, run.truth_trajectory);
    std::printf("IMU intrinsics %s: largest calibration error/sigma %.2f, ATE after 5 s %.2f mm\n",
                known ? "known" : "taken as identity", worst, ate * 1e3);
    if (known) {
      EXPECT_LT(worst, 3.0);
      EXPECT_LT(ate, 0.003);
    }
  }
}

// Per-sensor holds: a held quantity keeps its configured value (std 0), the rest of its class is
// estimated; a hold naming no sensor of the rig, or a quantity the sensor lacks, is refused.
TEST(Estimator, HoldsNamedQuantitiesAndRefusesUnknownOnes) {
  const SimRun run = simulate("sim_vi_rig", 5.0, 3, MotionKind::kHandheld, true);
  EstimatorOptions options = deterministic();
  options.estimate_intrinsics = true;
  for (const auto& [bad, says] :
       {std::pair<std::string, std::string>{"cam7.intrinsics", "(cam0, cam1, cam2, imu1, imu2)"},
        {"imu1.intrinsics", "quantity must be extrinsic, time_offset, got 'intrinsics'"},
        {"cam1", "expected <sensor>.<quantity>"}}) {
    options.hold = {bad};
    const auto refused = Estimator::create(run.guess, options);
    ASSERT_FALSE(refused.ok()) << bad;
    EXPECT_NE(refused.status().message().find("estimator option hold: '" + bad + "'"),
              std::string::npos)
        << refused.status().message();
    EXPECT_NE(refused.status().message().find(says), std::string::npos)
        << refused.status().message();
  }
  options.hold = {"cam1.intrinsics", "imu2.time_offset", "cam2.extrinsic"};
  auto created = Estimator::create(run.guess, options);
  ASSERT_TRUE(created.ok()) << created.status().message();
  Estimator& estimator = *created.value();
  feed(run, &estimator);
  ASSERT_TRUE(estimator.initialized()) << estimator.status();
  ASSERT_TRUE(estimator.computeCovariance().ok());
  const Rig estimate = estimator.calibration();
  EXPECT_EQ(estimate.cameras[1].intrinsics, run.guess.cameras[1].intrinsics);
  EXPECT_EQ(estimate.cameras[1].distortion_coeffs, run.guess.cameras[1].distortion_coeffs);
  EXPECT_EQ(estimate.cameras[1].std->intrinsics, Eigen::Vector4d::Zero());
  EXPECT_NE(estimate.cameras[0].intrinsics, run.guess.cameras[0].intrinsics);
  EXPECT_GT(estimate.cameras[0].std->intrinsics.minCoeff(), 0.0);
  EXPECT_EQ(estimate.inertial[2].time_offset, run.guess.inertial[2].time_offset);
  EXPECT_NE(estimate.inertial[1].time_offset, run.guess.inertial[1].time_offset);
  EXPECT_TRUE(estimate.cameras[2].T_cam_imu.p == run.guess.cameras[2].T_cam_imu.p);
  EXPECT_FALSE(estimate.cameras[0].T_cam_imu.p == run.guess.cameras[0].T_cam_imu.p);
}

// An auxiliary sensor that stops for a second leaves the window with a warning and comes back
// when its readings do; nothing else is disturbed.
TEST(Estimator, AuxiliarySensorThatStopsLeavesAndRejoins) {
  const SimRun run = simulate("sim_small_rig", 10.0, 14);
  auto created = Estimator::create(run.guess, deterministic());
  ASSERT_TRUE(created.ok());
  Estimator& estimator = *created.value();
  const TimeNs t0 = run.truth_trajectory.front().first;
  bool left_said = false, back_said = false;
  for (const auto& e : run.data.events()) {
    if (e.kind == 0) {
      const auto& [sensor, s] = run.data.imu_samples[e.index];
      if (sensor == 1 && s.stamp_ns > t0 + fromSeconds(5.0) && s.stamp_ns < t0 + fromSeconds(6.0))
        continue;  // imu1 silent for a second
      const Status st = estimator.addImu(sensor, {s.stamp_ns, s.gyro, s.accel});
      if (!st.ok() && st.message().find("imu1: no readings") != std::string::npos) left_said = true;
      if (!st.ok() && st.message().find("imu1: readings again") != std::string::npos)
        back_said = true;
    } else {
      estimator.addTagFrame(run.data.frames[e.index]);
    }
  }
  ASSERT_TRUE(estimator.initialized()) << estimator.status();
  EXPECT_TRUE(left_said);
  EXPECT_TRUE(back_said);
  EXPECT_EQ(estimator.counters().aux_dropouts, 1);
  EXPECT_EQ(estimator.counters().aux_starts, 2);  // at initialization and after the silence
  EXPECT_EQ(estimator.counters().resets, 0);
  ASSERT_TRUE(estimator.computeCovariance().ok());
  const Rig estimate = estimator.calibration();
  const CameraErrors e = inertialErrors(run.truth.inertial[1], estimate.inertial[1]);
  std::printf("imu1 after a 1 s silence: %.4f deg, %.3f mm, %.4f ms\n", e.rotation_deg,
              e.translation_mm, e.time_offset_ms);
  expectInertialCalibrated(e, "imu1", 0.1, 5.0, 0.5);
}

}  // namespace
}  // namespace mvis
