// The window's states as data (no behaviour beyond views): what every part of the estimator
// reads, and what the window (window.h) owns. Private to src/core/estimator.
//
// A window state is the base IMU's [q, p, v, b_g, b_a] at a cam0 frame time (report Eq. 12),
// with the factors whose oldest state it is (they are marginalized with it), the auxiliary
// sensors' states at its time (aux_sensors.h) and the propagation-noise blocks of the frames
// attached to it (camera_frames.h).
#pragma once

#include <ceres/ceres.h>

#include <memory>
#include <vector>

#include "mvis/estimator/estimator.h"
#include "mvis/factors/base_motion.h"
#include "mvis/factors/state_blocks.h"

namespace mvis {
namespace estimator_internal {

struct ResidualRecord {
  ceres::ResidualBlockId id = nullptr;
  const ceres::CostFunction* cost = nullptr;
  const ceres::LossFunction* loss = nullptr;
  std::vector<double*> blocks;
  int inertial = -1;  // the inertial sensor whose readings the factor holds, else -1
  int corners = 0;    // the tag corners the factor holds (camera factors), else 0
};

// An auxiliary sensor's state at one window time (state_blocks.h: aux_state or gyro bias).
struct AuxState {
  double x[9];  // [v b_g b_a], [b_g b_a] (rigid-velocity model) or [b_g] (gyroscope)
  // The sensor's time offset when this state was made [s]: the state belongs to the sensor-clock
  // time t - td0 of its window state t.
  double td0 = 0.0;
};

struct State {
  TimeNs t = 0;
  double pose[kPoseSize];
  double speed_bias[kSpeedBiasSize];
  BaseMotion motion;  // base readings at t (kinematic frame poses, auxiliary factors)
  // Per auxiliary sensor (index sensor - 1): its state at t, or null while it has none.
  std::vector<std::unique_ptr<AuxState>> aux;
  std::vector<ResidualRecord> residuals;
  // Propagation-noise blocks of the frames attached to this state (kPropagationNoiseSize each).
  std::vector<std::unique_ptr<double[]>> propagation_noise;
  int frames = 0;  // camera frames owned (their corners: the records', which may move)

  Eigen::Vector3d biasGyro() const { return Eigen::Vector3d(speed_bias + 3); }
  Eigen::Vector3d biasAccel() const { return Eigen::Vector3d(speed_bias + 6); }
  EstimatorState toEstimate() const {
    EstimatorState s;
    s.stamp_ns = t;
    s.T_G_I = poseToSE3(pose);
    s.v_G = Eigen::Vector3d(speed_bias);
    s.bias_gyro = biasGyro();
    s.bias_accel = biasAccel();
    return s;
  }
};

}  // namespace estimator_internal
}  // namespace mvis
