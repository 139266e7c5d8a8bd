// The base IMU's readings as the estimator keeps them: a buffer of increasing stamps (base
// clock, corrected by the configured intrinsics on arrival), and what is computed from it:
// readings at any time (cubic through the four around it), the readings to integrate between two
// times (resampled in imu_integration_step_s steps, imu_readings.h), preintegration, gaps and the
// angular acceleration. Private to src/core/estimator.
//
// Owns: the readings. Asks nothing of the other parts; who trims it decides how far back the
// window and the initialization still need readings.
#pragma once

#include <deque>
#include <limits>
#include <memory>
#include <vector>

#include "mvis/inertial/imu_correction.h"
#include "mvis/inertial/imu_preintegration.h"
#include "mvis/rig/rig.h"

namespace mvis {
namespace estimator_internal {

// The gap below which an inertial sensor's readings are interpolated by the cubic through four
// of them (0: linear only, when readings are taken as they come or the rate is unknown).
TimeNs cubicIntervalNs(const InertialSensor& sensor, double integration_step_s);

class ImuBuffer {
 public:
  ImuBuffer(const InertialSensor& base, double integration_step_s);

  // The newest reading's stamp, or the lowest TimeNs when empty.
  TimeNs lastStamp() const {
    return readings_.empty() ? std::numeric_limits<TimeNs>::min() : readings_.back().stamp_ns;
  }
  bool empty() const { return readings_.empty(); }
  TimeNs firstStamp() const { return readings_.front().stamp_ns; }
  std::size_t size() const { return readings_.size(); }
  const std::deque<ImuMeasurement>& readings() const { return readings_; }
  // Appends a reading with a later stamp than lastStamp() (its span set to the interval since).
  void push(ImuMeasurement m);
  void clear() { readings_.clear(); }
  // Whether the readings reach t far enough for the cubic at t: past t, and the one after that
  // unless a gap follows t.
  bool reaches(TimeNs t) const;

  // The reading at t, interpolated between its neighbours (the nearest one outside the buffer).
  ImuMeasurement at(TimeNs t) const;
  // Readings over [a, b] with interpolated readings at both ends, as they come.
  std::vector<ImuMeasurement> between(TimeNs a, TimeNs b) const;
  // The readings over [a, b] to integrate: resampled at the integration step.
  std::vector<ImuMeasurement> toIntegrate(TimeNs a, TimeNs b) const;
  // Preintegrated over [a, b] at biases (bg, ba); the readings corrected by `correction` when
  // given (the current intrinsics estimate, for deltas used as they are), else as stored.
  std::shared_ptr<ImuPreintegration> preintegrate(TimeNs a, TimeNs b, const Eigen::Vector3d& bg,
                                                  const Eigen::Vector3d& ba,
                                                  const ImuCorrection* correction = nullptr) const;
  // Whether t falls between two readings further apart than maxInterval().
  bool insideGap(TimeNs t) const;
  // Readings further apart than this are a gap (2.5 nominal periods) [s]; 0 when the rate is
  // unknown.
  double maxInterval() const;
  // Angular acceleration at t: slope of a line fitted to the gyroscope readings within 10 ms.
  Eigen::Vector3d angularAcceleration(TimeNs t) const;
  // The reading at t from lines fitted to the readings within 10 ms (their values at t), at(t)
  // where fewer than three are there: the base motion at a window state (base_motion.h), which
  // shifts the auxiliary IMUs' and gyroscopes' ends by their time offsets' changes, and the rate
  // that shifts a camera frame's anchor (camera_frames.cpp). One
  // reading's white noise (the VI-Rig's gyroscope: 3.8e-3 rad/s) is all a rig that does not
  // turn shows of its rate, and a time offset's derivative there took it as motion.
  ImuMeasurement smoothedAt(TimeNs t) const;
  // What the readings over [a, b] tell of a time offset against them [1/s^2]: (b - a) times
  // |w'|^2 / q_g^2 + |f'|^2 / q_a^2 (evaluation.h's timeOffsetFloor), the rate's and specific
  // force's slopes from lines through those readings less what their noise adds on average (so
  // negative where the rig hardly moves; a sum over many intervals is what means something); 0
  // where no line fits.
  double timeOffsetInformation(TimeNs a, TimeNs b) const;
  // Drops readings before keep_from, keeping at least two.
  void trimBefore(TimeNs keep_from);

 private:
  ImuNoise noise_;
  double rate_hz_;
  double step_s_;
  TimeNs cubic_interval_ns_;
  std::deque<ImuMeasurement> readings_;
};

}  // namespace estimator_internal
}  // namespace mvis
