// Smooth rig trajectories with analytic derivatives, so simulated angular velocity and specific
// force are exact.
//
// Position: p_G_I(t) = center + sum_k amplitude_k * sin(2 pi f_k t + phase_k), per axis.
// Orientation: R_G_I(t) = Rz(yaw) * Ry(pitch) * Rx(roll) * R_offset, each Euler angle a
// constant plus sinusoids; R_offset is constant (it points the cameras at the tags).
// Frames: {G} world, z up, g_G = [0 0 -9.81]; {I} the base IMU.
#pragma once

#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "mvis/common/lie.h"

namespace mvis {

inline const Eigen::Vector3d kGravity_G(0.0, 0.0, -9.81);  // [m/s^2]

// The kinematic state of the base IMU at one instant.
struct TrajectoryState {
  SE3 T_G_I;                                       // pose of the base IMU in the world
  Eigen::Vector3d v_G = Eigen::Vector3d::Zero();   // velocity [m/s]
  Eigen::Vector3d a_G = Eigen::Vector3d::Zero();   // acceleration [m/s^2] (no gravity)
  Eigen::Vector3d w_I = Eigen::Vector3d::Zero();   // angular velocity in {I} [rad/s]
  Eigen::Vector3d dw_I = Eigen::Vector3d::Zero();  // angular acceleration in {I} [rad/s^2]

  // Specific force in {I}, what a perfect accelerometer at the base IMU measures.
  Eigen::Vector3d specificForce() const { return T_G_I.q.conjugate() * (a_G - kGravity_G); }
};

// One sinusoid: amplitude * sin(2 pi frequency t + phase).
struct Sinusoid {
  double amplitude = 0.0;     // [m] or [rad]
  double frequency_hz = 0.0;  // [Hz]
  double phase = 0.0;         // [rad]
};

// A constant plus sinusoids, with its first and second time derivatives.
struct Signal {
  double offset = 0.0;
  std::vector<Sinusoid> terms;
  // value, first and second derivative at t [s]
  std::array<double, 3> evaluate(double t) const;
};

class SinusoidTrajectory {
 public:
  SinusoidTrajectory(std::array<Signal, 3> position, std::array<Signal, 3> yaw_pitch_roll,
                     const Eigen::Matrix3d& R_offset)
      : position_(std::move(position)), euler_(std::move(yaw_pitch_roll)), R_offset_(R_offset) {}

  TrajectoryState evaluate(double t) const;

 private:
  std::array<Signal, 3> position_;  // x, y, z [m]
  std::array<Signal, 3> euler_;     // yaw, pitch, roll [rad]
  Eigen::Matrix3d R_offset_;
};

}  // namespace mvis
