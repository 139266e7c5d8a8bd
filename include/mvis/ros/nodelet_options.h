// The nodelet's ROS parameters (private namespace), documented key by key in config/mvis.yaml.
#pragma once

#include <ros/node_handle.h>

#include <string>
#include <utility>
#include <vector>

#include "mvis/common/status.h"
#include "mvis/estimator/calibration_status.h"
#include "mvis/estimator/estimator.h"
#include "mvis/frontend/tag_frontend.h"

namespace mvis {

struct NodeletOptions {
  std::string config_dir;  // directory with the rig's yaml files (required)
  // Other names for the three files (relative to config_dir unless absolute; empty: the
  // defaults kalibr_imu_chain.yaml, kalibr_imucam_chain.yaml, aprilgrid.yaml).
  std::string imu_chain, cam_chain, target;
  std::string world_frame = "odom";  // TF/odometry parent frame (REP-105)
  std::string body_frame;            // odometry child frame; empty: <frame_prefix><base IMU>
  bool publish_tf = true;            // world -> body, body -> sensors, world -> board
  std::string frame_prefix;          // prepended to sensor names to form their TF frames
  // "image" (sensor_msgs/Image on the camera's rostopic), "compressed"
  // (sensor_msgs/CompressedImage on <rostopic>/compressed, decoded by mvis) or "tag_detections"
  std::string camera_input = "image";
  double diagnostics_period_s = 1.0;  // [s] between diagnostics messages
  double sensor_timeout_s = 1.0;      // [s] silence after which a sensor counts as stopped
  double tag_decimate = 1.0;          // quad search at 1/decimate resolution (>= 1)
  bool tag_refine_corners = true;     // mvis's edge-based sub-pixel corner refinement
  int tag_max_hamming = 1;            // bits the tag decoder may correct (0..2)
  // Threads detecting tags, 0: one per core; above 1 the cameras' images are detected in
  // parallel (and libapriltag gets as many threads).
  int tag_threads = 0;
  int tagThreads() const;          // tag_threads, 0 resolved
  int tag_full_search_every = 10;  // images; between, tags are searched where predicted (1: off)
  // Estimator (see config/mvis.yaml and include/mvis/estimator/estimator.h).
  int window_size = 5;                 // states in the sliding window
  int carried_tags = 12;               // without a board: tags carried in the prior (0: all)
  bool window_own_tags = true;         // without a board: use the tags beyond them
  double pixel_sigma = 1.0;            // [px] corner noise
  double huber_sigma = 3.0;            // [sigma] camera factors' robust loss, 0: none
  std::string robust_loss = "corner";  // where it acts: "corner" or "frame"
  bool propagation_noise = false;      // frames between states carry the IMU's noise
  int min_tags = 2;                    // tags a frame needs with a board (1 without)
  double imu_max_gap_s = 0.03;  // [s] longer base-IMU holes restart from the trusted calibration
  double failure_step_sigma = 10.0;       // [sigma] calibration step that is a failure, 0: off
  bool detect_changes = true;             // a sensor that moved is found and re-calibrated
  double frame_gate_sigma = 10.0;         // [pixel_sigma] frames this far off are dropped, 0: off
  double held_intrinsics_p = 1e-4;        // false-alarm rate of the held-Tg test, 0: off
  bool estimate_extrinsics = true;        // camera-IMU extrinsics
  bool estimate_time_offsets = true;      // camera time offsets
  bool estimate_aux_extrinsics = true;    // T_i_b of aux IMUs (rotation of gyroscopes)
  bool estimate_aux_time_offsets = true;  // time_offset of aux IMUs and gyroscopes
  bool estimate_intrinsics = false;       // every camera's intrinsics and distortion
  bool estimate_imu_intrinsics = false;   // rpng and kalibr sensors' intrinsics
  bool estimate_gravity_sensitivity = false;        // and their Tg
  std::vector<std::string> hold;                    // "<sensor>.<quantity>" held (EstimatorOptions)
  std::string aux_imu_model = "velocity_state";     // or "rigid_velocity" (report Appendix B)
  int max_iterations = 10;                          // per solve
  int solve_every = 3;                              // solve after every n-th cam0 frame
  double observability_ratio = 500.0;               // EstimatorOptions; 0: no degeneracy check
  double imu_intrinsics_observability_ratio = 1.0;  // EstimatorOptions; 0: off
  double observability_horizon_s = 5.0;             // [s] motion the check looks back over
  int solver_threads = 1;                           // Ceres threads
  // Guided calibration: the sigma at which each kind of quantity counts as converged (the
  // ready_* keys).
  StatusTargets ready;
  // Parent of the result directories: each save writes a new <result_dir>/<UTC time> (empty:
  // $ROS_HOME/mvis_results); on shutdown only with save_on_shutdown.
  std::string result_dir;
  bool save_on_shutdown = true;

  // The estimator's and the tag front end's options these parameters set (both runners).
  EstimatorOptions estimatorOptions() const;
  TagFrontendOptions frontendOptions() const;
  StatusTargets statusTargets() const { return ready; }

  // Empty when the options are usable, else what is wrong, naming the parameter.
  std::string validate() const;
  static NodeletOptions fromParameters(const ros::NodeHandle& private_nh);
  // The same keys from a YAML file (config/mvis.yaml; mvis_offline --params). A key it does not
  // know or a value of the wrong type is refused, naming the file and the key.
  static StatusOr<NodeletOptions> fromYamlFile(const std::string& path);
  // Every key with its value as text, in config/mvis.yaml's order (the report, the tests).
  std::vector<std::pair<std::string, std::string>> values() const;
};

}  // namespace mvis
