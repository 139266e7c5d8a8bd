// IMU-rate odometry between solves: the newest window state (the anchor, handed over with every
// estimator update) carried to each later base-IMU reading with the readings since, as the IMU
// factor predicts it (Forster et al.'s preintegration, imu_preintegration.h): the readings
// corrected by the base IMU's intrinsics as configured or as estimated at the anchor, less the
// anchor's biases.
//
// It needs nothing of the estimator but the anchor, so it can run beside it: the nodelet feeds
// it every base reading the moment it arrives and hands it each new anchor when a solve ends on
// the estimator's thread, and odometry never waits for a solve. A new anchor re-integrates the
// readings kept after it (a few tens of ms of them when the estimator keeps up, up to a second
// while it catches up after its first batch): setAnchor() leaves that to the next add(); a
// caller on two threads does it on the anchor's thread instead, in three steps: prepare() copies
// the readings (under the caller's lock), PreparedAnchor::integrate() integrates them (without
// it), install() adopts the result and adds the readings that came meanwhile (under it).
// Readings are kept for `keep_s` seconds; an anchor older than that (the estimator is that far
// behind) gives no odometry until a newer one comes. Not thread-safe: the caller serializes.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "mvis/estimator/estimator.h"
#include "mvis/inertial/imu_readings.h"
#include "mvis/rig/rig.h"

namespace mvis {

// A new anchor with its readings integrated, made by OdometryPropagator::prepare().
class PreparedAnchor {
 public:
  PreparedAnchor();
  ~PreparedAnchor();
  PreparedAnchor(PreparedAnchor&&) noexcept;
  PreparedAnchor& operator=(PreparedAnchor&&) noexcept;
  // The integration over the copied readings; thread-safe against the propagator.
  void integrate();

 private:
  friend class OdometryPropagator;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

class OdometryPropagator {
 public:
  // `base`: the base IMU (noise, rate: gaps and the cubic interpolation as the estimator's);
  // `integration_step_s`: EstimatorOptions::imu_integration_step_s.
  OdometryPropagator(const InertialSensor& base, double integration_step_s, double keep_s = 5.0);
  ~OdometryPropagator();
  OdometryPropagator(OdometryPropagator&&) noexcept;
  OdometryPropagator& operator=(OdometryPropagator&&) noexcept;

  // A raw base reading (base clock). The anchor's state propagated to its time, or nothing:
  // no anchor, the reading not after it, not finite, out of order (dropped), or the anchor
  // older than the kept readings (why() says which). A stamp more than 1 s before the last one
  // (a bag replayed) forgets everything before it, anchor included.
  std::optional<EstimatorState> add(const ImuMeasurement& raw);
  // The state to propagate from, from now on (an invalid anchor: none).
  void setAnchor(const PropagationAnchor& anchor);
  // The same in three steps (above): the anchor with a copy of the readings it needs; then,
  // once integrated, adopted, unless reset() or a clock jump came in between (then dropped).
  PreparedAnchor prepare(const PropagationAnchor& anchor) const;
  void install(PreparedAnchor&& prepared);
  // Forgets the readings and the anchor (the estimator started over).
  void reset();
  // The base IMU's angular rate in its own frame at the last reading add() propagated to: the
  // corrected reading less the anchor's gyroscope bias [rad/s].
  const Eigen::Vector3d& angularVelocity() const { return angular_velocity_; }
  // Why the last add() gave nothing ("" when it gave a state).
  const std::string& why() const { return why_; }

 private:
  struct Readings;
  std::unique_ptr<Readings> readings_;
  PropagationAnchor anchor_;
  std::uint64_t epoch_ = 0;  // counts reset()s: a prepared anchor from before one is stale
  Eigen::Vector3d angular_velocity_ = Eigen::Vector3d::Zero();
  std::string why_;
};

}  // namespace mvis
