// Simulated inertial data against the trajectory, independently of the estimator: derivatives
// against finite differences, dead reckoning against the trajectory, the rigid-body relation of
// an auxiliary IMU against its own differentiated pose, the intrinsic model's inverse.
#include <gtest/gtest.h>

#include <cmath>

#include "mvis/sim/imu_simulator.h"
#include "sim_test_util.h"

namespace mvis {
namespace {

using test::handheld;
using test::idealImu;

TEST(SimTrajectory, DerivativesMatchFiniteDifferences) {
  const auto trajectory = handheld();
  const double h = 1e-5;
  for (double t : {0.0, 1.3, 4.7, 9.1}) {
    const TrajectoryState s = trajectory.evaluate(t);
    const TrajectoryState before = trajectory.evaluate(t - h), after = trajectory.evaluate(t + h);
    // Central differences: O(h^2) truncation (~1e-10 here) and ~1e-16 / h = 1e-11 round-off in
    // positions, more in rotations through Log; 1e-6 leaves margin and catches any wrong term
    // (those are of order 0.1-10).
    EXPECT_LT((s.v_G - (after.T_G_I.p - before.T_G_I.p) / (2 * h)).norm(), 1e-6);
    EXPECT_LT((s.a_G - (after.v_G - before.v_G) / (2 * h)).norm(), 1e-6);
    const Eigen::Vector3d w_numeric =
        lie::logQuat(before.T_G_I.q.conjugate() * after.T_G_I.q) / (2 * h);
    EXPECT_LT((s.w_I - w_numeric).norm(), 1e-6) << "t " << t;
    EXPECT_LT((s.dw_I - (after.w_I - before.w_I) / (2 * h)).norm(), 1e-6) << "t " << t;
  }
}

// Dead reckoning with noise-free, bias-free samples reproduces the trajectory; a sign or frame
// error in gravity, specific force or angular velocity would be off by metres.
TEST(SimImu, IntegratingIdealSamplesReproducesTheTrajectory) {
  const auto trajectory = handheld();
  const InertialSensor imu = idealImu(1000.0);
  ImuSimulationOptions options;
  options.noise = false;
  options.biases = false;
  const auto samples = simulateImu(
      imu, [&](double t) { return trajectory.evaluate(t); }, 0, 0, fromSeconds(5.0), options);
  ASSERT_EQ(samples.size(), 5001u);
  TrajectoryState start = trajectory.evaluate(0.0);
  Eigen::Quaterniond q = start.T_G_I.q;
  Eigen::Vector3d p = start.T_G_I.p, v = start.v_G;
  for (std::size_t k = 0; k + 1 < samples.size(); ++k) {
    const double dt = toSeconds(samples[k + 1].stamp_ns - samples[k].stamp_ns);
    // Trapezoidal rule on angular velocity and on world acceleration.
    const Eigen::Quaterniond q_next =
        q * lie::expQuat(0.5 * (samples[k].gyro + samples[k + 1].gyro) * dt);
    const Eigen::Vector3d a0 = q * samples[k].accel + kGravity_G;
    const Eigen::Vector3d a1 = q_next * samples[k + 1].accel + kGravity_G;
    p += v * dt + (a0 / 3.0 + a1 / 6.0) * dt * dt;
    v += 0.5 * (a0 + a1) * dt;
    q = q_next.normalized();
  }
  const TrajectoryState end = trajectory.evaluate(5.0);
  // Second-order integration at 1 kHz over 5 s: errors of order dt^2 * T * |jerk| ~ 1e-5.
  EXPECT_LT((p - end.T_G_I.p).norm(), 5e-4);
  EXPECT_LT((v - end.v_G).norm(), 5e-4);
  EXPECT_LT(lie::logQuat(q.conjugate() * end.T_G_I.q).norm(), 1e-5);
}

// The auxiliary IMU's readings against its own pose, differentiated numerically: no use of the
// lever-arm formula the simulator applies.
TEST(SimImu, AuxiliaryImuObeysTheRigidBodyRelation) {
  const auto trajectory = handheld();
  InertialSensor aux = idealImu(100.0);
  aux.name = "imu1";
  const SE3 T_b_a(lie::expQuat(Eigen::Vector3d(0.1, -0.2, 1.4)), Eigen::Vector3d(0.2, -0.1, 0.05));
  aux.T_i_b = T_b_a.inverse();
  aux.time_offset = 0.0;
  ImuSimulationOptions options;
  options.noise = false;
  options.biases = false;
  const auto samples = simulateImu(
      aux, [&](double t) { return trajectory.evaluate(t); }, 0, 0, fromSeconds(3.0), options);
  const auto auxPose = [&](double t) {
    const TrajectoryState s = trajectory.evaluate(t);
    return s.T_G_I * T_b_a;
  };
  const double h = 1e-4;
  for (std::size_t k = 10; k < samples.size(); k += 37) {
    const double t = toSeconds(samples[k].stamp_ns);
    const SE3 before = auxPose(t - h), now = auxPose(t), after = auxPose(t + h);
    const Eigen::Vector3d a_G = (after.p - 2.0 * now.p + before.p) / (h * h);
    const Eigen::Vector3d f_expected = now.q.conjugate() * (a_G - kGravity_G);
    const Eigen::Vector3d w_expected = lie::logQuat(before.q.conjugate() * after.q) / (2 * h);
    // Second differences with h = 1e-4: truncation ~h^2 |p''''| ~ 1e-7, round-off
    // ~1e-16 / h^2 ~ 1e-8 m/s^2.
    EXPECT_LT((samples[k].accel - f_expected).norm(), 1e-5) << "t " << t;
    EXPECT_LT((samples[k].gyro - w_expected).norm(), 1e-6) << "t " << t;
  }
}

TEST(SimImu, TimeOffsetShiftsTheSensorClock) {
  const auto trajectory = handheld();
  InertialSensor aux = idealImu(200.0);
  aux.time_offset = 0.0125;  // t_imu0 = t_aux + 0.0125
  ImuSimulationOptions options;
  options.noise = false;
  options.biases = false;
  const auto samples = simulateImu(
      aux, [&](double t) { return trajectory.evaluate(t); }, 0, fromSeconds(1.0), fromSeconds(1.0),
      options);
  ASSERT_EQ(samples.size(), 1u);
  EXPECT_EQ(samples[0].stamp_ns, fromSeconds(1.0));
  EXPECT_LT((samples[0].gyro - trajectory.evaluate(1.0125).w_I).norm(), 1e-12);
}

TEST(SimImu, IntrinsicModelInvertsAsTheReportSays) {
  const auto trajectory = handheld();
  InertialSensor imu = idealImu(400.0);
  imu.model = ImuModel::kRpng;
  imu.intrinsics.Tw << 1.003, 0.002, -0.001, 0, 0.997, 0.003, 0, 0, 1.002;
  imu.intrinsics.Ta << 0.998, -0.002, 0.001, 0, 1.004, 0.002, 0, 0, 0.996;
  imu.intrinsics.Tg << 1e-3, -2e-4, 3e-4, 5e-4, 1e-3, -1e-4, 2e-4, 3e-4, -1e-3;
  imu.intrinsics.R_IMUtoACC = lie::expSO3(Eigen::Vector3d(0.003, -0.002, 0.001));
  ImuSimulationOptions options;
  options.noise = false;
  options.initial_bias_gyro << 0.01, -0.02, 0.005;
  options.initial_bias_accel << 0.1, 0.05, -0.08;
  const auto samples = simulateImu(
      imu, [&](double t) { return trajectory.evaluate(t); }, 0, 0, fromSeconds(1.0), options);
  for (std::size_t k = 0; k < samples.size(); k += 50) {
    const ImuSample& s = samples[k];
    const TrajectoryState truth = trajectory.evaluate(toSeconds(s.stamp_ns));
    // Report Eq. 4 then Eq. 3, with Da = Ta^-1, Dw = Tw^-1 and R_IMUtoGYRO = I.
    const Eigen::Vector3d a_I = imu.intrinsics.R_IMUtoACC.transpose() *
                                imu.intrinsics.Ta.inverse() * (s.accel - s.bias_accel);
    const Eigen::Vector3d w_I =
        imu.intrinsics.Tw.inverse() * (s.gyro - s.bias_gyro - imu.intrinsics.Tg * a_I);
    EXPECT_LT((a_I - truth.specificForce()).norm(), 1e-12);
    EXPECT_LT((w_I - truth.w_I).norm(), 1e-12);
  }
}

TEST(SimImu, NoiseHasTheContinuousTimeDensityAndSeedsRepeat) {
  const auto still = [](double) {
    TrajectoryState s;
    return s;
  };
  const InertialSensor imu = idealImu(400.0);
  ImuSimulationOptions options;
  options.biases = false;
  options.seed = 42;
  const auto samples = simulateImu(imu, still, 0, 0, fromSeconds(50.0), options);
  double sum_sq = 0.0;
  for (const auto& s : samples) sum_sq += s.gyro.squaredNorm();
  const double sigma = std::sqrt(sum_sq / (3.0 * samples.size()));
  // 60000 values: the relative standard error of a standard deviation is 1/sqrt(2N) = 0.3%.
  EXPECT_NEAR(sigma / (imu.noise.gyroscope_noise_density * std::sqrt(400.0)), 1.0, 0.015);
  // Still and level: the accelerometer reads +9.81 upwards.
  double mean_z = 0.0;
  for (const auto& s : samples) mean_z += s.accel.z();
  EXPECT_NEAR(mean_z / samples.size(), 9.81, 1e-3);
  const auto again = simulateImu(imu, still, 0, 0, fromSeconds(50.0), options);
  EXPECT_EQ(again[12345].gyro, samples[12345].gyro);
  EXPECT_EQ(again.back().accel, samples.back().accel);
}

}  // namespace
}  // namespace mvis
