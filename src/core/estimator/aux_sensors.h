// Auxiliary IMUs and gyroscopes in the window (report Sec. 3): their readings (in their own
// clocks), their chains of states at the window times (window_state.h: State::aux), how a chain
// starts (Eq. 40-43), grows and stops, and their factors (AuxImuFactor, GyroFactor). Private to
// src/core/estimator.
//
// Owns: each sensor's reading buffer, whether it is said to have stopped, and its last bias
// estimate; the aux states it makes (kept in the window's states, whose lifetime they share).
// Asks of the others: the window (states, problem, factors), the sensors' calibration blocks and
// gravity, their intrinsics blocks, and the observability monitor (it reports the readings it
// integrates).
#pragma once

#include <deque>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "calibration_blocks.h"
#include "imu_intrinsics.h"
#include "observability_monitor.h"
#include "window.h"

namespace mvis {
namespace estimator_internal {

class AuxSensors {
 public:
  AuxSensors(const Rig& rig, const EstimatorOptions& options, Window& window,
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
  void clear();
  // A warning for the caller (a sensor left the window), once; empty if none.
  std::string takeWarning();

 private:
  struct Stream {
    std::size_t sensor = 0;
    bool gyro = false;
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
  // Starts a chain at window states k0..k1 (k1 > k0), all covered by its readings.
  void startChain(Stream& a, std::size_t k0, std::size_t k1);
  // Appends the state at window state k to the chain ending at k - 1.
  void append(Stream& a, std::size_t k);
  // Readings over [tau_a, tau_b] (the sensor's clock) preintegrated at the given biases; null
  // if they do not cover the interval or have a hole longer than aux_max_gap_s.
  std::shared_ptr<ImuPreintegration> preintegrate(const Stream& a, TimeNs tau_a, TimeNs tau_b,
                                                  const Eigen::Vector3d& bg,
                                                  const Eigen::Vector3d& ba) const;
  // The factor between the sensor's states at window states k and k + 1.
  void addFactor(Stream& a, std::size_t k, std::shared_ptr<const ImuPreintegration> pre);

  const Rig& rig_;
  const EstimatorOptions& options_;
  Window& window_;
  CalibrationBlocks& calibration_;
  ImuIntrinsicsBlocks& intrinsics_;
  ObservabilityMonitor& monitor_;
  EstimatorCounters& counters_;
  std::vector<std::unique_ptr<Stream>> streams_;  // index sensor - 1
  std::string warning_;
};

}  // namespace estimator_internal
}  // namespace mvis
