#include "mvis/ros/nodelet_options.h"

namespace mvis {

NodeletOptions NodeletOptions::fromParameters(const ros::NodeHandle& nh) {
  NodeletOptions o;
  nh.param("config_dir", o.config_dir, o.config_dir);
  nh.param("imu_chain", o.imu_chain, o.imu_chain);
  nh.param("cam_chain", o.cam_chain, o.cam_chain);
  nh.param("target", o.target, o.target);
  nh.param("world_frame", o.world_frame, o.world_frame);
  nh.param("frame_prefix", o.frame_prefix, o.frame_prefix);
  nh.param("camera_input", o.camera_input, o.camera_input);
  nh.param("diagnostics_period", o.diagnostics_period_s, o.diagnostics_period_s);
  nh.param("sensor_timeout", o.sensor_timeout_s, o.sensor_timeout_s);
  nh.param("tag_decimate", o.tag_decimate, o.tag_decimate);
  nh.param("tag_refine_corners", o.tag_refine_corners, o.tag_refine_corners);
  nh.param("tag_max_hamming", o.tag_max_hamming, o.tag_max_hamming);
  nh.param("tag_threads", o.tag_threads, o.tag_threads);
  nh.param("window_size", o.window_size, o.window_size);
  nh.param("carried_tags", o.carried_tags, o.carried_tags);
  nh.param("window_own_tags", o.window_own_tags, o.window_own_tags);
  nh.param("pixel_sigma", o.pixel_sigma, o.pixel_sigma);
  nh.param("huber_sigma", o.huber_sigma, o.huber_sigma);
  nh.param("robust_loss", o.robust_loss, o.robust_loss);
  nh.param("propagation_noise", o.propagation_noise, o.propagation_noise);
  nh.param("min_tags", o.min_tags, o.min_tags);
  nh.param("imu_max_gap", o.imu_max_gap_s, o.imu_max_gap_s);
  nh.param("failure_step_sigma", o.failure_step_sigma, o.failure_step_sigma);
  nh.param("frame_gate_sigma", o.frame_gate_sigma, o.frame_gate_sigma);
  nh.param("detect_changes", o.detect_changes, o.detect_changes);
  nh.param("held_intrinsics_p", o.held_intrinsics_p, o.held_intrinsics_p);
  nh.param("estimate_extrinsics", o.estimate_extrinsics, o.estimate_extrinsics);
  nh.param("estimate_time_offsets", o.estimate_time_offsets, o.estimate_time_offsets);
  nh.param("estimate_aux_extrinsics", o.estimate_aux_extrinsics, o.estimate_aux_extrinsics);
  nh.param("estimate_aux_time_offsets", o.estimate_aux_time_offsets, o.estimate_aux_time_offsets);
  nh.param("estimate_intrinsics", o.estimate_intrinsics, o.estimate_intrinsics);
  nh.param("estimate_imu_intrinsics", o.estimate_imu_intrinsics, o.estimate_imu_intrinsics);
  nh.param("estimate_gravity_sensitivity", o.estimate_gravity_sensitivity,
           o.estimate_gravity_sensitivity);
  nh.param("hold", o.hold, o.hold);
  nh.param("aux_imu_model", o.aux_imu_model, o.aux_imu_model);
  nh.param("max_iterations", o.max_iterations, o.max_iterations);
  nh.param("solve_every", o.solve_every, o.solve_every);
  nh.param("observability_ratio", o.observability_ratio, o.observability_ratio);
  nh.param("observability_horizon", o.observability_horizon_s, o.observability_horizon_s);
  nh.param("imu_intrinsics_observability_ratio", o.imu_intrinsics_observability_ratio,
           o.imu_intrinsics_observability_ratio);
  nh.param("solver_threads", o.solver_threads, o.solver_threads);
  nh.param("result_dir", o.result_dir, o.result_dir);
  return o;
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
  if (tag_threads < 1) return "parameter ~tag_threads must be >= 1";
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
  return "";
}

}  // namespace mvis
