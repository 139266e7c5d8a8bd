// A motion and an IMU shared by the inertial tests.
#pragma once

#include <vector>

#include "mvis/common/lie.h"
#include "mvis/inertial/imu_reintegration.h"
#include "mvis/rig/rig.h"
#include "mvis/sim/imu_simulator.h"
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

// `sensor`'s noise-free, bias-free readings over base times [t_i, t_j] [s] of `trajectory`
// (t0 = 0, the sensor's clock = the base clock).
inline std::vector<ImuMeasurement> noiseFreeReadings(const InertialSensor& sensor,
                                                     const SinusoidTrajectory& trajectory,
                                                     double t_i, double t_j) {
  const TrajectoryFunction base = [&](double t) { return trajectory.evaluate(t); };
  ImuSimulationOptions o;
  o.noise = false;
  o.biases = false;
  std::vector<ImuMeasurement> out;
  for (const auto& s : simulateImu(sensor, base, 0, fromSeconds(t_i), fromSeconds(t_j), o)) {
    out.push_back({s.stamp_ns, s.gyro, s.accel});
  }
  return out;
}

// Intrinsics of the report's Table 4 size (3e-3 on Dw, Da, 1e-3 on Tg, 3e-3 rad on R_IMUtoACC),
// fixed values with every element nonzero.
inline ImuIntrinsics tableFourIntrinsics() {
  ImuIntrinsics in;
  in.Tw << 1.003, -0.002, 0.004, 0.0, 0.996, 0.001, 0.0, 0.0, 1.002;
  in.Ta << 0.997, 0.003, -0.001, 0.0, 1.004, -0.003, 0.0, 0.0, 0.998;
  in.Tg << 1e-3, -5e-4, 2e-4, 7e-4, -1e-3, 3e-4, -4e-4, 6e-4, 8e-4;
  in.R_IMUtoACC = lie::expSO3(Eigen::Vector3d(0.003, -0.002, 0.004));
  return in;
}

// The intrinsics block of `in` relative to R0 = I (so that its rotation entries are generic).
inline std::vector<double> intrinsicsBlock(const ImuIntrinsics& in) {
  std::vector<double> b(kImuIntrinsicsSize);
  intrinsicsToBlock(in, b.data());
  const Eigen::Vector3d theta = lie::logSO3(in.R_IMUtoACC.transpose());
  for (int k = 0; k < 3; ++k) b[ImuIntrinsicsLayout::kAccRotation + k] = theta[k];
  return b;
}

}  // namespace mvis::test
