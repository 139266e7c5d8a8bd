// The estimate log's CSV files: columns, values, nan where nothing is known, thinning.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "mvis/rig/estimate_log.h"

namespace mvis {
namespace {

std::vector<std::vector<std::string>> readCsv(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::vector<std::string>> rows;
  for (std::string line; std::getline(in, line);) {
    std::vector<std::string> fields;
    std::stringstream ss(line);
    for (std::string f; std::getline(ss, f, ',');) fields.push_back(f);
    rows.push_back(fields);
  }
  return rows;
}

Rig smallRig() {
  Rig rig;
  rig.inertial.resize(3);
  rig.inertial[0].name = "imu0";
  rig.inertial[1].name = "imu1";
  rig.inertial[1].T_i_b =
      SE3(lie::expQuat(Eigen::Vector3d(0.1, -0.2, 0.3)), Eigen::Vector3d(0.01, 0.02, -0.03));
  rig.inertial[1].time_offset = 0.004;
  rig.inertial[1].model = ImuModel::kRpng;
  rig.inertial[1].intrinsics.Tw(0, 1) = 0.002;
  rig.inertial[1].intrinsics.Ta(2, 2) = 0.997;
  rig.inertial[1].intrinsics.Tg(1, 0) = 5e-4;
  rig.inertial[1].intrinsics.R_IMUtoACC = lie::expSO3(Eigen::Vector3d(0.0, 0.003, 0.0));
  rig.inertial[2].name = "imu2";
  rig.inertial[2].type = InertialType::kGyroscope;
  rig.inertial[2].T_i_b = SE3(lie::expQuat(Eigen::Vector3d(0, 0, 0.5)), Eigen::Vector3d::Zero());
  rig.cameras.resize(1);
  rig.cameras[0].name = "cam0";
  rig.cameras[0].T_cam_imu =
      SE3(lie::expQuat(Eigen::Vector3d(1.0, 0, 0)), Eigen::Vector3d(0.1, 0, 0));
  rig.cameras[0].timeshift_cam_imu = -0.002;
  rig.cameras[0].intrinsics = Eigen::Vector4d(400.0, 401.0, 320.5, 240.25);
  rig.cameras[0].distortion_coeffs = Eigen::Vector4d(0.01, -0.02, 0.001, -0.0005);
  return rig;
}

TEST(EstimateLog, WritesCalibrationAndPoseCovariance) {
  Rig rig = smallRig();
  EstimateLog log;
  log.addCalibration(1700000000123456789, rig);  // no standard deviations yet
  CameraCalibrationStd cam_std;
  cam_std.rotation = Eigen::Vector3d(1e-3, 2e-3, 3e-3);
  cam_std.translation = Eigen::Vector3d(4e-4, 5e-4, 6e-4);
  cam_std.timeshift_cam_imu = 7e-5;
  cam_std.intrinsics = Eigen::Vector4d(0.5, 0.6, 0.7, 0.8);
  cam_std.distortion_coeffs = Eigen::Vector4d(1e-4, 2e-4, 3e-4, 4e-4);
  rig.cameras[0].std = cam_std;
  InertialCalibrationStd imu_std;
  imu_std.rotation = Eigen::Vector3d::Constant(1e-3);
  imu_std.translation = Eigen::Vector3d::Constant(2e-3);
  imu_std.time_offset = 3e-4;
  rig.inertial[2].std = imu_std;
  imu_std.Tw(0, 1) = 1e-4;
  imu_std.Tg(1, 0) = 2e-5;
  imu_std.R_IMUtoACC = Eigen::Vector3d(3e-4, 4e-4, 5e-4);
  rig.inertial[1].std = imu_std;
  log.addCalibration(1700000001000000000, rig);
  Eigen::Matrix<double, 6, 6> cov = Eigen::Matrix<double, 6, 6>::Identity() * 1e-4;
  cov(0, 5) = cov(5, 0) = 2e-5;
  log.addPose(1700000001000000000, rig.inertial[1].T_i_b, cov);
  log.addPose(1700000002000000000, SE3(), Eigen::Matrix<double, 6, 6>::Constant(NAN));

  const std::string dir = ::testing::TempDir() + "/mvis_estimate_log";
  std::filesystem::create_directories(dir);
  ASSERT_TRUE(log.write(dir).ok());

  const auto cal = readCsv(dir + "/calibration.csv");
  ASSERT_EQ(cal.size(), 1u + 2 * 3);  // header, two solves of three sensors
  ASSERT_EQ(cal[0].size(), 33u + 48u);
  EXPECT_EQ(cal[0][0], "stamp");
  EXPECT_EQ(cal[0][16], "std_time_offset");
  EXPECT_EQ(cal[0][17], "fu");
  EXPECT_EQ(cal[0][32], "std_k4");
  EXPECT_EQ(cal[0][33], "tw11");
  EXPECT_EQ(cal[0][34], "tw12");
  EXPECT_EQ(cal[0][44], "ta33");
  EXPECT_EQ(cal[0][48], "tg21");
  EXPECT_EQ(cal[0][56], "acc_rz");
  EXPECT_EQ(cal[0][58], "std_tw12");
  EXPECT_EQ(cal[0][80], "std_acc_rz");
  for (const auto& row : cal) ASSERT_EQ(row.size(), 33u + 48u);
  // First solve: cam0 without standard deviations.
  EXPECT_EQ(cal[1][0], "1700000000.123456789");
  EXPECT_EQ(cal[1][1], "cam0");
  EXPECT_EQ(cal[1][2], "camera");
  EXPECT_NEAR(std::stod(cal[1][3]), 1.0, 1e-9);
  EXPECT_NEAR(std::stod(cal[1][6]), 0.1, 1e-12);
  EXPECT_NEAR(std::stod(cal[1][9]), -0.002, 1e-15);
  EXPECT_EQ(cal[1][10], "nan");
  // Second solve: cam0's intrinsics and their standard deviations.
  EXPECT_NEAR(std::stod(cal[4][17]), 400.0, 1e-9);
  EXPECT_NEAR(std::stod(cal[4][20]), 240.25, 1e-9);
  EXPECT_NEAR(std::stod(cal[4][24]), -0.0005, 1e-15);
  EXPECT_NEAR(std::stod(cal[4][25]), 0.5, 1e-12);
  EXPECT_NEAR(std::stod(cal[4][32]), 4e-4, 1e-15);
  EXPECT_EQ(cal[1][25], "nan");
  // Second solve: imu1 with its values and standard deviations (no intrinsics); the gyroscope
  // has no position.
  const auto& imu1 = cal[5];
  EXPECT_EQ(imu1[1], "imu1");
  EXPECT_EQ(imu1[2], "imu");
  EXPECT_NEAR(std::stod(imu1[3]), 0.1, 1e-9);
  EXPECT_NEAR(std::stod(imu1[5]), 0.3, 1e-9);
  EXPECT_NEAR(std::stod(imu1[8]), -0.03, 1e-12);
  EXPECT_NEAR(std::stod(imu1[9]), 0.004, 1e-15);
  EXPECT_NEAR(std::stod(imu1[13]), 2e-3, 1e-15);
  EXPECT_NEAR(std::stod(imu1[16]), 3e-4, 1e-15);
  EXPECT_EQ(imu1[17], "nan");
  EXPECT_EQ(imu1[32], "nan");
  // Its rpng intrinsics and their standard deviations; the camera and the calibrated gyroscope
  // have none.
  EXPECT_NEAR(std::stod(imu1[33]), 1.0, 1e-15);
  EXPECT_NEAR(std::stod(imu1[34]), 0.002, 1e-15);
  EXPECT_NEAR(std::stod(imu1[44]), 0.997, 1e-15);
  EXPECT_NEAR(std::stod(imu1[48]), 5e-4, 1e-15);
  EXPECT_NEAR(std::stod(imu1[55]), 0.003, 1e-12);
  EXPECT_NEAR(std::stod(imu1[58]), 1e-4, 1e-15);
  EXPECT_NEAR(std::stod(imu1[57]), 0.0, 1e-15);  // std_tw11: held
  EXPECT_NEAR(std::stod(imu1[72]), 2e-5, 1e-15);
  EXPECT_NEAR(std::stod(imu1[80]), 5e-4, 1e-15);
  EXPECT_EQ(cal[4][33], "nan");
  EXPECT_EQ(cal[6][33], "nan");
  const auto& gyro = cal[6];
  EXPECT_EQ(gyro[2], "gyroscope");
  EXPECT_NEAR(std::stod(gyro[5]), 0.5, 1e-9);
  EXPECT_EQ(gyro[6], "nan");
  EXPECT_EQ(gyro[14], "nan");
  EXPECT_NEAR(std::stod(gyro[10]), 1e-3, 1e-15);

  const auto poses = readCsv(dir + "/pose_covariance.csv");
  ASSERT_EQ(poses.size(), 2u);  // header and the one finite covariance
  ASSERT_EQ(poses[0].size(), 8u + 36u);
  EXPECT_EQ(poses[0][8], "c00");
  EXPECT_EQ(poses[0][43], "c55");
  EXPECT_EQ(poses[1][0], "1700000001.000000000");
  EXPECT_NEAR(std::stod(poses[1][3]), -0.03, 1e-12);
  EXPECT_NEAR(std::stod(poses[1][8]), 1e-4, 1e-16);
  EXPECT_NEAR(std::stod(poses[1][8 + 5]), 2e-5, 1e-16);
  EXPECT_NEAR(std::stod(poses[1][8 + 30]), 2e-5, 1e-16);
}

TEST(EstimateLog, KeepsEveryOtherSolvePastItsLimit) {
  const Rig rig = smallRig();  // three calibrated sensors: three rows per solve
  EstimateLog log(10);
  for (int k = 0; k < 4; ++k) log.addCalibration(k * kNsPerSecond, rig);
  // 12 rows > 10: the solves at 0 s and 2 s stay, whole (6 rows); the run goes on.
  EXPECT_EQ(log.calibrationRows(), 6u);
  log.addCalibration(4 * kNsPerSecond, rig);
  EXPECT_EQ(log.calibrationRows(), 9u);
  const std::string dir = ::testing::TempDir() + "/mvis_estimate_log_thin";
  std::filesystem::create_directories(dir);
  ASSERT_TRUE(log.write(dir).ok());
  const auto cal = readCsv(dir + "/calibration.csv");
  ASSERT_EQ(cal.size(), 10u);
  const std::vector<std::string> stamps = {"0.000000000", "2.000000000", "4.000000000"};
  for (std::size_t i = 0; i < 9; ++i) {
    EXPECT_EQ(cal[1 + i][0], stamps[i / 3]) << i;
    EXPECT_EQ(cal[1 + i][1], (std::vector<std::string>{"cam0", "imu1", "imu2"}[i % 3])) << i;
  }
}

TEST(EstimateLog, StatusRowsQuotedAndBounded) {
  EstimateLog log(10);
  for (int k = 0; k < 25; ++k) {
    log.addStatus(k * kNsPerSecond, "cam0", "rotation", k % 2 ? "converged" : "improving", 0.5,
                  0.016, k % 2 ? "" : "rotate about imu0's y and z axes, say \"briskly\"");
  }
  const std::string dir = ::testing::TempDir() + "/mvis_estimate_log_status";
  std::filesystem::create_directories(dir);
  ASSERT_TRUE(log.write(dir).ok());
  std::ifstream in(dir + "/calibration_status.csv");
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  ASSERT_GE(lines.size(), 2u);
  EXPECT_EQ(lines[0], "stamp,sensor,quantity,status,sigma,target,advice");
  // At most 10 rows kept, the newest last.
  EXPECT_LE(lines.size(), 11u);
  EXPECT_EQ(lines.back(),
            "24.000000000,cam0,rotation,improving,0.5,0.016,"
            "\"rotate about imu0's y and z axes, say \"\"briskly\"\"\"");
}

}  // namespace
}  // namespace mvis
