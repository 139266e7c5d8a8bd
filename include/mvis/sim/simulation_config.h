// The simulation yaml: what to simulate on top of a rig description (the truth). Every key is
// documented in config/sim_vi_rig/sim.yaml.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "mvis/common/status.h"
#include "mvis/common/time.h"
#include "mvis/sim/rig_simulator.h"
#include "mvis/sim/tag_renderer.h"

namespace mvis {

enum class CameraOutput { kImages, kDetections };

// A sensor that moves during the recording (a knocked mount): from `at_s` on, its extrinsic is
// the true one moved by [rotation, translation] in its own frame (T_s_b' = Delta T_s_b for a
// camera's T_cam_imu or an auxiliary sensor's T_i_b, Delta = (Exp(rotation), translation)), and
// its time offset (timeshift_cam_imu, time_offset) is the true one plus time_offset_s.
struct SensorMove {
  std::string sensor;  // a camera's or auxiliary inertial sensor's name
  double at_s = 0.0;   // [s] from the first sample; 0: the whole recording
  Eigen::Vector3d rotation_rad = Eigen::Vector3d::Zero();   // rotation vector [rad]
  Eigen::Vector3d translation_m = Eigen::Vector3d::Zero();  // [m]
  double time_offset_s = 0.0;  // added to its time offset (a clock reset) [s]
};

struct SimulationConfig {
  double duration_s = 60.0;
  std::uint64_t seed = 1;
  TimeNs start_ns = 1700000000LL * kNsPerSecond;  // base-clock time of the first sample
  MotionOptions motion;
  std::vector<double> camera_rate_hz;  // one per camera of the rig
  CameraOutput camera_output = CameraOutput::kImages;
  double pixel_noise_px = 0.5;               // detections: Gaussian noise on true corners [px]
  double image_noise_sigma = 2.0;            // images: Gaussian intensity noise [0..255]
  int supersample = 3;                       // images: anti-aliasing samples per pixel and axis
  BoardKind board = BoardKind::kKalibrGrid;  // images: the printed board
  double image_blur_px = 0.0;                // images: Gaussian blur of the optics [px]
  // images: the renderer. false: TagBoardRenderer (sampled reflectance); true: exact area
  // coverage (coverage_renderer.h), with a camera response and vignetting.
  bool coverage_renderer = false;
  double image_gamma = 1.0;        // coverage renderer: response, out = 255 (in/255)^(1/gamma)
  double image_vignetting = 0.0;   // coverage renderer: irradiance lost at the image's corners
  bool imu_noise = true;           // white noise and bias random walks on inertial data
  int threads = 2;                 // images: rendering threads (same images for any number)
  PerturbationSizes perturbation;  // of the written initial guess
  std::vector<SensorMove> moves;   // sensors that move during the recording
};

// The rig after the moves (the truth at the recording's end); an error names an unknown sensor.
StatusOr<Rig> movedRig(const Rig& truth, const std::vector<SensorMove>& moves);

// Parses the simulation yaml; `num_cameras` is the rig's, to check camera_rate_hz. Errors name
// the file and key: "FILE: KEY: problem".
StatusOr<SimulationConfig> parseSimulationConfig(const std::string& yaml_text,
                                                 const std::string& path, std::size_t num_cameras);
StatusOr<SimulationConfig> loadSimulationConfig(const std::string& path, std::size_t num_cameras);

}  // namespace mvis
