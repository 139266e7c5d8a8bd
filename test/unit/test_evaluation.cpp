// Evaluation against the truth (mvis/estimator/evaluation.h): the time offsets' information
// floor on a motion whose answer is known in closed form.
#include <gtest/gtest.h>

#include <cmath>

#include "mvis/estimator/evaluation.h"

namespace mvis {
namespace {

// Yaw about gravity, psi(t) = A sin(2 pi f t), at a fixed point: the rate is (0, 0, psi') and
// the specific force R^T (0, 0, g) = (0, 0, g) never changes, so the information is the
// gyroscope's alone, int psi''^2 dt / q^2 = T A^2 (2 pi f)^4 / 2 / q^2 over whole periods.
TEST(TimeOffsetFloor, MatchesTheClosedFormOfAYawOscillation) {
  const double A = 0.5, f = 1.5, T = 10.0, rate = 500.0;
  std::vector<StampedPose> truth;
  for (int i = 0; i <= static_cast<int>(T * rate); ++i) {
    const double t = i / rate;
    SE3 pose;
    pose.q = Eigen::Quaterniond(
        Eigen::AngleAxisd(A * std::sin(2 * M_PI * f * t), Eigen::Vector3d::UnitZ()));
    pose.p = Eigen::Vector3d(0.3, -0.2, 1.2);
    truth.emplace_back(1700000000000000000LL + static_cast<TimeNs>(i) * 2000000, pose);
  }
  ImuNoise noise;
  noise.gyroscope_noise_density = 1.7e-4;
  noise.accelerometer_noise_density = 2e-3;
  const double w = 2 * M_PI * f;
  const double expected = noise.gyroscope_noise_density / std::sqrt(T * A * A * std::pow(w, 4) / 2);
  const double floor = timeOffsetFloor(truth, noise);
  std::printf("floor %.6f ms, closed form %.6f ms\n", floor * 1e3, expected * 1e3);
  // Finite differences at 500 Hz of a 1.5 Hz signal: ~(w h)^2 / 12 ~ 1e-4 relative.
  EXPECT_NEAR(floor / expected, 1.0, 2e-3);
  // Half the gyroscope's noise: half the floor (the accelerometer adds nothing here).
  noise.gyroscope_noise_density /= 2;
  EXPECT_NEAR(timeOffsetFloor(truth, noise) / floor, 0.5, 1e-6);
  // No noise density: no floor.
  noise.gyroscope_noise_density = 0.0;
  EXPECT_TRUE(std::isnan(timeOffsetFloor(truth, noise)));
}

}  // namespace
}  // namespace mvis
