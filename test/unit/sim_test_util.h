// A motion and an IMU shared by the inertial tests.
#pragma once

#include "mvis/rig/rig.h"
#include "mvis/sim/trajectory.h"

namespace mvis::test {

// A 3-D handheld-like motion: ~0.3 m and ~0.5 rad swings at 0.2-0.9 Hz.
inline SinusoidTrajectory handheld() {
  std::array<Signal, 3> position = {Signal{0.3, {{0.30, 0.23, 0.0}, {0.05, 0.71, 1.0}}},
                                    Signal{0.3, {{0.25, 0.31, 0.5}, {0.04, 0.83, 2.0}}},
                                    Signal{1.0, {{0.15, 0.27, 1.2}, {0.03, 0.91, 0.3}}}};
  std::array<Signal, 3> euler = {Signal{0.2, {{0.50, 0.19, 0.0}, {0.10, 0.67, 0.4}}},
                                 Signal{0.0, {{0.35, 0.29, 1.1}, {0.08, 0.73, 0.2}}},
                                 Signal{0.0, {{0.40, 0.23, 2.1}, {0.07, 0.87, 0.9}}}};
  Eigen::Matrix3d R_offset;
  R_offset << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  return SinusoidTrajectory(position, euler, R_offset);
}

// A calibrated base IMU with the VI-Rig's noise (report Table 4).
inline InertialSensor idealImu(double rate_hz) {
  InertialSensor s;
  s.name = "imu0";
  s.update_rate = rate_hz;
  s.noise = {2e-3, 3e-3, 1.7e-4, 1.9e-5};
  return s;
}

}  // namespace mvis::test
