// Initialization pieces on exact simulated data: gravity and velocities from poses and
// preintegrated readings, and a camera clock offset recovered from rotations and the gyroscope.
#include <gtest/gtest.h>

#include <memory>
#include <random>

#include "mvis/estimator/initialization.h"
#include "mvis/sim/imu_simulator.h"
#include "sim_test_util.h"

namespace mvis {
namespace {

using test::handheld;
using test::idealImu;

TEST(Initialization, GravityAndVelocitiesFromPosesAndReadings) {
  const auto trajectory = handheld();
  const InertialSensor imu = idealImu(500.0);
  const TrajectoryFunction base = [&](double t) { return trajectory.evaluate(t); };
  ImuSimulationOptions exact;
  exact.noise = false;
  exact.biases = false;
  std::vector<TimeNs> t;
  std::vector<SE3> poses;
  std::vector<std::unique_ptr<ImuPreintegration>> pre;
  std::vector<const ImuPreintegration*> pre_ptrs;
  for (int i = 0; i < 10; ++i) t.push_back(fromSeconds(2.0 + i / 30.0));
  for (std::size_t i = 0; i < t.size(); ++i) {
    poses.push_back(trajectory.evaluate(toSeconds(t[i])).T_G_I);
    if (i + 1 == t.size()) break;
    pre.push_back(std::make_unique<ImuPreintegration>(imu.noise, Eigen::Vector3d::Zero(),
                                                      Eigen::Vector3d::Zero()));
    for (const auto& s : simulateImu(imu, base, 0, t[i], t[i + 1], exact)) {
      pre.back()->add({s.stamp_ns, s.gyro, s.accel});
    }
    // The 500 Hz samples start at t_i but miss t_i+1 (1/30 s is no multiple of 2 ms): the
    // estimator interpolates a reading there; here it is exact.
    if (pre.back()->endNs() != t[i + 1]) {
      Eigen::Vector3d w, f;
      trueInertialMotion(imu, trajectory.evaluate(toSeconds(t[i + 1])), &w, &f);
      pre.back()->add({t[i + 1], w, f});
    }
    pre_ptrs.push_back(pre.back().get());
  }
  const GravityAlignment a = alignGravity(t, poses, pre_ptrs);
  // Exact poses and readings: only the midpoint integration's ~1e-6 errors remain, divided by
  // tau^2 ~ 0.1 s^2.
  EXPECT_LT((a.gravity - kGravity_G).norm(), 1e-3);
  ASSERT_EQ(a.velocities.size(), t.size());
  for (std::size_t i = 0; i < t.size(); ++i) {
    EXPECT_LT((a.velocities[i] - trajectory.evaluate(toSeconds(t[i])).v_G).norm(), 1e-3) << i;
  }
}

TEST(Initialization, ClockOffsetFromRotationsAndGyroscope) {
  const auto trajectory = handheld();
  // A camera 30 ms behind (t_cam = t_imu - 0.030) looking along the IMU's x axis, 1.5 s of
  // 30 Hz board rotations; the configured offset is 0.
  Eigen::Matrix3d R_C_I;
  R_C_I << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  std::deque<std::pair<TimeNs, Eigen::Matrix3d>> rotations;
  for (int i = 0; i < 45; ++i) {
    const double t_imu = 3.0 + i / 30.0;
    const Eigen::Matrix3d R_G_C = trajectory.evaluate(t_imu).T_G_I.rotation() * R_C_I.transpose();
    rotations.emplace_back(fromSeconds(t_imu - 0.030), R_G_C);
  }
  const auto gyro_at = [&](TimeNs t) { return trajectory.evaluate(toSeconds(t)).w_I; };
  const double delta = clockCorrection(rotations, R_C_I.transpose(), 0, fromSeconds(2.0),
                                       fromSeconds(6.0), gyro_at, 0.3);
  // The 1 ms grid refined by a parabola, on exact data.
  EXPECT_NEAR(delta, 0.030, 0.0005);
  // Without motion there is nothing to match: no correction.
  std::deque<std::pair<TimeNs, Eigen::Matrix3d>> still;
  for (int i = 0; i < 45; ++i) still.emplace_back(fromSeconds(3.0 + i / 30.0), R_C_I.transpose());
  EXPECT_EQ(clockCorrection(
                still, R_C_I.transpose(), 0, fromSeconds(2.0), fromSeconds(6.0),
                [](TimeNs) { return Eigen::Vector3d::Zero().eval(); }, 0.3),
            0.0);
}

// With noisy board poses the cost is flat within tens of ms of the true offset: a configured
// offset a few ms off must be left to the estimator, not "corrected" onto a noise minimum.
TEST(Initialization, ClockCheckLeavesASmallOffsetAlone) {
  const auto trajectory = handheld();
  Eigen::Matrix3d R_C_I;
  R_C_I << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  const auto gyro_at = [&](TimeNs t) { return trajectory.evaluate(toSeconds(t)).w_I; };
  int corrected = 0;
  for (std::uint32_t seed = 1; seed <= 20; ++seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> noise(0.0, 0.004);  // [rad] per board pose
    std::deque<std::pair<TimeNs, Eigen::Matrix3d>> rotations;
    for (int i = 0; i < 45; ++i) {
      const double t_imu = 3.0 + i / 30.0;
      const Eigen::Vector3d n(noise(rng), noise(rng), noise(rng));
      const Eigen::Matrix3d R_G_C =
          trajectory.evaluate(t_imu).T_G_I.rotation() * R_C_I.transpose() * lie::expSO3(n);
      rotations.emplace_back(fromSeconds(t_imu - 0.004), R_G_C);  // 4 ms behind
    }
    const double delta = clockCorrection(rotations, R_C_I.transpose(), 0, fromSeconds(2.0),
                                         fromSeconds(6.0), gyro_at, 0.3);
    // Either left alone or moved towards the truth, never past it by a frame period.
    if (delta != 0.0) ++corrected;
    EXPECT_LT(std::abs(delta - 0.004), 0.006) << seed << ": " << delta;
  }
  std::printf("small offset corrected in %d of 20 noisy runs\n", corrected);
  // Measured: 0 of 20; without the check against the configured offset's own cost, 20 of 20,
  // one of them 10.7 ms (6.7 ms past the truth).
  EXPECT_LE(corrected, 5);
}

}  // namespace
}  // namespace mvis
