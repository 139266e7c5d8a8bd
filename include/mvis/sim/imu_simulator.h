// Inertial measurements of any sensor of the rig along a base-IMU trajectory.
//
// For inertial sensor i with p_imui = T_i_b * p_imu0 and the base state (R, p, v, a, w, dw) at
// base time t_b = t_i + time_offset (the Kalibr convention), the sensor's true angular velocity
// and specific force in its own frame are
//   w_i = R_i_b w
//   f_i = R_i_b (R^T (a - g) + dw x p_b_i + w x (w x p_b_i)),   p_b_i = position of i in {I}
// and the rpng model (report Eq. 1-2) turns them into readings:
//   w_m = Tw R_IMUtoGYRO w_i + Tg f_i + b_g + n_g,   a_m = Ta R_IMUtoACC f_i + b_a + n_a
// White noise has standard deviation density / sqrt(dt); biases are random walks with steps of
// random_walk * sqrt(dt). A gyroscope's accelerometer reading is zero.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <vector>

#include "mvis/common/time.h"
#include "mvis/rig/rig.h"
#include "mvis/sim/trajectory.h"

namespace mvis {

struct ImuSample {
  TimeNs stamp_ns = 0;                                  // in the sensor's own clock
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();       // [rad/s]
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();      // [m/s^2]
  Eigen::Vector3d bias_gyro = Eigen::Vector3d::Zero();  // true bias at this sample
  Eigen::Vector3d bias_accel = Eigen::Vector3d::Zero();
};

struct ImuSimulationOptions {
  bool noise = true;   // white noise on the readings
  bool biases = true;  // bias random walks (from zero unless initial biases are given)
  Eigen::Vector3d initial_bias_gyro = Eigen::Vector3d::Zero();
  Eigen::Vector3d initial_bias_accel = Eigen::Vector3d::Zero();
  std::uint64_t seed = 1;
};

using TrajectoryFunction = std::function<TrajectoryState(double t_base_s)>;

// True angular velocity and specific force of `sensor`, in its frame, at base time t.
void trueInertialMotion(const InertialSensor& sensor, const TrajectoryState& base,
                        Eigen::Vector3d* w_i, Eigen::Vector3d* f_i);

// Samples of `sensor` at its update_rate with sensor-clock stamps from start_ns to end_ns
// (inclusive of start), the trajectory taking base time in seconds from `t0_ns`.
std::vector<ImuSample> simulateImu(const InertialSensor& sensor, const TrajectoryFunction& base,
                                   TimeNs t0_ns, TimeNs start_ns, TimeNs end_ns,
                                   const ImuSimulationOptions& options);

}  // namespace mvis
