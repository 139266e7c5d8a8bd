// The configuration files users already have (test/data/formats, written by the project after the
// real ones): OpenVINS's shipped EuRoC files (model kalibr, T_imu_cam, five-digit rotations) and
// Kalibr's results as they come (camchain-imucam with T_cn_cnm1 and three cameras, the IMU file
// with gyroscopes/accelerometers sections). Each is loaded, applied and written back.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "mvis/common/lie.h"
#include "mvis/inertial/imu_correction.h"
#include "mvis/rig/rig_io.h"
#include "rig_test_util.h"

namespace mvis {
namespace {

const std::string kFormats = std::string(MVIS_SOURCE_DIR) + "/test/data/formats";

bool mentions(const std::vector<std::string>& warnings, const std::string& text) {
  for (const auto& w : warnings) {
    if (w.find(text) != std::string::npos) return true;
  }
  return false;
}

// Read, write, read: every value the same (rotations re-orthonormalized on the first read move
// by round-off only after it).
void expectRoundTrip(const Rig& rig, const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("mvis_test_formats_" + name);
  std::filesystem::remove_all(dir);
  ASSERT_TRUE(saveRig(rig, dir.string()).ok());
  std::vector<std::string> warnings;
  const auto again = loadRig(dir.string(), &warnings);
  ASSERT_TRUE(again.ok()) << again.status().message();
  EXPECT_TRUE(warnings.empty()) << warnings.front();
  test::expectSameRig(rig, again.value());
  std::filesystem::remove_all(dir);
}

TEST(RigIoFormats, OpenVinsEurocLoadsAsItShips) {
  std::vector<std::string> warnings;
  const auto rig = loadRig(kFormats + "/openvins_euroc", &warnings);
  ASSERT_TRUE(rig.ok()) << rig.status().message();
  const Rig& r = rig.value();
  ASSERT_EQ(r.inertial.size(), 1u);
  EXPECT_EQ(r.inertial[0].model, ImuModel::kKalibr);
  EXPECT_TRUE(r.inertial[0].intrinsics.Tw.isIdentity(0.0));
  ASSERT_EQ(r.cameras.size(), 2u);
  // T_imu_cam inverted: cam0's position in imu0 as given.
  EXPECT_LT((r.cameras[0].T_cam_imu.inverse().p -
             Eigen::Vector3d(-0.0216401454975, -0.064676986768, 0.00981073058949))
                .norm(),
            1e-12);
  // cam1's five-digit rotation: used as the nearest rotation, with a warning saying so and by how
  // much (its entries move by ~1e-5); nothing else warns.
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("kalibr_imucam_chain.yaml: cam1: T_imu_cam: rotation part is not "
                             "orthonormal (max |R^T R - I| = 1.34e-05): using the nearest "
                             "rotation"),
            std::string::npos)
      << warnings[0];
  expectRoundTrip(r, "openvins");
}

TEST(RigIoFormats, KalibrResultsLoadAsTheyCome) {
  std::vector<std::string> warnings;
  const auto rig = loadRig(
      RigFiles::in(kFormats + "/kalibr_results", "imu-rig.yaml", "camchain-imucam-rig.yaml"),
      &warnings);
  ASSERT_TRUE(rig.ok()) << rig.status().message();
  const Rig& r = rig.value();
  ASSERT_EQ(r.cameras.size(), 3u);
  EXPECT_EQ(r.cameras[2].distortion_model, DistortionModel::kEquidistant);
  EXPECT_EQ(r.cameras[1].timeshift_cam_imu, -0.0031);
  // T_cn_cnm1 agrees with the T_cam_imu chain: nothing to warn about.
  EXPECT_TRUE(warnings.empty()) << warnings.front();
  // The IMU result: scale-misalignment is the kalibr model, gyroscopes M / C_gyro_i / A and
  // accelerometers M its Tw / R_IMUtoGYRO / Tg / Ta.
  ASSERT_EQ(r.inertial.size(), 2u);
  const InertialSensor& imu0 = r.inertial[0];
  EXPECT_EQ(imu0.model, ImuModel::kKalibr);
  EXPECT_EQ(imu0.intrinsics.Tw(1, 0), 0.0013);
  EXPECT_EQ(imu0.intrinsics.Ta(2, 1), 0.0023);
  EXPECT_EQ(imu0.intrinsics.Tg(0, 0), 1.2e-4);
  EXPECT_NEAR(Eigen::AngleAxisd(imu0.intrinsics.R_IMUtoGYRO).angle(), 0.35 * M_PI / 180.0, 1e-12);
  EXPECT_TRUE(imu0.intrinsics.R_IMUtoACC.isIdentity(0.0));
  EXPECT_EQ(r.inertial[1].model, ImuModel::kCalibrated);
  EXPECT_EQ(r.inertial[1].time_offset, 0.0023);
  expectRoundTrip(r, "kalibr");
}

TEST(RigIoFormats, KalibrChainDisagreementWarnsNamingBothCameras) {
  std::vector<std::string> warnings;
  const auto rig = loadRig(RigFiles::in(kFormats + "/kalibr_results", "imu-rig.yaml",
                                        "camchain-imucam-inconsistent.yaml"),
                           &warnings);
  ASSERT_TRUE(rig.ok()) << rig.status().message();
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_TRUE(mentions(warnings,
                       "camchain-imucam-inconsistent.yaml: cam2: T_cn_cnm1: disagrees "
                       "with cam2 and cam1's T_cam_imu by 0.00099999"))
      << warnings[0];
  EXPECT_TRUE(mentions(warnings, "mvis uses T_cam_imu"));
}

// The kalibr model applied to readings: w_m = Tw R_IMUtoGYRO w + Tg a + b_g, a_m = Ta a + b_a
// (report Eq. 1-2 with R_IMUtoACC = I) corrects back to the true motion and biases.
TEST(RigIoFormats, KalibrModelCorrectsReadings) {
  const auto rig = loadRig(
      RigFiles::in(kFormats + "/kalibr_results", "imu-rig.yaml", "camchain-imucam-rig.yaml"));
  ASSERT_TRUE(rig.ok());
  const ImuIntrinsics& in = rig.value().inertial[0].intrinsics;
  const Eigen::Vector3d w(0.7, -1.3, 2.1), a(1.2, -0.4, 9.6);
  const Eigen::Vector3d bg(0.01, -0.02, 0.005), ba(0.1, 0.05, -0.2);
  ImuMeasurement m;
  m.accel = in.Ta * a + ba;
  m.gyro = in.Tw * in.R_IMUtoGYRO * w + in.Tg * a + bg;
  const ImuCorrection correction(in);
  Eigen::Vector3d bg_c, ba_c;
  correction.biases(bg, ba, &bg_c, &ba_c);
  const ImuMeasurement c = correction.apply(m, false);
  EXPECT_LT((c.accel - ba_c - a).norm(), 1e-12);
  EXPECT_LT((c.gyro - bg_c - w).norm(), 1e-12);
  // Without R_IMUtoGYRO the rate would be off by its 0.35 deg: 0.002 rad/s here.
  ImuIntrinsics no_rotation = in;
  no_rotation.R_IMUtoGYRO.setIdentity();
  const ImuCorrection wrong(no_rotation);
  EXPECT_GT((wrong.apply(m, false).gyro - c.gyro).norm(), 1e-3);
}

TEST(RigIoFormats, FilesByName) {
  // A name given absolute is used as it is; a missing one names the file.
  const auto files = RigFiles::in("/somewhere", "/abs/imu.yaml", "cams.yaml");
  EXPECT_EQ(files.imu_chain, "/abs/imu.yaml");
  EXPECT_EQ(files.cam_chain, "/somewhere/cams.yaml");
  EXPECT_EQ(files.target, "/somewhere/aprilgrid.yaml");
  const auto rig = loadRig(RigFiles::in(kFormats + "/kalibr_results", "imu-missing.yaml"));
  ASSERT_FALSE(rig.ok());
  EXPECT_EQ(rig.status().message(),
            kFormats + "/kalibr_results/imu-missing.yaml: cannot read the file");
}

}  // namespace
}  // namespace mvis
