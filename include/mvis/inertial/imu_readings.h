// Inertial readings and their interpolation, shared by the preintegration, the re-integration
// with intrinsics and the estimator's buffers.
//
// Readings far apart (an auxiliary IMU at 100 Hz has 3-4 between window states) leave the
// midpoint scheme an error of order dt^2 in the deltas that does not average out over a run.
// readingsBetween resamples them in shorter steps from the cubic through the four readings
// around each step (the signal's error O(dt^4)), leaving the scheme's error at the step's. The
// intrinsics' corrections (imu_correction.h, imu_reintegration.h) are affine in the readings and
// the cubic's weights sum to one, so resampling raw readings and correcting them commute:
// re-integration works on the same resampled readings.
#pragma once

#include <Eigen/Core>
#include <deque>
#include <vector>

#include "mvis/common/time.h"

namespace mvis {

// One inertial reading, stamped in the base clock.
struct ImuMeasurement {
  TimeNs stamp_ns = 0;
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();   // [rad/s]
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();  // [m/s^2]
  // Time between the two real readings around the interval that ends here (0: just the
  // interval). An interpolated reading inside a gap carries the gap's length, so every piece of
  // a gap split by window states is treated as the gap it is.
  TimeNs span_ns = 0;
};

// Reading at time t by linear interpolation between two readings bracketing it.
ImuMeasurement interpolateMeasurement(const ImuMeasurement& a, const ImuMeasurement& b, TimeNs t);

// The reading at t in a buffer of increasing stamps (the nearest one outside the buffer),
// interpolated between its neighbours: linearly, or with max_interval_ns > 0 by the cubic
// through the four readings around t where none of their three intervals is longer (a gap).
ImuMeasurement readingIn(const std::deque<ImuMeasurement>& buffer, TimeNs t,
                         TimeNs max_interval_ns = 0);

// The readings over [a, b] with interpolated readings at both ends; with max_step_ns > 0 also
// between readings further apart than that (not across a gap), in equal steps no longer.
// Interpolation as readingIn's.
std::vector<ImuMeasurement> readingsBetween(const std::deque<ImuMeasurement>& buffer, TimeNs a,
                                            TimeNs b, TimeNs max_step_ns = 0,
                                            TimeNs max_interval_ns = 0);

}  // namespace mvis
