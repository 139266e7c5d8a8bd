// The failure checks on real data (test/data/real_euroc: 36 s of EuRoC's imu_april calibration
// recording, yac's AprilGrid corners, EuRoC's reference calibration). A clean recording must not
// raise a failure or restart the window: before the checks were scaled by how much the
// calibration moves on the data (trusted_calibration.h), this bag raised 7 false failures with
// its rough configuration and the restarts left the cameras 0.4-0.9 deg from the reference.
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "mvis/rig/rig_io.h"
#include "mvis/ros/offline.h"

namespace mvis {
namespace {

const std::string kData = std::string(MVIS_SOURCE_DIR) + "/test/data/real_euroc";

Rig load(const std::string& dir) {
  auto rig = loadRig(dir);
  EXPECT_TRUE(rig.ok()) << rig.status().message();
  return rig.value();
}

// The configuration with the reference's intrinsics (the extrinsics and time shift stay rough).
Rig withReferenceIntrinsics() {
  Rig rig = load(kData + "/config");
  const Rig reference = load(kData + "/reference");
  for (std::size_t c = 0; c < rig.cameras.size(); ++c) {
    rig.cameras[c].intrinsics = reference.cameras[c].intrinsics;
    rig.cameras[c].distortion_coeffs = reference.cameras[c].distortion_coeffs;
  }
  return rig;
}

OfflineResult run(const Rig& guess, bool checks, bool intrinsics,
                  const std::string& bag = kData + "/imu_april_0-36s.bag",
                  bool imu_intrinsics = false) {
  OfflineOptions options;
  options.estimator.max_solve_time_s = 1e3;  // as mvis_offline: no dependence on the load
  options.estimator.init_solve_time_s = 1e3;
  options.estimator.estimate_intrinsics = intrinsics;
  if (!checks) options.estimator.failure_step_sigma = options.estimator.frame_gate_sigma = 0.0;
  if (imu_intrinsics) {
    options.estimator.estimate_imu_intrinsics = true;
    options.estimator.estimate_gravity_sensitivity = true;
  }
  auto r = runOffline(guess, bag, options);
  EXPECT_TRUE(r.ok()) << r.status().message();
  return r.value();
}

// cam1's pose in cam0's frame: rotation [deg] and translation [mm] from the reference's.
void relativeError(const Rig& estimate, double* rotation_deg, double* translation_mm) {
  const Rig reference = load(kData + "/reference");
  const auto relative = [](const Rig& rig) {
    return rig.cameras[1].T_cam_imu * rig.cameras[0].T_cam_imu.inverse();
  };
  const SE3 e = relative(estimate), r = relative(reference);
  *rotation_deg = Eigen::AngleAxisd(e.q * r.q.inverse()).angle() * 180.0 / M_PI;
  *translation_mm = 1e3 * (e.p - r.p).norm();
}

void expectSame(const Rig& a, const Rig& b) {
  for (std::size_t c = 0; c < a.cameras.size(); ++c) {
    EXPECT_LT(
        Eigen::AngleAxisd(a.cameras[c].T_cam_imu.q * b.cameras[c].T_cam_imu.q.inverse()).angle(),
        1e-9);
    EXPECT_LT((a.cameras[c].T_cam_imu.p - b.cameras[c].T_cam_imu.p).norm(), 1e-9);
  }
}

// With the rough configuration (intrinsics ~1% off and held) the calibration moves up to 3.7x
// more than its covariance allows (Estimator::sigmaInflation, 3.3 at the end); with the
// reference intrinsics up to 2.3x. Either way no failure, no restart, no frame or corner
// dropped, and the estimate is the one without the checks.
TEST(RealEuroc, CleanRecordingRaisesNoFailure) {
  for (const bool reference_intrinsics : {false, true}) {
    SCOPED_TRACE(reference_intrinsics ? "reference intrinsics" : "rough configuration");
    const Rig guess = reference_intrinsics ? withReferenceIntrinsics() : load(kData + "/config");
    const OfflineResult on = run(guess, true, false);
    const OfflineResult off = run(guess, false, false);
    EXPECT_EQ(on.counters.failures, 0);
    EXPECT_EQ(on.counters.restarts, 0);
    EXPECT_EQ(on.counters.frames_rejected + on.counters.corners_rejected, 0);
    expectSame(on.calibration, off.calibration);
    double rotation_deg = 0.0, translation_mm = 0.0;
    relativeError(on.calibration, &rotation_deg, &translation_mm);
    std::printf("%s: cam0-cam1 %.3f deg %.2f mm from the reference\n",
                reference_intrinsics ? "reference intrinsics" : "rough configuration", rotation_deg,
                translation_mm);
    if (reference_intrinsics) {
      // Measured 0.020 deg / 0.22 mm (stereo PnP on the full run agrees with the reference to a
      // median 0.25 deg / 4.6 mm per pair: the reference is not ground truth, but close).
      EXPECT_LT(rotation_deg, 0.05);
      EXPECT_LT(translation_mm, 0.5);
    }
  }
}

// With the cameras' intrinsics estimated from the rough start, cam0's distortion jumps (k1 by
// 16 of its sigma within 1.5 s at 27 s, towards the reference's value) when the board reaches the
// image's border, and a few of yac's corners there are 8-33 px off: the corners are dropped, the
// jumps are said as inconsistent intrinsics, and nothing restarts (a restart would go back to
// distortion fitted to the image's centre).
TEST(RealEuroc, IntrinsicsJumpsAreSaidNotRestartedOn) {
  const OfflineResult r = run(load(kData + "/config"), true, true);
  EXPECT_EQ(r.counters.failures, 0);
  EXPECT_EQ(r.counters.restarts, 0);
  EXPECT_GT(r.counters.inconsistencies, 0);
  EXPECT_GT(r.counters.corners_rejected, 0);
  double rotation_deg = 0.0, translation_mm = 0.0;
  relativeError(r.calibration, &rotation_deg, &translation_mm);
  std::printf("estimated intrinsics: cam0-cam1 %.3f deg %.2f mm from the reference\n", rotation_deg,
              translation_mm);
  // Measured 0.025 deg / 1.5 mm (0.036 deg / 1.4 mm without any check).
  EXPECT_LT(rotation_deg, 0.06);
  EXPECT_LT(translation_mm, 3.0);
}

// The bag's messages before and from `cut` [s after its start], as two bags in `dir`.
std::pair<std::string, std::string> halves(const std::string& dir, double cut) {
  std::filesystem::create_directories(dir);
  const std::string first = dir + "/first.bag", second = dir + "/second.bag";
  rosbag::Bag in(kData + "/imu_april_0-36s.bag", rosbag::bagmode::Read);
  rosbag::Bag a(first, rosbag::bagmode::Write), b(second, rosbag::bagmode::Write);
  rosbag::View view(in);
  const ros::Time at = view.getBeginTime() + ros::Duration(cut);
  for (const rosbag::MessageInstance& m : view) {
    (m.getTime() < at ? a : b).write(m.getTopic(), m.getTime(), m, m.getConnectionHeader());
  }
  return {first, second};
}

// Per camera and axis, |a - b| over sqrt(sigma_a^2 + sigma_b^2) (rotation in b's tangent,
// translation, time offset); the largest.
double largestDisagreement(const Rig& a, const Rig& b) {
  double worst = 0.0;
  for (std::size_t c = 0; c < a.cameras.size(); ++c) {
    const auto& sa = a.cameras[c].std;
    const auto& sb = b.cameras[c].std;
    if (!sa || !sb) return std::numeric_limits<double>::infinity();
    const Eigen::AngleAxisd d(b.cameras[c].T_cam_imu.q.inverse() * a.cameras[c].T_cam_imu.q);
    const Eigen::Vector3d rotation = d.angle() * d.axis();
    const Eigen::Vector3d translation = a.cameras[c].T_cam_imu.p - b.cameras[c].T_cam_imu.p;
    for (int k = 0; k < 3; ++k) {
      worst = std::max(worst, std::abs(rotation[k]) / std::hypot(sa->rotation[k], sb->rotation[k]));
      worst = std::max(
          worst, std::abs(translation[k]) / std::hypot(sa->translation[k], sb->translation[k]));
    }
    worst =
        std::max(worst, std::abs(a.cameras[c].timeshift_cam_imu - b.cameras[c].timeshift_cam_imu) /
                            std::hypot(sa->timeshift_cam_imu, sb->timeshift_cam_imu));
  }
  return worst;
}

// The online pass's reported sigmas on real data (Estimator::calibration): the recording's two
// halves, each calibrated online, agree within 3 of their combined sigmas, with and without
// every IMU's intrinsics (and Tg) estimated. With the covariance's own sigmas they differed by
// up to 10.0 and 6.0 of them (cam1's rotation); measured now 2.60 and 1.78.
TEST(RealEuroc, HalvesAgreeWithinTheirReportedSigmas) {
  const auto [first, second] = halves(::testing::TempDir() + "/mvis_euroc_halves", 18.0);
  for (const bool imu_intrinsics : {false, true}) {
    SCOPED_TRACE(imu_intrinsics ? "every IMU's intrinsics" : "extrinsics and time offsets");
    const Rig guess = withReferenceIntrinsics();
    const OfflineResult a = run(guess, true, false, first, imu_intrinsics);
    const OfflineResult b = run(guess, true, false, second, imu_intrinsics);
    const double worst = largestDisagreement(a.calibration, b.calibration);
    std::printf("%s: halves %.2f combined sigmas apart at most\n",
                imu_intrinsics ? "IMU intrinsics" : "extrinsics", worst);
    EXPECT_LT(worst, 3.0);
    EXPECT_EQ(a.counters.restarts + b.counters.restarts, 0);
  }
}

// The two IMU intrinsic models on real data (rough configuration, every IMU's intrinsics and Tg
// estimated). Each splits the sensor triads' full matrices (M_gyro = Tw R_IMUtoGYRO, M_acc = Ta
// R_IMUtoACC) into a triangle and a rotation, rpng with upper triangles and the rotation on the
// accelerometer, kalibr with lower ones and the rotation on the gyroscope, so their rotations are
// not each other's inverse: on this bag R_IMUtoACC and R_IMUtoGYRO^T differ by 1.4 deg at
// sigmas of 0.2 deg, because the data show a symmetric shear of about 0.6 deg between the two
// triads (A's off-diagonal 0.010-0.013 below), which an upper and a lower triangle split
// differently. What does not depend on the split, A = M_acc M_gyro^-1 (a vector's accelerometer
// reading from its gyroscope reading, whatever the frame {I}), agrees: its elements within
// 0.002 (measured 0.0019), its rotation (A's polar factor) within 0.08 deg.
TEST(RealEuroc, IntrinsicModelsAgreeOnWhatTheyShare) {
  Eigen::Matrix3d A[2];
  for (int k = 0; k < 2; ++k) {
    Rig guess = load(kData + "/config");
    guess.inertial[0].model = k == 0 ? ImuModel::kRpng : ImuModel::kKalibr;
    const OfflineResult r = run(guess, true, false, kData + "/imu_april_0-36s.bag", true);
    const ImuIntrinsics& m = r.calibration.inertial[0].intrinsics;
    A[k] = m.Ta * m.R_IMUtoACC * (m.Tw * m.R_IMUtoGYRO).inverse();
  }
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd0(A[0], Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd1(A[1], Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d R0 = svd0.matrixU() * svd0.matrixV().transpose();
  const Eigen::Matrix3d R1 = svd1.matrixU() * svd1.matrixV().transpose();
  const double rotation_deg = Eigen::AngleAxisd(R0.transpose() * R1).angle() * 180.0 / M_PI;
  const double largest = (A[0] - A[1]).cwiseAbs().maxCoeff();
  std::printf("rpng against kalibr: A's elements %.4f apart at most, its rotation %.3f deg\n",
              largest, rotation_deg);
  EXPECT_LT(largest, 0.003);
  EXPECT_LT(rotation_deg, 0.15);
}

}  // namespace
}  // namespace mvis
