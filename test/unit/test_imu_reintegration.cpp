// Re-integration of raw readings with IMU intrinsics (imu_reintegration.h): the model's
// conventions against the simulator's (readings made with Table 4 intrinsics integrate back to
// the true motion only with them), agreement with ImuPreintegration at identity intrinsics, the
// exact Jacobian against central differences, and the block's round trip to rpng matrices; the
// same for the kalibr model's parametrization.
#include <gtest/gtest.h>

#include "mvis/common/lie.h"
#include "mvis/inertial/imu_preintegration.h"
#include "mvis/inertial/imu_reintegration.h"
#include "mvis/sim/imu_simulator.h"
#include "sim_test_util.h"

namespace mvis {
namespace {

using test::handheld;
using test::idealImu;
using test::intrinsicsBlock;
using test::tableFourIntrinsics;

constexpr double kTi = 3.0, kTj = 3.1;

// Table 4's sizes in the kalibr model: Tw, Ta lower triangular, the gyroscope turned by
// R_IMUtoGYRO, the accelerometer defining the frame.
ImuIntrinsics tableFourKalibr() {
  const ImuIntrinsics rpng = tableFourIntrinsics();
  ImuIntrinsics in;
  in.Tw = rpng.Tw.transpose();
  in.Ta = rpng.Ta.transpose();
  in.Tg = rpng.Tg;
  in.R_IMUtoGYRO = rpng.R_IMUtoACC;
  return in;
}

// The kalibr block of `in` relative to R0 = I (its rotation entries generic) and its frame.
std::vector<double> kalibrBlock(const ImuIntrinsics& in, ImuIntrinsicsFrame* frame) {
  std::vector<double> b(kImuIntrinsicsSize);
  intrinsicsToBlock(in, b.data(), true);
  const Eigen::Vector3d theta = lie::logSO3(in.R_IMUtoGYRO.transpose());
  for (int k = 0; k < 3; ++k) b[ImuIntrinsicsLayout::kAccRotation + k] = theta[k];
  frame->kalibr = true;
  return b;
}

std::vector<ImuMeasurement> readings(const InertialSensor& sensor) {
  return test::noiseFreeReadings(sensor, handheld(), kTi, kTj);
}

// Pose and velocity errors at t_j when predicting from the truth at t_i with the deltas.
struct PredictionError {
  double rotation, position, velocity;
};
PredictionError predictionError(const ImuDeltas& d) {
  const auto trajectory = handheld();
  const TrajectoryState si = trajectory.evaluate(kTi), sj = trajectory.evaluate(kTj);
  const double T = d.duration;
  const Eigen::Matrix3d R_i = si.T_G_I.rotation();
  const Eigen::Matrix3d R_j = R_i * d.dR;
  const Eigen::Vector3d p_j = si.T_G_I.p + si.v_G * T + 0.5 * kGravity_G * T * T + R_i * d.dp;
  const Eigen::Vector3d v_j = si.v_G + kGravity_G * T + R_i * d.dv;
  return {lie::logSO3(sj.T_G_I.rotation().transpose() * R_j).norm(), (p_j - sj.T_G_I.p).norm(),
          (v_j - sj.v_G).norm()};
}

TEST(ImuReintegration, UndoesTheSimulatorsIntrinsics) {
  InertialSensor sensor = idealImu(500.0);
  sensor.model = ImuModel::kRpng;
  sensor.intrinsics = tableFourIntrinsics();
  const auto m = readings(sensor);
  const std::vector<double> block = intrinsicsBlock(sensor.intrinsics);
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  const ImuIntrinsicsFrame frame;  // R0 = I
  const PredictionError with = predictionError(
      reintegrate(m, deltaVariables(zero.data(), zero.data(), block.data()), frame, false));
  const PredictionError without = predictionError(
      reintegrate(m, deltaVariables(zero.data(), zero.data(), nullptr), frame, false));
  // With them, only the midpoint scheme's error remains (measured 1.3e-7 rad, 1.3e-6 m/s,
  // 2.8e-7 m over 0.1 s at 500 Hz); without them 1.1e-3 rad, 6.3e-3 m/s, 3.2e-4 m.
  EXPECT_LT(with.rotation, 1e-6);
  EXPECT_LT(with.velocity, 4e-6);
  EXPECT_LT(with.position, 1e-6);
  EXPECT_GT(without.rotation, 50.0 * with.rotation);
  EXPECT_GT(without.velocity, 50.0 * with.velocity);
}

TEST(ImuReintegration, UndoesTheSimulatorsKalibrIntrinsics) {
  InertialSensor sensor = idealImu(500.0);
  sensor.model = ImuModel::kKalibr;
  sensor.intrinsics = tableFourKalibr();
  const auto m = readings(sensor);
  ImuIntrinsicsFrame frame;  // R0 = I
  const std::vector<double> block = kalibrBlock(sensor.intrinsics, &frame);
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  const PredictionError with = predictionError(
      reintegrate(m, deltaVariables(zero.data(), zero.data(), block.data()), frame, false));
  // Read as the rpng model (the same numbers, upper triangular and the rotation on the
  // accelerometer), the deltas miss the motion as without intrinsics.
  const PredictionError as_rpng = predictionError(reintegrate(
      m, deltaVariables(zero.data(), zero.data(), block.data()), ImuIntrinsicsFrame(), false));
  EXPECT_LT(with.rotation, 1e-6);
  EXPECT_LT(with.velocity, 4e-6);
  EXPECT_LT(with.position, 1e-6);
  EXPECT_GT(as_rpng.rotation, 50.0 * with.rotation);
  EXPECT_GT(as_rpng.velocity, 50.0 * with.velocity);
}

TEST(ImuReintegration, MatchesPreintegrationAtIdentityIntrinsics) {
  const InertialSensor sensor = idealImu(500.0);
  const auto m = readings(sensor);
  const Eigen::Vector3d bg(2e-3, -1e-3, 1.5e-3), ba(2e-2, 1e-2, -3e-2);
  ImuPreintegration pre(sensor.noise, bg, ba);
  for (const auto& r : m) pre.add(r);
  const ImuDeltas d =
      reintegrate(m, deltaVariables(bg.data(), ba.data(), nullptr), ImuIntrinsicsFrame(), true);
  EXPECT_LT(lie::logSO3(pre.deltaR().toRotationMatrix().transpose() * d.dR).norm(), 1e-12);
  EXPECT_LT((pre.deltaP() - d.dp).norm(), 1e-12);
  EXPECT_LT((pre.deltaV() - d.dv).norm(), 1e-12);
  // The preintegration's propagated bias Jacobians are the same derivatives.
  const ImuDeltas p = deltasOf(pre);
  const Eigen::Matrix<double, 9, 6> a = d.J.leftCols<6>(), b = p.J.leftCols<6>();
  EXPECT_LT((a - b).cwiseAbs().maxCoeff(), 1e-9 * (1.0 + a.cwiseAbs().maxCoeff())) << a << "\n\n"
                                                                                   << b;
}

TEST(ImuReintegration, JacobianMatchesCentralDifferences) {
  for (const bool kalibr : {false, true}) {
    for (bool gyro_only : {false, true}) {
      InertialSensor sensor = idealImu(500.0);
      sensor.intrinsics = kalibr ? tableFourKalibr() : tableFourIntrinsics();
      const auto m = readings(sensor);
      ImuIntrinsicsFrame frame;
      const std::vector<double> block =
          kalibr ? kalibrBlock(sensor.intrinsics, &frame) : intrinsicsBlock(sensor.intrinsics);
      frame.R0 = lie::expSO3(Eigen::Vector3d(0.1, -0.2, 0.3));  // a generic R0
      frame.gyro_only = gyro_only;
      const Eigen::Vector3d bg(2e-3, -1e-3, 1.5e-3), ba(2e-2, 1e-2, -3e-2);
      const ImuDeltas::Vector30d x = deltaVariables(bg.data(), ba.data(), block.data());
      const ImuDeltas d = reintegrate(m, x, frame, true);
      const double h = 1e-6;
      Eigen::Matrix<double, 9, kDeltaVariables> numeric;
      for (int k = 0; k < kDeltaVariables; ++k) {
        ImuDeltas::Vector30d xp = x, xm = x;
        xp[k] += h;
        xm[k] -= h;
        const ImuDeltas a = reintegrate(m, xp, frame, false), b = reintegrate(m, xm, frame, false);
        numeric.block<3, 1>(0, k) =
            (lie::logSO3(d.dR.transpose() * a.dR) - lie::logSO3(d.dR.transpose() * b.dR)) / (2 * h);
        numeric.block<3, 1>(3, k) = (a.dp - b.dp) / (2 * h);
        numeric.block<3, 1>(6, k) = (a.dv - b.dv) / (2 * h);
      }
      // Central differences with h = 1e-6 on deltas of size ~1: truncation ~1e-12, round-off
      // ~1e-16 / 1e-6 = 1e-10 (measured 4e-10 for Jacobian entries up to 1.05).
      EXPECT_LT((numeric - d.J).cwiseAbs().maxCoeff(), 1e-8) << gyro_only << kalibr;
      // A gyroscope's deltas do not depend on what it lacks (b_a, Da; its rotation with rpng,
      // which is the accelerometer's); they do on Tg through the specific force its readings
      // are given (here the readings' own accelerations).
      if (gyro_only) {
        using L = ImuIntrinsicsLayout;
        EXPECT_EQ(d.J.middleCols(3, 3).cwiseAbs().maxCoeff(), 0.0);
        EXPECT_EQ(d.J.middleCols(6 + L::kDa, 6).cwiseAbs().maxCoeff(), 0.0);
        if (!kalibr) {
          EXPECT_EQ(d.J.middleCols(6 + L::kAccRotation, 3).cwiseAbs().maxCoeff(), 0.0);
        }
        EXPECT_GT(d.J.block(0, 6 + L::kTg, 3, 9).cwiseAbs().maxCoeff(), 1e-3);
      }
    }
  }
}

TEST(ImuReintegration, BlockRoundTripsToRpngMatrices) {
  const ImuIntrinsics in = tableFourIntrinsics();
  double block[kImuIntrinsicsSize];
  intrinsicsToBlock(in, block);
  // Relative to R0 = R_IMUtoACC^T: theta = 0, Dw = Tw^-1.
  EXPECT_EQ(block[ImuIntrinsicsLayout::kAccRotation], 0.0);
  EXPECT_LT((upperTriangular(block) * in.Tw - Eigen::Matrix3d::Identity()).norm(), 1e-15);
  const ImuIntrinsics back = intrinsicsFromBlock(block, in.R_IMUtoACC.transpose());
  EXPECT_LT((back.Tw - in.Tw).norm(), 1e-15);
  EXPECT_LT((back.Ta - in.Ta).norm(), 1e-15);
  EXPECT_LT((back.Tg - in.Tg).norm(), 1e-15);
  EXPECT_LT((back.R_IMUtoACC - in.R_IMUtoACC).norm(), 1e-15);
  EXPECT_EQ(back.Tw(1, 0), 0.0);
}

TEST(ImuReintegration, BlockRoundTripsToKalibrMatrices) {
  const ImuIntrinsics in = tableFourKalibr();
  double block[kImuIntrinsicsSize];
  intrinsicsToBlock(in, block, true);
  ImuIntrinsicsFrame frame;
  frame.kalibr = true;
  frame.R0 = in.R_IMUtoGYRO.transpose();
  // Dw stored as its transpose's upper entries.
  EXPECT_LT((upperTriangular(block).transpose() * in.Tw - Eigen::Matrix3d::Identity()).norm(),
            1e-15);
  const ImuIntrinsics back = intrinsicsFromBlock(block, frame);
  EXPECT_LT((back.Tw - in.Tw).norm(), 1e-15);
  EXPECT_LT((back.Ta - in.Ta).norm(), 1e-15);
  EXPECT_LT((back.Tg - in.Tg).norm(), 1e-15);
  EXPECT_LT((back.R_IMUtoGYRO - in.R_IMUtoGYRO).norm(), 1e-15);
  EXPECT_TRUE(back.R_IMUtoACC.isIdentity(0.0));
  EXPECT_EQ(back.Tw(0, 1), 0.0);
}

}  // namespace
}  // namespace mvis
