// Faults (mvis/sim/faults.h) injected into a simulated run and fed to the estimator, for the
// fault suite: the run's messages as streams named by sensor, the faults applied, each message
// delivered with its new stamp (corrupt ones non-finite or with their corners moved far).
#pragma once

#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include "estimator_test_util.h"
#include "mvis/sim/faults.h"

namespace mvis::test {

// What a faulted run ended with: every camera's and auxiliary sensor's calibration errors.
struct FaultOutcome {
  std::vector<std::string> names;
  std::vector<CameraErrors> errors;
  // Per sensor the standard deviations of the same norms: rotation [deg], translation [mm] and
  // time offset [ms] (the norm of the per-axis standard deviations).
  std::vector<Eigen::Vector3d> sigmas;
  EstimatorCounters counters;
  std::vector<std::string> warnings;       // every distinct status message
  std::vector<CalibrationChange> changes;  // every change of a sensor's calibration declared
  bool initialized = false;
  // The worst translation error [mm], rotation [deg] and time offset [ms], and the largest error
  // over sigma of any element.
  double translation_mm = 0.0, rotation_deg = 0.0, time_offset_ms = 0.0, sigma_ratio = 0.0;
};

inline void feedWithFaults(const SimRun& run, const std::vector<Fault>& faults,
                           Estimator* estimator, std::vector<std::string>* warnings) {
  const auto events = run.data.events();
  std::vector<StreamMessage> messages;
  messages.reserve(events.size());
  for (const auto& e : events) {
    if (e.kind == 0) {
      messages.push_back({run.truth.inertial[run.data.imu_samples[e.index].first].name, e.stamp});
    } else {
      messages.push_back({run.truth.cameras[run.data.frames[e.index].camera].name, e.stamp});
    }
  }
  for (const FaultedMessage& m : applyFaults(messages, faults, 7)) {
    const auto& e = events[m.source];
    Status s = Status::Ok();
    if (e.kind == 0) {
      const auto& [sensor, sample] = run.data.imu_samples[e.index];
      ImuMeasurement reading{m.stamp_ns, sample.gyro, sample.accel};
      if (m.corrupt) reading.gyro.x() = std::numeric_limits<double>::quiet_NaN();
      s = estimator->addImu(sensor, reading);
    } else {
      TagFrame frame = run.data.frames[e.index];
      frame.stamp_ns = m.stamp_ns;
      if (m.corrupt) {
        for (auto& tag : frame.tags) {
          for (auto& c : tag.corners_px) c += Eigen::Vector2d(40.0, -25.0);
        }
      }
      s = estimator->addTagFrame(frame);
    }
    if (!s.ok() && warnings != nullptr &&
        std::find(warnings->begin(), warnings->end(), s.message()) == warnings->end() &&
        warnings->size() < 5000) {
      warnings->push_back(s.message());
    }
  }
}

inline FaultOutcome runWithFaults(const SimRun& run, const std::string& faults,
                                  const EstimatorOptions& options) {
  FaultOutcome out;
  std::vector<Fault> parsed;
  if (!faults.empty()) {
    auto p = parseFaults(faults);
    EXPECT_TRUE(p.ok()) << p.status().message();
    if (!p.ok()) return out;
    parsed = p.value();
  }
  auto created = Estimator::create(run.guess, options);
  EXPECT_TRUE(created.ok()) << created.status().message();
  if (!created.ok()) return out;
  auto estimator = std::move(created).value();
  feedWithFaults(run, parsed, estimator.get(), &out.warnings);
  out.initialized = estimator->initialized();
  out.counters = estimator->counters();
  out.changes = estimator->changes();
  if (!out.initialized) return out;
  EXPECT_TRUE(estimator->computeCovariance().ok());
  const Rig rig = estimator->calibration();
  const auto take = [&](const std::string& name, const CameraErrors& e) {
    out.names.push_back(name);
    out.errors.push_back(e);
    out.translation_mm = std::max(out.translation_mm, e.translation_mm);
    out.rotation_deg = std::max(out.rotation_deg, e.rotation_deg);
    out.time_offset_ms = std::max(out.time_offset_ms, e.time_offset_ms);
    out.sigma_ratio = std::max({out.sigma_ratio, e.rotation_sigma_ratio.maxCoeff(),
                                e.translation_sigma_ratio.maxCoeff(), e.time_offset_sigma_ratio});
  };
  for (std::size_t c = 0; c < rig.cameras.size(); ++c) {
    take(rig.cameras[c].name, errors(run.truth.cameras[c], rig.cameras[c]));
    const auto& sd = rig.cameras[c].std;
    out.sigmas.push_back(!sd ? Eigen::Vector3d::Zero()
                             : Eigen::Vector3d(sd->rotation.norm() * 180.0 / M_PI,
                                               sd->translation.norm() * 1e3,
                                               sd->timeshift_cam_imu * 1e3));
  }
  for (std::size_t i = 1; i < rig.inertial.size(); ++i) {
    take(rig.inertial[i].name, inertialErrors(run.truth.inertial[i], rig.inertial[i]));
    const auto& sd = rig.inertial[i].std;
    out.sigmas.push_back(!sd ? Eigen::Vector3d::Zero()
                             : Eigen::Vector3d(sd->rotation.norm() * 180.0 / M_PI,
                                               sd->translation.norm() * 1e3,
                                               sd->time_offset * 1e3));
  }
  return out;
}

inline void print(const std::string& label, const FaultOutcome& o) {
  std::printf(
      "%-28s %s restarts %ld failures %ld rejected %ld: worst %.4f deg %.3f mm %.4f ms, %.2f "
      "sigma\n",
      label.c_str(), o.initialized ? "ok" : "NOT INITIALIZED", o.counters.restarts,
      o.counters.failures, o.counters.frames_rejected, o.rotation_deg, o.translation_mm,
      o.time_offset_ms, o.sigma_ratio);
  for (std::size_t i = 0; i < o.names.size(); ++i) {
    const CameraErrors& e = o.errors[i];
    std::printf("    %-6s %.4f deg %.3f mm %.4f ms  sigma ratios r %.2f t %.2f dt %.2f\n",
                o.names[i].c_str(), e.rotation_deg, e.translation_mm, e.time_offset_ms,
                e.rotation_sigma_ratio.maxCoeff(), e.translation_sigma_ratio.maxCoeff(),
                e.time_offset_sigma_ratio);
  }
  for (std::size_t i = 0; i < o.warnings.size() && i < 6; ++i) {
    std::printf("    | %s\n", o.warnings[i].c_str());
  }
}

}  // namespace mvis::test
