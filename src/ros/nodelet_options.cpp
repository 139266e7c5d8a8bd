#include "mvis/ros/nodelet_options.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <set>
#include <sstream>
#include <thread>
#include <type_traits>

namespace mvis {

namespace {

// Every key of config/mvis.yaml and its field: the one list both readers walk.
template <class Read>
void readKeys(NodeletOptions& o, Read&& read) {
  read("config_dir", o.config_dir);
  read("imu_chain", o.imu_chain);
  read("cam_chain", o.cam_chain);
  read("target", o.target);
  read("world_frame", o.world_frame);
  read("body_frame", o.body_frame);
  read("publish_tf", o.publish_tf);
  read("frame_prefix", o.frame_prefix);
  read("camera_input", o.camera_input);
  read("diagnostics_period", o.diagnostics_period_s);
  read("sensor_timeout", o.sensor_timeout_s);
  read("tag_decimate", o.tag_decimate);
  read("tag_refine_corners", o.tag_refine_corners);
  read("tag_max_hamming", o.tag_max_hamming);
  read("tag_threads", o.tag_threads);
  read("tag_full_search_every", o.tag_full_search_every);
  read("window_size", o.window_size);
  read("carried_tags", o.carried_tags);
  read("window_own_tags", o.window_own_tags);
  read("pixel_sigma", o.pixel_sigma);
  read("huber_sigma", o.huber_sigma);
  read("robust_loss", o.robust_loss);
  read("propagation_noise", o.propagation_noise);
  read("min_tags", o.min_tags);
  read("imu_max_gap", o.imu_max_gap_s);
  read("failure_step_sigma", o.failure_step_sigma);
  read("frame_gate_sigma", o.frame_gate_sigma);
  read("detect_changes", o.detect_changes);
  read("held_intrinsics_p", o.held_intrinsics_p);
  read("estimate_extrinsics", o.estimate_extrinsics);
  read("estimate_time_offsets", o.estimate_time_offsets);
  read("estimate_aux_extrinsics", o.estimate_aux_extrinsics);
  read("estimate_aux_time_offsets", o.estimate_aux_time_offsets);
  read("estimate_intrinsics", o.estimate_intrinsics);
  read("estimate_imu_intrinsics", o.estimate_imu_intrinsics);
  read("estimate_gravity_sensitivity", o.estimate_gravity_sensitivity);
  read("hold", o.hold);
  read("aux_imu_model", o.aux_imu_model);
  read("max_iterations", o.max_iterations);
  read("solve_every", o.solve_every);
  read("observability_ratio", o.observability_ratio);
  read("observability_horizon", o.observability_horizon_s);
  read("imu_intrinsics_observability_ratio", o.imu_intrinsics_observability_ratio);
  read("solver_threads", o.solver_threads);
  read("ready_rotation_deg", o.ready.rotation_deg);
  read("ready_camera_translation_mm", o.ready.camera_translation_mm);
  read("ready_imu_translation_mm", o.ready.imu_translation_mm);
  read("ready_time_offset_ms", o.ready.time_offset_ms);
  read("ready_camera_intrinsics_px", o.ready.camera_intrinsics_px);
  read("ready_camera_distortion", o.ready.camera_distortion);
  read("ready_imu_intrinsics", o.ready.imu_intrinsics);
  read("ready_gravity_sensitivity", o.ready.gravity_sensitivity);
  read("result_dir", o.result_dir);
  read("save_on_shutdown", o.save_on_shutdown);
}

}  // namespace

NodeletOptions NodeletOptions::fromParameters(const ros::NodeHandle& nh) {
  NodeletOptions o;
  readKeys(o, [&nh](const char* key, auto& value) { nh.param(key, value, value); });
  return o;
}

StatusOr<NodeletOptions> NodeletOptions::fromYamlFile(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    return Status::Error(path + ": cannot read it as YAML (" + e.what() + ")");
  }
  NodeletOptions o;
  if (root.IsNull()) return o;  // an empty file: the defaults
  if (!root.IsMap()) return Status::Error(path + ": expected a map of parameter: value");
  std::set<std::string> known;
  readKeys(o, [&known](const char* key, auto&) { known.insert(key); });
  for (const auto& entry : root) {
    const std::string key = entry.first.as<std::string>();
    if (known.count(key) == 0) {
      return Status::Error(path + ": unknown parameter '" + key +
                           "' (config/mvis.yaml lists every parameter)");
    }
  }
  std::string problem;
  readKeys(o, [&](const char* key, auto& value) {
    const YAML::Node node = root[key];
    if (!node || !problem.empty()) return;
    try {
      value = node.as<std::decay_t<decltype(value)>>();
    } catch (const YAML::Exception&) {
      problem = path + ": parameter '" + std::string(key) + "' has a value of the wrong type (" +
                YAML::Dump(node) + ")";
    }
  });
  if (!problem.empty()) return Status::Error(problem);
  return o;
}

std::vector<std::pair<std::string, std::string>> NodeletOptions::values() const {
  std::vector<std::pair<std::string, std::string>> out;
  NodeletOptions copy = *this;  // readKeys walks a mutable one
  readKeys(copy, [&out](const char* key, auto& value) {
    using T = std::decay_t<decltype(value)>;
    std::ostringstream text;
    if constexpr (std::is_same_v<T, bool>) {
      text << (value ? "true" : "false");
    } else if constexpr (std::is_same_v<T, std::vector<std::string>>) {
      text << "[";
      for (std::size_t i = 0; i < value.size(); ++i) text << (i ? ", " : "") << value[i];
      text << "]";
    } else {
      text << value;
    }
    out.emplace_back(key, text.str());
  });
  return out;
}

EstimatorOptions NodeletOptions::estimatorOptions() const {
  EstimatorOptions eo;
  eo.window_size = window_size;
  eo.carried_tags = carried_tags;
  eo.window_own_tags = window_own_tags;
  eo.pixel_sigma_px = pixel_sigma;
  eo.huber_sigma = huber_sigma;
  eo.robust_loss = robust_loss == "frame" ? RobustLoss::kFrame : RobustLoss::kCorner;
  eo.propagation_noise = propagation_noise;
  eo.min_tags = min_tags;
  eo.imu_max_gap_s = imu_max_gap_s;
  eo.failure_step_sigma = failure_step_sigma;
  eo.frame_gate_sigma = frame_gate_sigma;
  eo.detect_changes = detect_changes;
  eo.held_intrinsics_p = held_intrinsics_p;
  eo.estimate_extrinsics = estimate_extrinsics;
  eo.estimate_time_offsets = estimate_time_offsets;
  eo.estimate_aux_extrinsics = estimate_aux_extrinsics;
  eo.estimate_aux_time_offsets = estimate_aux_time_offsets;
  eo.estimate_intrinsics = estimate_intrinsics;
  eo.estimate_imu_intrinsics = estimate_imu_intrinsics;
  eo.estimate_gravity_sensitivity = estimate_gravity_sensitivity;
  eo.hold = hold;
  eo.aux_imu_model =
      aux_imu_model == "rigid_velocity" ? AuxImuModel::kRigidVelocity : AuxImuModel::kVelocityState;
  eo.max_iterations = max_iterations;
  eo.solve_every = solve_every;
  eo.observability_ratio = observability_ratio;
  eo.imu_intrinsics_observability_ratio = imu_intrinsics_observability_ratio;
  eo.observability_horizon_s = observability_horizon_s;
  eo.threads = solver_threads;
  return eo;
}

int NodeletOptions::tagThreads() const {
  return tag_threads > 0 ? tag_threads
                         : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

TagFrontendOptions NodeletOptions::frontendOptions() const {
  TagFrontendOptions fo;
  fo.detector.decimate = tag_decimate;
  fo.detector.refine_corners = tag_refine_corners;
  fo.detector.max_hamming = tag_max_hamming;
  fo.detector.threads = tagThreads();
  fo.full_search_every = tag_full_search_every;
  fo.checks.max_hamming = tag_max_hamming;
  return fo;
}

std::string NodeletOptions::validate() const {
  if (config_dir.empty()) {
    return "parameter ~config_dir is not set (the directory holding kalibr_imu_chain.yaml, "
           "kalibr_imucam_chain.yaml and optionally aprilgrid.yaml)";
  }
  if (world_frame.empty()) return "parameter ~world_frame must not be empty";
  if (camera_input != "image" && camera_input != "compressed" && camera_input != "tag_detections") {
    return "parameter ~camera_input must be 'image', 'compressed' or 'tag_detections', got '" +
           camera_input + "'";
  }
  if (!(diagnostics_period_s > 0.0)) return "parameter ~diagnostics_period must be positive";
  if (!(sensor_timeout_s > 0.0)) return "parameter ~sensor_timeout must be positive";
  if (!(tag_decimate >= 1.0)) return "parameter ~tag_decimate must be >= 1";
  if (tag_max_hamming < 0 || tag_max_hamming > 2) {
    return "parameter ~tag_max_hamming must be 0, 1 or 2";
  }
  if (tag_threads < 0) return "parameter ~tag_threads must be >= 0 (0: one per core)";
  if (tag_full_search_every < 1) return "parameter ~tag_full_search_every must be >= 1";
  if (window_size < 3) return "parameter ~window_size must be >= 3";
  if (carried_tags < 0) return "parameter ~carried_tags must be >= 0 (0: every tag)";
  if (!(observability_ratio >= 0.0)) {
    return "parameter ~observability_ratio must be >= 0 (0 turns the check off)";
  }
  if (!(imu_intrinsics_observability_ratio >= 0.0)) {
    return "parameter ~imu_intrinsics_observability_ratio must be >= 0 (0 turns it off)";
  }
  if (!(observability_horizon_s > 0.0)) return "parameter ~observability_horizon must be positive";
  if (!(pixel_sigma > 0.0)) return "parameter ~pixel_sigma must be positive";
  if (!(huber_sigma >= 0.0)) return "parameter ~huber_sigma must be >= 0 (0: no robust loss)";
  if (robust_loss != "corner" && robust_loss != "frame") {
    return "parameter ~robust_loss must be 'corner' or 'frame', got '" + robust_loss + "'";
  }
  if (min_tags < 1) return "parameter ~min_tags must be >= 1";
  if (!(imu_max_gap_s > 0.0)) return "parameter ~imu_max_gap must be positive";
  if (!(failure_step_sigma == 0.0 || failure_step_sigma >= 3.0)) {
    return "parameter ~failure_step_sigma must be 0 (off) or >= 3";
  }
  if (!(frame_gate_sigma == 0.0 || frame_gate_sigma >= 3.0)) {
    return "parameter ~frame_gate_sigma must be 0 (off) or >= 3";
  }
  if (!(held_intrinsics_p >= 0.0 && held_intrinsics_p < 0.5)) {
    return "parameter ~held_intrinsics_p must be 0 (off) or a probability under 0.5";
  }
  if (aux_imu_model != "velocity_state" && aux_imu_model != "rigid_velocity") {
    return "parameter ~aux_imu_model must be 'velocity_state' or 'rigid_velocity', got '" +
           aux_imu_model + "'";
  }
  if (max_iterations < 1) return "parameter ~max_iterations must be >= 1";
  if (solve_every < 1 || solve_every > window_size - 2) {
    return "parameter ~solve_every must be >= 1 and <= ~window_size - 2 (each state is solved "
           "with at least three later states before it is marginalized)";
  }
  if (solver_threads < 1) return "parameter ~solver_threads must be >= 1";
  const std::pair<const char*, double> targets[] = {
      {"ready_rotation_deg", ready.rotation_deg},
      {"ready_camera_translation_mm", ready.camera_translation_mm},
      {"ready_imu_translation_mm", ready.imu_translation_mm},
      {"ready_time_offset_ms", ready.time_offset_ms},
      {"ready_camera_intrinsics_px", ready.camera_intrinsics_px},
      {"ready_camera_distortion", ready.camera_distortion},
      {"ready_imu_intrinsics", ready.imu_intrinsics},
      {"ready_gravity_sensitivity", ready.gravity_sensitivity}};
  for (const auto& [key, value] : targets) {
    if (!(value > 0.0)) return "parameter ~" + std::string(key) + " must be positive";
  }
  return "";
}

}  // namespace mvis
