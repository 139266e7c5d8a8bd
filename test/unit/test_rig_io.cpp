// Rig files: reading the shipped configs, and writing then reading gives the same rig.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "mvis/rig/rig_io.h"
#include "rig_test_util.h"

using mvis::test::expectSameRig;
using mvis::test::expectSameTransform;

namespace mvis {
namespace {

namespace fs = std::filesystem;

fs::path freshDirectory(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("mvis_test_" + name);
  fs::remove_all(dir);
  return dir;
}

TEST(RigIo, LoadsTheShippedVIRig) {
  const auto rig = loadRig(std::string(MVIS_SOURCE_DIR) + "/config/sim_vi_rig");
  ASSERT_TRUE(rig.ok()) << rig.status().message();
  const Rig& r = rig.value();
  ASSERT_EQ(r.inertial.size(), 3u);
  EXPECT_EQ(r.inertial[0].update_rate, 500.0);
  EXPECT_EQ(r.inertial[0].model, ImuModel::kRpng);
  EXPECT_EQ(r.inertial[1].update_rate, 100.0);
  EXPECT_EQ(r.inertial[2].type, InertialType::kGyroscope);
  ASSERT_EQ(r.cameras.size(), 3u);
  EXPECT_EQ(r.cameras[0].distortion_model, DistortionModel::kEquidistant);
  EXPECT_EQ(r.cameras[1].distortion_model, DistortionModel::kRadtan);
  EXPECT_EQ(r.cameras[1].resolution, (std::array<int, 2>{752, 480}));
  ASSERT_TRUE(r.target.has_value());
  // Tag 7 (column 1, row 1) of the 6x6 grid: bottom-left at (1.3 * 0.088) in x and y.
  EXPECT_TRUE(r.target->corner(7, 0).isApprox(Eigen::Vector3d(0.1144, 0.1144, 0.0), 1e-12));
  EXPECT_TRUE(r.target->corner(7, 2).isApprox(Eigen::Vector3d(0.2024, 0.2024, 0.0), 1e-12));
  // cam0 sits 10 cm ahead of imu0, looking along its x axis (z_cam ~ x_imu).
  const SE3 T_imu_cam0 = r.cameras[0].T_cam_imu.inverse();
  EXPECT_NEAR(T_imu_cam0.p.x(), 0.10, 1e-12);
  EXPECT_GT((T_imu_cam0.rotation() * Eigen::Vector3d::UnitZ()).x(), 0.99);
}

TEST(RigIo, WriteThenReadGivesTheSameRig) {
  const auto original = loadRig(std::string(MVIS_SOURCE_DIR) + "/config/sim_vi_rig");
  ASSERT_TRUE(original.ok()) << original.status().message();
  const fs::path dir = freshDirectory("roundtrip");
  ASSERT_TRUE(saveRig(original.value(), dir.string()).ok());
  const auto reread = loadRig(dir.string());
  ASSERT_TRUE(reread.ok()) << reread.status().message();
  expectSameRig(original.value(), reread.value());
  fs::remove_all(dir);
}

TEST(RigIo, WriteThenReadKeepsStandardDeviationsAndIntrinsics) {
  auto parsed = parseImuChain(test::validImuChain(), "imu.yaml");
  ASSERT_TRUE(parsed.ok()) << parsed.status().message();
  auto cameras = parseCamChain(test::validCamChain(), "cam.yaml");
  ASSERT_TRUE(cameras.ok()) << cameras.status().message();
  Rig rig;
  rig.inertial = parsed.value();
  rig.cameras = cameras.value();
  rig.inertial[0].intrinsics.Tg << 1e-3, 2e-4, 0, 0, -3e-4, 0, 5e-5, 0, 1e-3;
  rig.inertial[0].intrinsics.R_IMUtoACC = lie::expSO3(Eigen::Vector3d(0.001, -0.002, 0.003));
  InertialCalibrationStd istd;
  istd.rotation << 1e-3, 2e-3, 3e-3;
  istd.translation << 1e-4, 2e-4, 3e-4;
  istd.time_offset = 5e-5;
  istd.Tw(0, 1) = 1e-4;
  istd.Tg(2, 0) = 7e-5;
  istd.R_IMUtoACC << 1e-4, 1e-4, 2e-4;
  rig.inertial[1].std = istd;
  CameraCalibrationStd cstd;
  cstd.rotation << 3e-4, 3e-4, 1e-4;
  cstd.translation << 1e-3, 1e-3, 2e-3;
  cstd.timeshift_cam_imu = 1e-4;
  cstd.intrinsics << 0.5, 0.5, 0.3, 0.3;
  cstd.distortion_coeffs << 1e-3, 1e-3, 1e-4, 1e-4;
  rig.cameras[0].std = cstd;

  const fs::path dir = freshDirectory("roundtrip_std");
  ASSERT_TRUE(saveRig(rig, dir.string()).ok());
  const auto reread = loadRig(dir.string());
  ASSERT_TRUE(reread.ok()) << reread.status().message();
  expectSameRig(rig, reread.value());
  EXPECT_FALSE(reread.value().target.has_value());
  fs::remove_all(dir);
}

TEST(RigIo, AcceptsTImuCamAsTheInverse) {
  const auto kalibr = parseCamChain(test::validCamChain(), "cam.yaml");
  ASSERT_TRUE(kalibr.ok());
  const Eigen::Matrix4d T_imu_cam = kalibr.value()[0].T_cam_imu.inverse().matrix();
  std::string text = "cam0:\n  T_imu_cam:\n";
  for (int r = 0; r < 4; ++r) {
    text += "    - [" + std::to_string(T_imu_cam(r, 0)) + ", " + std::to_string(T_imu_cam(r, 1)) +
            ", " + std::to_string(T_imu_cam(r, 2)) + ", " + std::to_string(T_imu_cam(r, 3)) + "]\n";
  }
  text += test::validCamChain().substr(test::validCamChain().find("  cam_overlaps"));
  const auto openvins = parseCamChain(text, "cam.yaml");
  ASSERT_TRUE(openvins.ok()) << openvins.status().message();
  expectSameTransform(openvins.value()[0].T_cam_imu, kalibr.value()[0].T_cam_imu);
}

TEST(RigIo, AcceptsTheOpenCvHeaderOpenVinsWrites) {
  const auto parsed = parseImuChain("%YAML:1.0\n" + test::validImuChain(), "imu.yaml");
  ASSERT_TRUE(parsed.ok()) << parsed.status().message();
  EXPECT_EQ(parsed.value().size(), 3u);
  EXPECT_EQ(parsed.value()[0].intrinsics.Tw(0, 1), 0.002);
  EXPECT_EQ(parsed.value()[1].time_offset, 0.004);
}

}  // namespace
}  // namespace mvis
