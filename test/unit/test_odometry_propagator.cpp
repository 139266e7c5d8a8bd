// IMU-rate odometry beside the estimator (odometry_propagator.h): from an anchor at the true
// state, noise-free readings carry it along the simulator's trajectory; a new anchor gives what a
// fresh propagator gives; the intrinsics in the anchor are applied; and every reading that gives
// no state says why.
#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <optional>
#include <vector>

#include "mvis/estimator/odometry_propagator.h"
#include "sim_test_util.h"

namespace mvis {
namespace {

using test::handheld;
using test::idealImu;
using test::noiseFreeReadings;

const Eigen::Vector3d kGravity(0.0, 0.0, -9.81);

PropagationAnchor trueAnchor(const SinusoidTrajectory& trajectory, double t) {
  const TrajectoryState s = trajectory.evaluate(t);
  PropagationAnchor a;
  a.valid = true;
  a.state.stamp_ns = fromSeconds(t);
  a.state.T_G_I = s.T_G_I;
  a.state.v_G = s.v_G;
  a.gravity_G = kGravity;
  return a;
}

double positionError(const EstimatorState& s, const SinusoidTrajectory& trajectory) {
  return (s.T_G_I.p - trajectory.evaluate(toSeconds(s.stamp_ns)).T_G_I.p).norm();
}

double rotationError(const EstimatorState& s, const SinusoidTrajectory& trajectory) {
  const Eigen::Quaterniond q = trajectory.evaluate(toSeconds(s.stamp_ns)).T_G_I.q;
  return lie::logQuat(q.conjugate() * s.T_G_I.q).norm();
}

TEST(OdometryPropagator, FollowsTheTrajectoryFromEachAnchor) {
  const auto trajectory = handheld();
  const InertialSensor imu = idealImu(500.0);
  const std::vector<ImuMeasurement> readings = noiseFreeReadings(imu, trajectory, 0.0, 3.0);
  OdometryPropagator propagator(imu, 0.0025);
  // The anchor between readings (1.0011 s), as a window state at a camera's time is.
  const double t_anchor = 1.0011, t_second = 2.0013;
  std::vector<EstimatorState> out;
  for (const auto& m : readings) {
    const double t = toSeconds(m.stamp_ns);
    // The anchor arrives late (as from the estimator's thread): 30 ms after its state's time.
    if (t >= t_anchor + 0.03 && out.empty()) propagator.setAnchor(trueAnchor(trajectory, t_anchor));
    if (t >= t_second + 0.03 && toSeconds(out.back().stamp_ns) < t_second + 0.03) {
      propagator.setAnchor(trueAnchor(trajectory, t_second));
    }
    if (auto s = propagator.add(m)) {
      out.push_back(*s);
    } else {
      EXPECT_FALSE(propagator.why().empty());
    }
  }
  ASSERT_FALSE(out.empty());
  // Odometry from the first reading after the anchor arrived to the end, every reading.
  EXPECT_NEAR(toSeconds(out.front().stamp_ns), t_anchor + 0.03, 0.0021);
  const auto after = std::count_if(readings.begin(), readings.end(), [&](const ImuMeasurement& m) {
    return toSeconds(m.stamp_ns) >= t_anchor + 0.03;
  });
  EXPECT_EQ(out.size(), static_cast<std::size_t>(after));
  // The midpoint scheme errs by O(dt^2) (test_imu_factor: 2e-6 m over 0.1 s at 200 Hz): over
  // the 1 s from each anchor at 500 Hz the errors grow to ~1e-5 m / 1e-6 rad; the bounds are
  // 10x that, and 1000x below what one reading placed wrong would cause.
  double worst_p = 0.0, worst_r = 0.0;
  for (const auto& s : out) {
    worst_p = std::max(worst_p, positionError(s, trajectory));
    worst_r = std::max(worst_r, rotationError(s, trajectory));
  }
  std::printf("worst position %.2e m, rotation %.2e rad over %zu states\n", worst_p, worst_r,
              out.size());
  EXPECT_LT(worst_p, 1e-4);
  EXPECT_LT(worst_r, 1e-5);

  // A new anchor keeps nothing of the old one: exactly what a propagator that never had the old
  // one gives, anchored at the same reading.
  OdometryPropagator fresh(imu, 0.0025);
  std::optional<EstimatorState> s;
  for (const auto& m : readings) {
    const double t = toSeconds(m.stamp_ns);
    if (t < t_second - 1.0) continue;
    if (t >= t_second + 0.03 && !s) fresh.setAnchor(trueAnchor(trajectory, t_second));
    s = fresh.add(m);
  }
  ASSERT_TRUE(s.has_value());
  const EstimatorState* last_fresh = &*s;
  EXPECT_EQ(last_fresh->stamp_ns, out.back().stamp_ns);
  EXPECT_EQ((last_fresh->T_G_I.p - out.back().T_G_I.p).norm(), 0.0);
  EXPECT_EQ((last_fresh->v_G - out.back().v_G).norm(), 0.0);
}

// Re-anchored in three steps (the nodelet's: integrated on the estimator's thread while readings
// keep coming): the same states as setAnchor() to rounding; a reset in between drops it.
TEST(OdometryPropagator, PreparedAnchorsMatchTheDirectOnes) {
  const auto trajectory = handheld();
  const InertialSensor imu = idealImu(500.0);
  const std::vector<ImuMeasurement> readings = noiseFreeReadings(imu, trajectory, 0.0, 2.0);
  OdometryPropagator direct(imu, 0.0025), prepared(imu, 0.0025);
  const PropagationAnchor anchor = trueAnchor(trajectory, 1.0011);
  std::optional<PreparedAnchor> pending;
  std::size_t compared = 0;
  double worst = 0.0;
  for (std::size_t k = 0; k < readings.size(); ++k) {
    const double t = toSeconds(readings[k].stamp_ns);
    if (t >= 1.3 && !pending && compared == 0) {
      direct.setAnchor(anchor);
      pending = prepared.prepare(anchor);  // 0.3 s of readings copied
      pending->integrate();
    }
    if (t >= 1.31 && pending) {  // installed 5 readings later
      prepared.install(std::move(*pending));
      pending.reset();
    }
    const auto a = direct.add(readings[k]);
    const auto b = prepared.add(readings[k]);
    if (t >= 1.31) {
      ASSERT_TRUE(a && b) << t;
      worst = std::max(worst, (a->T_G_I.p - b->T_G_I.p).norm());
      ++compared;
    }
  }
  // The two split the same readings differently between resampled and single steps.
  EXPECT_GT(compared, 300u);
  EXPECT_LT(worst, 1e-7);
  // A reset (the estimator restarted) between prepare and install: the anchor is dropped.
  PreparedAnchor stale = prepared.prepare(trueAnchor(trajectory, 1.9));
  stale.integrate();
  prepared.reset();
  prepared.install(std::move(stale));
  EXPECT_FALSE(prepared.add(readings.back()).has_value());
  EXPECT_EQ(prepared.why(), "no state to propagate yet");
}

TEST(OdometryPropagator, AppliesTheAnchorsIntrinsics) {
  const auto trajectory = handheld();
  InertialSensor imu = idealImu(500.0);
  imu.intrinsics = test::tableFourIntrinsics();
  const std::vector<ImuMeasurement> readings = noiseFreeReadings(imu, trajectory, 0.5, 2.0);
  double error_with = 0.0, error_without = 0.0;
  for (const bool corrected : {true, false}) {
    OdometryPropagator propagator(imu, 0.0025);
    PropagationAnchor anchor = trueAnchor(trajectory, 1.0);
    if (corrected) anchor.correction = ImuCorrection(imu.intrinsics);
    propagator.setAnchor(anchor);
    std::optional<EstimatorState> s;
    for (const auto& m : readings) s = propagator.add(m);
    ASSERT_TRUE(s.has_value());
    (corrected ? error_with : error_without) = positionError(*s, trajectory);
  }
  // Over 1 s, Table 4's intrinsics left uncorrected move the pose by centimetres (Tg's 1e-3
  // rad/s per m/s^2 alone turns gravity by 10 mrad); corrected, the integration's own error.
  std::printf("after 1 s: %.2e m corrected, %.2e m not\n", error_with, error_without);
  EXPECT_LT(error_with, 1e-4);
  EXPECT_GT(error_without, 1e-2);
}

TEST(OdometryPropagator, SaysWhyAReadingGivesNoState) {
  const auto trajectory = handheld();
  const InertialSensor imu = idealImu(500.0);
  const std::vector<ImuMeasurement> readings = noiseFreeReadings(imu, trajectory, 0.0, 8.0);
  OdometryPropagator propagator(imu, 0.0025, 5.0);
  EXPECT_FALSE(propagator.add(readings[0]).has_value());
  EXPECT_EQ(propagator.why(), "no state to propagate yet");
  // An anchor older than the 5 s of readings kept: the estimator is that far behind.
  for (std::size_t k = 1; k < 3500; ++k) propagator.add(readings[k]);  // to 7 s
  propagator.setAnchor(trueAnchor(trajectory, 1.0));
  EXPECT_FALSE(propagator.add(readings[3500]).has_value());
  EXPECT_NE(propagator.why().find("older than the readings kept"), std::string::npos)
      << propagator.why();
  // Repeated and non-finite readings are dropped; a newer anchor propagates again.
  propagator.setAnchor(trueAnchor(trajectory, 6.5));
  EXPECT_FALSE(propagator.add(readings[3500]).has_value());
  EXPECT_EQ(propagator.why(), "reading out of order or repeated");
  ImuMeasurement bad = readings[3501];
  bad.gyro.x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(propagator.add(bad).has_value());
  EXPECT_EQ(propagator.why(), "non-finite reading");
  const auto s = propagator.add(readings[3501]);
  ASSERT_TRUE(s.has_value()) << propagator.why();
  EXPECT_LT(positionError(*s, trajectory), 1e-4);
  // A reading before the anchor gives nothing; a clock 2 s back (a bag replayed) forgets it.
  OdometryPropagator late(imu, 0.0025);
  late.add(readings[0]);
  late.setAnchor(trueAnchor(trajectory, 0.5));
  EXPECT_FALSE(late.add(readings[10]).has_value());
  EXPECT_EQ(late.why(), "reading before the newest state");
  for (std::size_t k = 11; k < 2000; ++k) late.add(readings[k]);
  EXPECT_FALSE(late.add(readings[5]).has_value());
  EXPECT_EQ(late.why(), "no state to propagate yet");
}

}  // namespace
}  // namespace mvis
