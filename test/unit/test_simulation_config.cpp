// The simulation yaml: the shipped file parses, and a bad one is refused naming file and key.
#include <gtest/gtest.h>

#include "mvis/sim/simulation_config.h"

namespace mvis {
namespace {

const std::string kValid =
    "duration_s: 20\nseed: 7\nmotion: yaw_only\ncamera_rate_hz: [30, 25]\n"
    "camera_output: detections\nperturbation:\n  camera_rotation_deg: 1.0\n";

std::string error(const std::string& text) {
  const auto parsed = parseSimulationConfig(text, "sim.yaml", 2);
  return parsed.ok() ? "(accepted)" : parsed.status().message();
}

TEST(SimulationConfig, TheShippedFileParses) {
  const auto config =
      loadSimulationConfig(std::string(MVIS_SOURCE_DIR) + "/config/sim_vi_rig/sim.yaml", 3);
  ASSERT_TRUE(config.ok()) << config.status().message();
  EXPECT_EQ(config.value().camera_rate_hz, (std::vector<double>{30.0, 25.0, 30.0}));
  EXPECT_EQ(config.value().start_ns, 1700000000LL * kNsPerSecond);
  EXPECT_EQ(config.value().camera_output, CameraOutput::kImages);
  EXPECT_NEAR(config.value().perturbation.camera_rotation_rad, 2.0 * M_PI / 180.0, 1e-15);
}

TEST(SimulationConfig, ReadsWhatItIsGiven) {
  const auto config = parseSimulationConfig(kValid, "sim.yaml", 2);
  ASSERT_TRUE(config.ok()) << config.status().message();
  EXPECT_EQ(config.value().duration_s, 20.0);
  EXPECT_EQ(config.value().seed, 7u);
  EXPECT_EQ(config.value().motion.kind, MotionKind::kYawOnly);
  EXPECT_EQ(config.value().camera_output, CameraOutput::kDetections);
  EXPECT_NEAR(config.value().perturbation.camera_rotation_rad, M_PI / 180.0, 1e-15);
  // Untouched perturbations keep their defaults.
  EXPECT_EQ(config.value().perturbation.aux_translation_m, PerturbationSizes().aux_translation_m);
}

TEST(SimulationConfig, KeepsNanosecondsOfTheStartTime) {
  const auto config =
      parseSimulationConfig(kValid + "start_time_s: 1700000000.123456789\n", "sim.yaml", 2);
  ASSERT_TRUE(config.ok());
  // A double holds 1700000000.123456789 to ~0.2 us; the fraction is taken apart from the
  // whole seconds, so the stamp is within a microsecond rather than off by 0.2 us + rounding.
  EXPECT_NEAR(static_cast<double>(config.value().start_ns - 1700000000LL * kNsPerSecond),
              123456789.0, 1000.0);
}

TEST(SimulationConfig, RefusesBadFilesNamingTheKey) {
  EXPECT_EQ(error(kValid), "(accepted)");
  EXPECT_EQ(error("motion: sideways\ncamera_rate_hz: [30, 25]\n"),
            "sim.yaml: motion: unknown motion 'sideways' (expected handheld, yaw_only or "
            "translation_only)");
  EXPECT_EQ(error("camera_rate_hz: [30, 25, 30]\n"),
            "sim.yaml: camera_rate_hz: expected a list of 2 numbers");
  EXPECT_EQ(error("camera_rate_hz: [30, 0]\n"),
            "sim.yaml: camera_rate_hz: every rate must be positive");
  EXPECT_EQ(error("duration_s: -5\ncamera_rate_hz: [30, 25]\n"),
            "sim.yaml: duration_s: must be positive, got -5.0");
  EXPECT_EQ(error("camera_rate_hz: [30, 25]\npixel_noise_px: -1\n"),
            "sim.yaml: pixel_noise_px: must not be negative");
  EXPECT_EQ(error("camera_rate_hz: [30, 25]\ncamera_output: video\n"),
            "sim.yaml: camera_output: unknown camera output 'video' (expected images or "
            "detections)");
  EXPECT_EQ(error("camera_rate_hz: [30, 25]\nduraton_s: 5\n"),
            "sim.yaml: duraton_s: unknown key (a typo? see doc/conventions.md for the keys of "
            "this file)");
  EXPECT_EQ(error("camera_rate_hz: [30, 25]\nperturbation:\n  camera_roll_deg: 1\n"),
            "sim.yaml: perturbation: camera_roll_deg: unknown key (a typo? see "
            "doc/conventions.md for the keys of this file)");
  EXPECT_EQ(error("duration_s: 5\n"), "sim.yaml: camera_rate_hz: missing");
  EXPECT_EQ(error("camera_rate_hz: [30, 25]\nrenderer: raytraced\n"),
            "sim.yaml: renderer: unknown renderer 'raytraced' (expected sampled or coverage)");
  EXPECT_EQ(error("camera_rate_hz: [30, 25]\nimage_gamma: 2.2\n"),
            "sim.yaml: image_gamma: needs renderer: coverage");
  EXPECT_EQ(error("camera_rate_hz: [30, 25]\nrenderer: coverage\nimage_vignetting: 1.5\n"),
            "sim.yaml: image_vignetting: must be under 1");
  EXPECT_EQ(error("camera_rate_hz: [30, 25]\nrenderer: coverage\nimage_gamma: 2.2\n"),
            "(accepted)");
}

// Sensors that move: read by name, in degrees and metres; an unknown key or sensor is refused.
TEST(SimulationConfig, ReadsMovesAndRefusesUnknownSensors) {
  const auto config = parseSimulationConfig(
      kValid + "moves:\n  cam1: {at_s: 12.5, rotation_deg: [0, 0, 1.5], translation_m: [0.005, 0, "
               "0]}\n",
      "sim.yaml", 2);
  ASSERT_TRUE(config.ok()) << config.status().message();
  ASSERT_EQ(config.value().moves.size(), 1u);
  const SensorMove& m = config.value().moves[0];
  EXPECT_EQ(m.sensor, "cam1");
  EXPECT_EQ(m.at_s, 12.5);
  EXPECT_NEAR(m.rotation_rad.z(), 1.5 * M_PI / 180.0, 1e-15);
  EXPECT_EQ(m.translation_m, Eigen::Vector3d(0.005, 0.0, 0.0));
  EXPECT_EQ(error(kValid + "moves:\n  cam1: {at: 3}\n"),
            "sim.yaml: moves: cam1: at: unknown key (a typo? see doc/conventions.md for the keys "
            "of this file)");
  Rig rig;
  rig.cameras.resize(1);
  rig.cameras[0].name = "cam0";
  const auto moved = movedRig(rig, config.value().moves);
  ASSERT_FALSE(moved.ok());
  EXPECT_EQ(moved.status().message(),
            "moves: cam1: no camera or auxiliary inertial sensor of that name in the rig");
  // The move itself: T_cam_imu' = Delta T_cam_imu.
  rig.cameras[0].name = "cam1";
  const auto ok = movedRig(rig, config.value().moves);
  ASSERT_TRUE(ok.ok());
  EXPECT_NEAR(ok.value().cameras[0].T_cam_imu.p.x(), 0.005, 1e-15);
  EXPECT_NEAR(Eigen::AngleAxisd(ok.value().cameras[0].T_cam_imu.q).angle(), 1.5 * M_PI / 180.0,
              1e-12);
}

}  // namespace
}  // namespace mvis
