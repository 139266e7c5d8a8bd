// A bad configuration file is refused with one exact message: FILE: SENSOR: KEY: problem.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "mvis/rig/rig_io.h"
#include "rig_test_util.h"

namespace mvis {
namespace {

using test::replaced;
using test::validCamChain;
using test::validImuChain;

std::string imuError(const std::string& text) {
  const auto result = parseImuChain(text, "imu.yaml");
  return result.ok() ? "(accepted)" : result.status().message();
}

std::string camError(const std::string& text) {
  const auto result = parseCamChain(text, "cam.yaml");
  return result.ok() ? "(accepted)" : result.status().message();
}

TEST(RigIoErrors, TheValidFixturesAreValid) {
  EXPECT_EQ(imuError(validImuChain()), "(accepted)");
  EXPECT_EQ(camError(validCamChain()), "(accepted)");
}

TEST(RigIoErrors, MissingKey) {
  EXPECT_EQ(imuError(replaced(validImuChain(), "  rostopic: /imu1\n", "")),
            "imu.yaml: imu1: rostopic: missing");
  EXPECT_EQ(imuError(replaced(validImuChain(), "  gyroscope_random_walk: 1.0e-5\n", "")),
            "imu.yaml: imu2: gyroscope_random_walk: missing");
  EXPECT_EQ(camError(replaced(validCamChain(),
                              "  intrinsics: [458.654, 457.296, 367.215, 248.375]\n", "")),
            "cam.yaml: cam0: intrinsics: missing");
  const std::string no_extrinsic = validCamChain().substr(validCamChain().find("  cam_overlaps"));
  EXPECT_EQ(camError("cam0:\n" + no_extrinsic),
            "cam.yaml: cam0: T_cam_imu: missing (the camera's pose relative to imu0)");
}

TEST(RigIoErrors, NonOrthonormalRotation) {
  EXPECT_EQ(imuError(replaced(validImuChain(), "[0.0, -1.0, 0.0, 0.05]", "[0.0, -1.1, 0.0, 0.05]")),
            "imu.yaml: imu1: T_i_b: rotation part is not orthonormal (max |R^T R - I| = 0.21; up "
            "to 0.001 is taken as rounding)");
  EXPECT_EQ(camError(replaced(validCamChain(), "[0.0, -1.0, 0.0, 0.02]", "[0.0, 1.0, 0.0, 0.02]")),
            "cam.yaml: cam0: T_cam_imu: rotation part is a reflection (determinant -1)");
  EXPECT_EQ(imuError(replaced(validImuChain(), "    - [0.0, 0.0, 0.0, 1.0]\n  rostopic: /gyro",
                              "    - [0.0, 0.0, 1.0, 1.0]\n  rostopic: /gyro")),
            "imu.yaml: imu2: T_i_b: bottom row must be [0, 0, 0, 1]");
}

TEST(RigIoErrors, NotUpperTriangular) {
  EXPECT_EQ(imuError(replaced(validImuChain(), "[0.0, 0.998, 0.003]", "[0.01, 0.998, 0.003]")),
            "imu.yaml: imu0: Tw: must be upper triangular for model rpng (row 1, column 0 is "
            "0.01)");
  EXPECT_EQ(imuError(replaced(validImuChain(), "    - [0.0, 0.0, 1.002]\n",
                              "    - [0.0, 0.0, 1.002]\n  Ta:\n    - [1.0, 0.0, 0.0]\n"
                              "    - [0.0, 1.0, 0.0]\n    - [0.0, -0.2, 1.0]\n")),
            "imu.yaml: imu0: Ta: must be upper triangular for model rpng (row 2, column 1 is "
            "-0.2)");
  // The same matrices under model kalibr: lower triangular is required.
  EXPECT_EQ(imuError(replaced(validImuChain(), "model: rpng", "model: kalibr")),
            "imu.yaml: imu0: Tw: must be lower triangular for model kalibr (row 0, column 1 is "
            "0.002)");
}

TEST(RigIoErrors, NotANumber) {
  EXPECT_EQ(imuError(replaced(validImuChain(), "accelerometer_noise_density: 2.0e-3",
                              "accelerometer_noise_density: .nan")),
            "imu.yaml: imu0: accelerometer_noise_density: is not a finite number");
  EXPECT_EQ(camError(replaced(validCamChain(), "367.215", ".inf")),
            "cam.yaml: cam0: intrinsics: is not a finite number");
  EXPECT_EQ(imuError(replaced(validImuChain(), "update_rate: 400.0", "update_rate: fast")),
            "imu.yaml: imu0: update_rate: expected a number");
}

TEST(RigIoErrors, NegativeNoiseDensity) {
  EXPECT_EQ(imuError(replaced(validImuChain(), "gyroscope_noise_density: 1.0e-4",
                              "gyroscope_noise_density: -1.0e-4")),
            "imu.yaml: imu2: gyroscope_noise_density: must be positive, got -0.0001");
}

TEST(RigIoErrors, UnknownModel) {
  EXPECT_EQ(imuError(replaced(validImuChain(), "model: rpng", "model: magic")),
            "imu.yaml: imu0: model: unknown model 'magic' (expected calibrated, rpng or kalibr, "
            "or Kalibr's scale-misalignment)");
  EXPECT_EQ(
      imuError(replaced(validImuChain(), "model: rpng", "model: scale-misalignment-size-effect")),
      "imu.yaml: imu0: model: Kalibr's scale-misalignment-size-effect is not supported (mvis "
      "does not model the accelerometers' size effect); calibrate with Kalibr's "
      "scale-misalignment model, or use model: calibrated to take the readings as they are");
  EXPECT_EQ(
      imuError(replaced(validImuChain(), "sensor_type: gyroscope", "sensor_type: magnetometer")),
      "imu.yaml: imu2: sensor_type: unknown sensor type 'magnetometer' (expected imu or "
      "gyroscope)");
  EXPECT_EQ(
      camError(replaced(validCamChain(), "distortion_model: radtan", "distortion_model: fov")),
      "cam.yaml: cam0: distortion_model: Kalibr's distortion model 'fov' is not supported (mvis "
      "supports radtan and equidistant: calibrate with Kalibr's pinhole-radtan or pinhole-equi)");
  EXPECT_EQ(
      camError(replaced(validCamChain(), "distortion_model: radtan", "distortion_model: plumb")),
      "cam.yaml: cam0: distortion_model: unknown distortion model 'plumb' (expected radtan or "
      "equidistant)");
  EXPECT_EQ(camError(replaced(validCamChain(), "camera_model: pinhole", "camera_model: omni")),
            "cam.yaml: cam0: camera_model: Kalibr's camera model 'omni' is not supported (mvis "
            "supports pinhole, with radtan or equidistant distortion: calibrate with Kalibr's "
            "pinhole-radtan or pinhole-equi)");
}

TEST(RigIoErrors, CalibratedModelFixesIntrinsics) {
  EXPECT_EQ(imuError(replaced(validImuChain(), "model: rpng", "model: calibrated")),
            "imu.yaml: imu0: Tw: model is calibrated, which fixes it at its default; set model: "
            "rpng or kalibr to use it");
}

TEST(RigIoErrors, DuplicateTopic) {
  EXPECT_EQ(imuError(replaced(validImuChain(), "rostopic: /gyro", "rostopic: /imu0")),
            "imu.yaml: imu2: rostopic: '/imu0' is already used by imu0");
  const std::string two_cameras = validCamChain() + replaced(validCamChain(), "cam0:", "cam1:");
  EXPECT_EQ(camError(two_cameras),
            "cam.yaml: cam1: rostopic: '/cam0/image_raw' is already used by cam0");
}

TEST(RigIoErrors, DuplicateTopicAcrossFiles) {
  const auto dir = std::filesystem::temp_directory_path() / "mvis_test_duplicate_topic";
  std::filesystem::create_directories(dir);
  std::ofstream(dir / kImuChainFile) << validImuChain();
  std::ofstream(dir / kCamChainFile) << replaced(validCamChain(), "/cam0/image_raw", "/imu1");
  const auto rig = loadRig(dir.string());
  ASSERT_FALSE(rig.ok());
  EXPECT_EQ(rig.status().message(), (dir / kCamChainFile).string() +
                                        ": cam0: rostopic: '/imu1' is already used by imu1 in "
                                        "kalibr_imu_chain.yaml");
  std::filesystem::remove_all(dir);
}

TEST(RigIoErrors, BaseImuRules) {
  EXPECT_EQ(imuError(replaced(validImuChain(), "  rostopic: /imu0\n",
                              "  rostopic: /imu0\n  time_offset: 0.01\n")),
            "imu.yaml: imu0: time_offset: must be 0 for imu0, the base IMU (it defines the base "
            "clock)");
  EXPECT_EQ(imuError(replaced(validImuChain(), "imu0:\n", "imu0:\n  sensor_type: gyroscope\n")),
            "imu.yaml: imu0: sensor_type: imu0 is the base IMU and must be an imu, not a "
            "gyroscope");
}

TEST(RigIoErrors, SensorNumbering) {
  EXPECT_EQ(imuError(replaced(validImuChain(), "imu1:", "imu3:")),
            "imu.yaml: imu1: missing (sensors are numbered imu0, imu1, ... without gaps)");
  EXPECT_EQ(imuError(replaced(validImuChain(), "imu2:", "gyro:")),
            "imu.yaml: gyro: unexpected top-level key (expected imu0, imu1, ...)");
}

TEST(RigIoErrors, UnknownKeyIsATypo) {
  EXPECT_EQ(camError(replaced(validCamChain(), "timeshift_cam_imu:", "time_shift_cam_imu:")),
            "cam.yaml: cam0: time_shift_cam_imu: unknown key (a typo? see doc/conventions.md for "
            "the keys of this file)");
}

TEST(RigIoErrors, BothExtrinsicForms) {
  EXPECT_EQ(camError(replaced(validCamChain(), "  T_cam_imu:\n",
                              "  T_imu_cam: [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]\n"
                              "  T_cam_imu:\n")),
            "cam.yaml: cam0: T_imu_cam: give T_cam_imu or T_imu_cam, not both");
}

TEST(RigIoErrors, NegativeStandardDeviation) {
  EXPECT_EQ(camError(validCamChain() + "  timeshift_cam_imu_std: -0.001\n"),
            "cam.yaml: cam0: timeshift_cam_imu_std: must not be negative");
  EXPECT_EQ(imuError(validImuChain() +
                     "  T_i_b_std:\n    rotation: [0.1, 0.1]\n    translation: [0, 0, 0]\n"),
            "imu.yaml: imu2: T_i_b_std: rotation: expected a list of 3 numbers");
}

TEST(RigIoErrors, SyntaxError) {
  const std::string message = imuError("imu0:\n  rostopic: [unclosed\n");
  EXPECT_EQ(message.rfind("imu.yaml: line ", 0), 0u) << message;
}

TEST(RigIoErrors, AprilGrid) {
  const std::string valid =
      "target_type: aprilgrid\ntagCols: 6\ntagRows: 6\ntagSize: 0.088\ntagSpacing: 0.3\n";
  EXPECT_TRUE(parseAprilGrid(valid, "grid.yaml").ok());
  EXPECT_EQ(parseAprilGrid(valid + "tagFamily: tag99h1\n", "grid.yaml").status().message(),
            "grid.yaml: tagFamily: unknown tag family 'tag99h1'");
  EXPECT_EQ(
      parseAprilGrid(replaced(valid, "tagCols: 6", "tagCols: 2.5"), "grid.yaml").status().message(),
      "grid.yaml: tagCols: must be a positive whole number, got 2.5");
  EXPECT_EQ(
      parseAprilGrid(replaced(valid, "aprilgrid", "checkerboard"), "grid.yaml").status().message(),
      "grid.yaml: target_type: unsupported target type 'checkerboard' (expected aprilgrid)");
}

TEST(RigIoErrors, MissingDirectoryAndFile) {
  EXPECT_EQ(loadRig("/nonexistent/mvis").status().message(),
            "/nonexistent/mvis: not a directory (expected a configuration directory holding "
            "kalibr_imu_chain.yaml and kalibr_imucam_chain.yaml)");
  const auto dir = std::filesystem::temp_directory_path() / "mvis_test_missing_file";
  std::filesystem::create_directories(dir);
  std::ofstream(dir / kImuChainFile) << validImuChain();
  EXPECT_EQ(loadRig(dir.string()).status().message(),
            (dir / kCamChainFile).string() + ": cannot read the file");
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace mvis
