// Checks of the estimator's options and of the rig they are used with, at creation.
#include <string>
#include <utility>
#include <vector>

#include "mvis/estimator/estimator.h"

namespace mvis {

namespace {

Status validateHolds(const Rig& rig, const std::vector<std::string>& hold) {
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

}  // namespace

Status validate(const EstimatorOptions& o) {
  auto bad = [](const std::string& key, const std::string& why) {
    return Status::Error("estimator option " + key + ": " + why);
  };
  if (o.window_size < 3) return bad("window_size", "must be at least 3");
  if (o.carried_tags < 0) return bad("carried_tags", "must be zero (every tag) or positive");
  if (o.max_iterations < 1) return bad("max_iterations", "must be at least 1");
  if (o.solve_every < 1 || o.solve_every > o.window_size - 2) {
    return bad("solve_every",
               "must be at least 1 and at most window_size - 2 (every state is solved with at "
               "least three later states before it is marginalized; with two, the time offsets "
               "came out biased on translation-only motion: doc/results.md)");
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
                               {"imu_max_gap_s", o.imu_max_gap_s},
                               {"observability_horizon_s", o.observability_horizon_s},
                               {"held_intrinsics_horizon_s", o.held_intrinsics_horizon_s},
                               {"imu_scale_misalignment_prior", o.imu_scale_misalignment_prior},
                               {"imu_gravity_sensitivity_prior", o.imu_gravity_sensitivity_prior},
                               {"imu_acc_rotation_prior_rad", o.imu_acc_rotation_prior_rad}}) {
    if (!(v > 0.0)) return bad(key, "must be positive");
  }
  if (o.covariance_every < 0) return bad("covariance_every", "must be zero or positive");
  if (!(o.imu_intrinsics_observability_ratio >= 0.0)) {
    return bad("imu_intrinsics_observability_ratio", "must be zero (off) or positive");
  }
  if (!(o.window_observability_ratio >= 0.0)) {
    return bad("window_observability_ratio", "must be zero (off) or positive");
  }
  if (!(o.observability_ratio >= 0.0)) {
    return bad("observability_ratio", "must be zero (off) or positive");
  }
  if (!(o.failure_step_sigma == 0.0 || o.failure_step_sigma >= 3.0)) {
    return bad("failure_step_sigma", "must be zero (off) or at least 3 (sigma)");
  }
  if (!(o.held_intrinsics_p >= 0.0 && o.held_intrinsics_p < 0.5)) {
    return bad("held_intrinsics_p", "must be zero (off) or a probability under 0.5");
  }
  if (!(o.frame_gate_sigma == 0.0 || o.frame_gate_sigma >= 3.0)) {
    return bad("frame_gate_sigma", "must be zero (off) or at least 3 (sigma)");
  }
  return Status::Ok();
}

Status validate(const EstimatorOptions& options, const Rig& rig) {
  Status valid = validate(options);
  if (!valid.ok()) return valid;
  if (rig.inertial.empty()) return Status::Error("the rig has no base IMU");
  if (rig.cameras.empty()) return Status::Error("the rig has no camera");
  Status holds_valid = validateHolds(rig, options.hold);
  if (!holds_valid.ok()) return holds_valid;
  if (options.estimate_imu_intrinsics && options.aux_imu_model == AuxImuModel::kRigidVelocity) {
    return Status::Error(
        "estimator options: estimate_imu_intrinsics needs aux_imu_model velocity_state (the "
        "rigid-velocity model reads the aux gyroscope uncorrected)");
  }
  return Status::Ok();
}

}  // namespace mvis
