// Simulated runs through the estimator, shared by the estimator tests: a run of the simulator
// recorded in arrival order, the estimator fed with it, and errors against the truth.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "mvis/estimator/estimator.h"
#include "mvis/estimator/evaluation.h"
#include "mvis/rig/rig_io.h"
#include "mvis/sim/simulation.h"

namespace mvis::test {

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

inline SimRun simulate(const std::string& rig_dir, double duration_s, std::uint64_t seed,
                       MotionKind motion = MotionKind::kHandheld, bool perturb_intrinsics = false,
                       const std::function<void(Rig*)>& edit_truth = nullptr,
                       const std::function<void(SimulationConfig*)>& edit_config = nullptr) {
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
  if (edit_config) edit_config(&config);
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

// The VI-Rig without any noise (IMU and corners exact), from the same rough guess as the noisy
// runs: what is left is bias in the model itself.
inline SimRun simulateNoiseFree(double duration_s, std::uint64_t seed) {
  return simulate("sim_vi_rig", duration_s, seed, MotionKind::kHandheld, false, nullptr,
                  [](SimulationConfig* c) {
                    c->imu_noise = false;
                    c->pixel_noise_px = 0.0;
                  });
}

// The solver's time budget makes results depend on the machine's load; tests lift it.
inline EstimatorOptions deterministic() {
  EstimatorOptions o;
  o.max_solve_time_s = 1e3;
  o.init_solve_time_s = 1e3;
  return o;
}

inline void feed(const SimRun& run, Estimator* estimator) {
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
inline std::unique_ptr<Estimator> runFrom(const Rig& guess, const SimRun& run,
                                          const EstimatorOptions& options,
                                          EstimatorUpdate* last = nullptr) {
  auto created = Estimator::create(guess, options);
  EXPECT_TRUE(created.ok()) << created.status().message();
  if (!created.ok()) return nullptr;
  std::unique_ptr<Estimator> estimator = std::move(created).value();
  if (last != nullptr)
    estimator->setUpdateCallback([last](const EstimatorUpdate& u) { *last = u; });
  feed(run, estimator.get());
  EXPECT_TRUE(estimator->initialized())
      << estimator->status() << "; last restart: " << estimator->lastRestart().reason;
  EXPECT_TRUE(estimator->computeCovariance().ok());
  // No simulated run here moves a sensor (test_estimator_changes does): none is declared moved
  // (but with plain squares wrong detections pull the estimate centimetres off, and the clean
  // corners then disagree with it).
  if (options.huber_sigma > 0.0) {
    EXPECT_EQ(estimator->counters().calibration_changes, 0)
        << (estimator->changes().empty() ? "" : estimator->changes().front().text);
  }
  if (!estimator->initialized()) return nullptr;
  return estimator;
}

struct CameraErrors {
  double rotation_deg, translation_mm, time_offset_ms;
  Eigen::Vector3d rotation_sigma_ratio, translation_sigma_ratio;  // |error| / std per axis
  double time_offset_sigma_ratio;
};

inline CameraErrors errors(const Camera& truth, const Camera& estimate) {
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
inline CameraErrors inertialErrors(const InertialSensor& truth, const InertialSensor& estimate) {
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

// The checks a camera or auxiliary sensor passes after a run: the absolute bounds and every
// error inside 3 sigma.
inline void expectCalibrated(const CameraErrors& e, const std::string& name, double rotation_deg,
                             double translation_mm, double time_offset_ms) {
  EXPECT_LT(e.rotation_deg, rotation_deg) << name;
  EXPECT_LT(e.translation_mm, translation_mm) << name;
  EXPECT_LT(e.time_offset_ms, time_offset_ms) << name;
  EXPECT_LT(e.rotation_sigma_ratio.maxCoeff(), 3.0) << name;
  EXPECT_LT(e.translation_sigma_ratio.maxCoeff(), 3.0) << name;
  EXPECT_LT(e.time_offset_sigma_ratio, 3.0) << name;
}

// The truth's pose at t, interpolated as the report's Appendix A.2 (lie::interpolatePose).
inline SE3 truthAt(const std::vector<StampedPose>& truth, TimeNs t) {
  auto after = std::lower_bound(truth.begin(), truth.end(), t,
                                [](const StampedPose& p, TimeNs s) { return p.first < s; });
  if (after == truth.begin()) return after->second;
  if (after == truth.end()) return truth.back().second;
  const auto before = std::prev(after);
  return lie::interpolatePose(
      before->second, after->second,
      static_cast<double>(t - before->first) / static_cast<double>(after->first - before->first));
}

}  // namespace mvis::test
