// Simulated measurements of a whole rig looking at its tag board.
//
// World {G} = the board frame of aprilgrid.yaml, lying flat (z up, gravity along -z); the rig
// moves above it with cam0 looking down at the board. Stamps: each sensor in its own clock,
// t_sensor = t_base - offset (Kalibr convention), base clock starting at t0_ns.
#pragma once

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "mvis/frontend/tag_observation.h"
#include "mvis/rig/rig.h"
#include "mvis/sim/imu_simulator.h"
#include "mvis/sim/tag_renderer.h"
#include "mvis/sim/trajectory.h"

namespace mvis {

enum class MotionKind {
  kHandheld,         // all six axes excited (report Fig. 5 left)
  kYawOnly,          // rotation about the world z axis only (report Table 2, 1-axis)
  kTranslationOnly,  // no rotation at all (report Tables 2-3)
};

// Parses "handheld", "yaw_only", "translation_only"; false for anything else.
bool parseMotionKind(const std::string& text, MotionKind* kind);
const char* toString(MotionKind kind);

struct MotionOptions {
  MotionKind kind = MotionKind::kHandheld;
  double height_m = 1.2;  // mean height of imu0 above the board [m]
  // Scales every swing (position and angle). At 0.8 and 1.2 m the VI-Rig turns at up to
  // 0.9 rad/s and its narrow cam1 keeps at least 9 of the 36 tags in view.
  double amplitude = 0.8;
};

// A smooth trajectory of imu0 above the board's centre, cam0 looking down at t = 0.
SinusoidTrajectory makeBoardTrajectory(const Rig& rig, const MotionOptions& options);

// Tag corners `camera` sees at its sensor-clock stamps from start_ns to end_ns at `rate_hz`:
// the true projections of the board corners plus Gaussian pixel noise [px] (0 for none). A
// tag is kept when all four corners lie inside the image (half a pixel margin) in front of
// the camera.
std::vector<TagFrame> simulateTagFrames(const Rig& rig, std::size_t camera, double rate_hz,
                                        const TrajectoryFunction& base, TimeNs t0_ns,
                                        TimeNs start_ns, TimeNs end_ns, double pixel_noise_px,
                                        std::uint64_t seed);

// Pose of camera `camera` in the world at its own sensor-clock stamp.
SE3 cameraPose(const Rig& rig, std::size_t camera, const TrajectoryFunction& base, TimeNs t0_ns,
               TimeNs stamp_ns);

// The pixel-to-board map of a camera with its distortion, for TagBoardRenderer (pixels where
// the distortion cannot be inverted see nothing).
PixelToBoard cameraToBoard(const Camera& camera, const SE3& T_G_C);

// How far a user's rough initial calibration is from the truth: every quantity gets zero-mean
// Gaussian noise with these standard deviations (the report's Table 4 uses the same idea).
struct PerturbationSizes {
  double camera_rotation_rad = 0.035;  // ~2 deg per axis
  double camera_translation_m = 0.02;
  double camera_time_offset_s = 0.01;
  double camera_focal_px = 0.0;  // off unless intrinsics are calibrated
  double camera_centre_px = 0.0;
  double camera_distortion = 0.0;
  double aux_rotation_rad = 0.035;
  double aux_translation_m = 0.01;
  double aux_time_offset_s = 0.005;
  double imu_scale_misalignment = 0.0;   // each upper-triangular element of Tw, Ta
  double imu_gravity_sensitivity = 0.0;  // each element of Tg
  double imu_acc_rotation_rad = 0.0;     // R_IMUtoACC (kalibr model: R_IMUtoGYRO)
};

// The truth with every calibration quantity perturbed (imu0's extrinsic and offset stay
// identity and zero: they define the base). Same seed, same result.
Rig perturbRig(const Rig& truth, const PerturbationSizes& sizes, std::uint64_t seed);

}  // namespace mvis
