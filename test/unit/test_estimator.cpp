// The sliding-window estimator on simulated tag detections with a perturbed initial
// calibration: calibration and trajectory errors against the truth, honesty of the reported
// standard deviations, and recovery from bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>

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

SimRun simulate(const std::string& rig_dir, double duration_s, std::uint64_t seed) {
  SimRun run;
  auto truth = loadRig(std::string(MVIS_SOURCE_DIR) + "/config/" + rig_dir);
  EXPECT_TRUE(truth.ok()) << truth.status().message();
  run.truth = truth.value();
  SimulationConfig config;
  config.duration_s = duration_s;
  config.seed = seed;
  config.camera_output = CameraOutput::kDetections;
  config.pixel_noise_px = 0.5;
  config.camera_rate_hz.clear();
  for (const auto& cam : run.truth.cameras) {
    config.camera_rate_hz.push_back(cam.name == "cam1" && run.truth.cameras.size() == 3 ? 25.0
                                                                                        : 30.0);
  }
  auto trajectory = runSimulation(run.truth, config, &run.data);
  EXPECT_TRUE(trajectory.ok()) << trajectory.status().message();
  run.truth_trajectory = trajectory.value();
  run.guess = perturbRig(run.truth, config.perturbation, seed);
  return run;
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

TEST(Estimator, CalibratesEveryCameraOfTheViRig) {
  const SimRun run = simulate("sim_vi_rig", 20.0, 3);
  EstimatorOptions options;
  options.pixel_sigma_px = 0.5;  // the simulated detections' noise
  auto created = Estimator::create(run.guess, options);
  ASSERT_TRUE(created.ok()) << created.status().message();
  auto& estimator = *created.value();
  int updates = 0;
  std::vector<double> total_ms;
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
    // The bounds (measured with seed 3: <= 0.02 deg, 0.23 mm, 0.026 ms).
    EXPECT_LT(after.rotation_deg, 0.05);
    EXPECT_LT(after.translation_mm, 1.0);
    EXPECT_LT(after.time_offset_ms, 0.05);
    // Honest uncertainty: every error inside 3 sigma.
    EXPECT_LT(after.rotation_sigma_ratio.maxCoeff(), 3.0);
    EXPECT_LT(after.translation_sigma_ratio.maxCoeff(), 3.0);
    EXPECT_LT(after.time_offset_sigma_ratio, 3.0);
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
  // Measured 4.4 mm and 0.8 mm (seed 3); the bounds leave room for other seeds' convergence.
  EXPECT_LT(ate, 0.008);
  EXPECT_LT(ate_converged, 0.002);
}

}  // namespace
}  // namespace mvis
