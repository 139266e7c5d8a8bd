// Readings corrected by an inertial sensor's known intrinsics (report Eq. 1-4, rig.h: the rpng
// and kalibr models alike), so that the estimator can treat every sensor as calibrated.
//
// With the model
//   a_m = Ta R_IMUtoACC a_I + b_a,   w_m = Tw R_IMUtoGYRO w_I + Tg a_I + b_g
// (rpng: R_IMUtoGYRO = I; kalibr: R_IMUtoACC = I), the corrected readings
//   a' = R_IMUtoACC^T Ta^-1 a_m                 = a_I + b_a'
//   w' = R_IMUtoGYRO^T Tw^-1 (w_m - Tg a')       = w_I + b_g'
// follow the calibrated model with the biases
//   b_a' = R_IMUtoACC^T Ta^-1 b_a,   b_g' = R_IMUtoGYRO^T Tw^-1 (b_g - Tg b_a'),
// which are what the estimator's bias states then hold (they still walk randomly; the noise
// densities change by the intrinsics' few parts per thousand, which is ignored). A gyroscope has
// no accelerometer: apply() gives w' = R_IMUtoGYRO^T Tw^-1 w_m, and the rest, -gravity a_I, is
// subtracted once the specific force a_I at the gyroscope is known (the base IMU's brought to it,
// src/core/estimator/aux_sensors.h).
//
// The intrinsics are taken as known here; estimating them is the re-integration's
// (imu_reintegration.h).
#pragma once

#include <Eigen/Core>

#include "mvis/inertial/imu_preintegration.h"
#include "mvis/rig/rig.h"

namespace mvis {

struct ImuCorrection {
  Eigen::Matrix3d to_accel = Eigen::Matrix3d::Identity();  // R_IMUtoACC^T Ta^-1
  Eigen::Matrix3d to_gyro = Eigen::Matrix3d::Identity();   // R_IMUtoGYRO^T Tw^-1
  Eigen::Matrix3d gravity = Eigen::Matrix3d::Zero();       // to_gyro Tg
  bool identity = true;                                    // nothing to correct

  explicit ImuCorrection(const ImuIntrinsics& intrinsics = ImuIntrinsics());
  // The corrected reading; `gyro_only`: the accelerometer part is left as it is.
  ImuMeasurement apply(const ImuMeasurement& m, bool gyro_only) const;
  // The biases b_g', b_a' that corrected readings carry for raw biases b_g, b_a.
  void biases(const Eigen::Vector3d& bias_gyro, const Eigen::Vector3d& bias_accel,
              Eigen::Vector3d* corrected_gyro, Eigen::Vector3d* corrected_accel) const;
};

}  // namespace mvis
