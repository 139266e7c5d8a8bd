// Auxiliary IMUs and gyroscopes in the window (report Sec. 3): their readings (in their own
// clocks), their chains of states at the window times (window_state.h: State::aux), how a chain
// starts (Eq. 40-43), grows and stops, and their factors (AuxImuFactor, GyroFactor). Private to
// src/core/estimator.
//
// Owns: each sensor's reading buffer, whether it is said to have stopped, and its last bias
// estimate; the aux states it makes (kept in the window's states, whose lifetime they share).
// Asks of the others: the base IMU's readings (a gyroscope's gravity sensitivity), the window
// (states, problem, factors), the sensors' calibration blocks and gravity, their intrinsics
// blocks, and the observability monitor (it reports the readings it integrates).
#pragma once

#include <deque>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "calibration_blocks.h"
#include "change_detector.h"
#include "imu_buffer.h"
#include "imu_intrinsics.h"
#include "observability_monitor.h"
#include "window.h"

namespace mvis {
namespace estimator_internal {

class AuxSensors {
 public:
  AuxSensors(const Rig& rig, const EstimatorOptions& options, const ImuBuffer& base, Window& window,
             CalibrationBlocks& calibration, ImuIntrinsicsBlocks& intrinsics,
             ObservabilityMonitor& monitor, EstimatorCounters& counters);

  std::size_t size() const { return streams_.size(); }
  // A reading of sensor `sensor` (>= 1) in its own clock; with `in_window` (the window runs) the
  // sensor's chain is extended at once. Errors describe a dropped reading or a sensor that
  // rejoins.
  Status add(std::size_t sensor, const ImuMeasurement& m, bool in_window);
  // Gives every sensor states at the window states its readings reach (the window must run).
  void extend();
  // Before the oldest window state leaves: its aux state blocks (appended to *leaving), and
  // each sensor's biases there as the start of a later chain.
  void leaving(const State& oldest, std::vector<double*>* leaving);
  // Drops readings before the window's oldest time `from` (base clock; lowest TimeNs max:
  // nothing to anchor to, two seconds are kept).
  void trim(TimeNs from);
  // Whether a gyroscope needs the base IMU's readings over the whole window (its gravity
  // sensitivity: specificForce()), not only from the newest state on.
  bool needsBaseReadings() const;
  void clear();
  // Every reading of a running chain is also evidence for `changes` (addEvidence), sensor s in
  // slot first_slot + s - 1; null: none.
  void setChangeDetector(ChangeDetector* changes, std::size_t first_slot) {
    changes_ = changes;
    first_slot_ = first_slot;
  }
  // A warning for the caller (a sensor left the window), once; empty if none.
  std::string takeWarning();

 private:
  struct Stream {
    std::size_t sensor = 0;
    bool gyro = false;
    // A gyroscope whose gravity sensitivity Tg is configured non-zero or has an intrinsics block
    // (Tg estimated, or held and tested): its readings get the specific force at it
    // (specificForce()).
    bool gravity_sensitive = false;
    int block_size = 9;            // of its AuxState::x
    TimeNs cubic_interval_ns = 0;  // cubicIntervalNs of the sensor
    std::deque<ImuMeasurement> readings;
    TimeNs last = std::numeric_limits<TimeNs>::min();
    bool stopped = false;                                 // said to have left the window
    Eigen::Vector3d bias_gyro = Eigen::Vector3d::Zero();  // last estimate, for a new chain
    Eigen::Vector3d bias_accel = Eigen::Vector3d::Zero();

    double* biasGyro(AuxState* s) const { return block_size == 9 ? s->x + 3 : s->x; }
    double* biasAccel(AuxState* s) const { return block_size == 9 ? s->x + 6 : s->x + 3; }
  };

  void extend(Stream& a);
  // Sensor a's readings over (from.t, to] (base clock) to the change detector: each against the
  // base IMU's reading at its time carried to it through the current extrinsic (rates, and for
  // an IMU specific force with the lever arm), at the state `from`'s biases, the sensor's biases
  // and time offset its nuisance parameters.
  void addEvidence(const Stream& a, const State& from, TimeNs to);
  // Starts a chain at window states k0..k1 (k1 > k0), all covered by its readings.
  void startChain(Stream& a, std::size_t k0, std::size_t k1);
  // Appends the state at window state k to the chain ending at k - 1.
  void append(Stream& a, std::size_t k);
  // Readings over [tau_a, tau_b] (the sensor's clock) preintegrated at the given biases; null
  // if they do not cover the interval or have a hole longer than aux_max_gap_s.
  std::shared_ptr<ImuPreintegration> preintegrate(const Stream& a, TimeNs tau_a, TimeNs tau_b,
                                                  const Eigen::Vector3d& bg,
                                                  const Eigen::Vector3d& ba) const;
  // Gives a gravity-sensitive gyroscope's readings (its clock) the specific force at the
  // gyroscope in its frame as their accel, from the base IMU's readings at the same base time
  // through the current extrinsic rotation and the lever arm (report Eq. 40's rigid body):
  //   a_A = R_AI (a_I + alpha x p_IA + w x (w x p_IA)),  a_I = a'_m - b'_a,  w = w'_m - b'_g
  // with the newest window state's base biases, alpha the base rate's slope over 20 ms and p_IA
  // the gyroscope's position in {I}. A configured Tg (not estimated) is subtracted here too
  // (imu_correction.h).
  // The specific force is data to the factors: its error (a base accelerometer bias of 0.1
  // m/s^2, an extrinsic 1 deg off) moves Tg a by 3e-5 rad/s at Tg = 3e-4, under the gyroscope's
  // white noise over any interval.
  // False when the base readings do not cover the readings' times (yet).
  bool specificForce(const Stream& a, std::vector<ImuMeasurement>* readings) const;
  // The factor between the sensor's states at window states k and k + 1.
  void addFactor(Stream& a, std::size_t k, std::shared_ptr<const ImuPreintegration> pre);

  const Rig& rig_;
  const EstimatorOptions& options_;
  const ImuBuffer& base_;
  Window& window_;
  CalibrationBlocks& calibration_;
  ImuIntrinsicsBlocks& intrinsics_;
  ObservabilityMonitor& monitor_;
  EstimatorCounters& counters_;
  ChangeDetector* changes_ = nullptr;
  std::size_t first_slot_ = 0;
  std::vector<std::unique_ptr<Stream>> streams_;  // index sensor - 1
  std::string warning_;
};

}  // namespace estimator_internal
}  // namespace mvis
