// Readings corrected by known IMU intrinsics follow the calibrated model with transformed
// biases (imu_correction.h), checked against the rpng model written out directly.
#include <gtest/gtest.h>

#include <cmath>
#include <deque>

#include "mvis/common/lie.h"
#include "mvis/inertial/imu_correction.h"

namespace mvis {
namespace {

ImuIntrinsics someIntrinsics() {
  ImuIntrinsics in;
  in.Tw << 1.003, -0.002, 0.001, 0, 0.998, 0.0025, 0, 0, 1.001;
  in.Ta << 0.997, 0.003, -0.001, 0, 1.002, -0.002, 0, 0, 1.004;
  in.Tg << 1e-3, -5e-4, 2e-4, 3e-4, 8e-4, -1e-4, -2e-4, 1e-4, 6e-4;
  in.R_IMUtoACC = lie::expSO3(Eigen::Vector3d(0.003, -0.002, 0.001));
  return in;
}

TEST(ImuCorrection, CorrectedReadingsFollowTheCalibratedModel) {
  const ImuIntrinsics in = someIntrinsics();
  const ImuCorrection correction(in);
  EXPECT_FALSE(correction.identity);
  const Eigen::Vector3d b_g(0.01, -0.02, 0.005), b_a(0.1, -0.05, 0.2);
  // The biases the corrected readings carry (imu_correction.h).
  const Eigen::Vector3d b_a_c = in.R_IMUtoACC.transpose() * in.Ta.inverse() * b_a;
  const Eigen::Vector3d b_g_c = in.Tw.inverse() * (b_g - in.Tg * b_a_c);
  // biases() gives the same (what IMU-rate propagation subtracts from corrected readings).
  Eigen::Vector3d b_g_out, b_a_out;
  correction.biases(b_g, b_a, &b_g_out, &b_a_out);
  EXPECT_LT((b_a_out - b_a_c).norm(), 1e-15);
  EXPECT_LT((b_g_out - b_g_c).norm(), 1e-15);
  for (int k = 0; k < 5; ++k) {
    const Eigen::Vector3d w_I(0.3 * k - 0.5, 1.1 - 0.2 * k, 0.4), a_I(0.5, -9.7 + k, 1.0 - k);
    ImuMeasurement raw;
    raw.gyro = in.Tw * w_I + in.Tg * a_I + b_g;
    raw.accel = in.Ta * in.R_IMUtoACC * a_I + b_a;
    const ImuMeasurement c = correction.apply(raw, false);
    EXPECT_LT((c.accel - (a_I + b_a_c)).norm(), 1e-12) << k;
    EXPECT_LT((c.gyro - (w_I + b_g_c)).norm(), 1e-12) << k;
    // A gyroscope: apply() corrects the scale and misalignment; its Tg term is -gravity a_I
    // once the specific force a_I at it is known.
    ImuMeasurement gyro_raw;
    gyro_raw.gyro = in.Tw * w_I + in.Tg * a_I + b_g;
    const ImuMeasurement g = correction.apply(gyro_raw, true);
    EXPECT_LT((g.gyro - correction.gravity * a_I - (w_I + in.Tw.inverse() * b_g)).norm(), 1e-12)
        << k;
  }
  // Calibrated intrinsics change nothing.
  const ImuCorrection none;
  EXPECT_TRUE(none.identity);
  ImuMeasurement raw;
  raw.gyro = Eigen::Vector3d(1, 2, 3);
  raw.accel = Eigen::Vector3d(4, 5, 6);
  EXPECT_EQ(none.apply(raw, false).gyro, raw.gyro);
  EXPECT_EQ(none.apply(raw, false).accel, raw.accel);
}

// Readings resampled between real ones (readingsBetween's cubic, imu_preintegration.h) and then
// corrected equal the corrected readings resampled, biases subtracted too (the re-integration's
// affine model, imu_reintegration.h): the cubic's weights sum to one. So the estimator may
// resample raw readings once and correct or re-integrate them at any biases and intrinsics later.
TEST(ImuCorrection, CommutesWithTheCubicResampling) {
  const ImuCorrection correction(someIntrinsics());
  const Eigen::Vector3d bg(0.01, -0.02, 0.005), ba(0.1, 0.05, -0.2);
  const auto correct = [&](ImuMeasurement m) {
    m.gyro -= bg;
    m.accel -= ba;
    return correction.apply(m, false);
  };
  std::deque<ImuMeasurement> raw, corrected;
  for (int k = 0; k < 6; ++k) {
    ImuMeasurement m;
    m.stamp_ns = fromSeconds(0.01 * k + 0.001 * (k % 2));  // uneven spacing
    m.gyro = Eigen::Vector3d(0.3 * k - 0.5, std::sin(k), 0.4 * k * k);
    m.accel = Eigen::Vector3d(0.5 * k, -9.7 + std::cos(k), 1.0 - k);
    raw.push_back(m);
    corrected.push_back(correct(m));
  }
  const TimeNs max_interval = fromSeconds(0.025);
  const auto a = readingsBetween(raw, fromSeconds(0.012), fromSeconds(0.037), fromSeconds(0.0025),
                                 max_interval);
  const auto b = readingsBetween(corrected, fromSeconds(0.012), fromSeconds(0.037),
                                 fromSeconds(0.0025), max_interval);
  ASSERT_EQ(a.size(), b.size());
  ASSERT_GT(a.size(), 10u);
  for (std::size_t i = 0; i < a.size(); ++i) {
    const ImuMeasurement c = correct(a[i]);
    EXPECT_EQ(c.stamp_ns, b[i].stamp_ns);
    EXPECT_LT((c.gyro - b[i].gyro).norm(), 1e-12) << i;
    EXPECT_LT((c.accel - b[i].accel).norm(), 1e-12) << i;
  }
}

}  // namespace
}  // namespace mvis
