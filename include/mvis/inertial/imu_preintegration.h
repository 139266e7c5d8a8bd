// Preintegrated base-IMU measurements between two window states (report Sec. 2.1, Eq. 32-36).
//
// Between states i and j (base-clock times t_i < t_j) the corrected readings
//   w = w_m - b_g,  a = a_m - b_a
// are integrated with the biases held at their linearization point (b_g0, b_a0). Over each
// interval dt between consecutive readings 0 and 1 the rotation uses the mean angular velocity
// and the acceleration is the trapezoid of its two ends rotated into the start frame
// (the midpoint scheme of VINS-Mono):
//   w = (w_0 + w_1) / 2,   dR_{k+1} = dR_k Exp(w dt)
//   a = (dR_k a_0 + dR_{k+1} a_1) / 2
//   dp_{k+1} = dp_k + dv_k dt + 1/2 a dt^2,   dv_{k+1} = dv_k + a dt
// The deltas are expressed in the frame of state i and relate to the states as
//   dR = R_i^T R_j,  dp = R_i^T (p_j - p_i - v_i T - 1/2 g T^2),  dv = R_i^T (v_j - v_i - g T)
// with g the gravity vector in the world frame and T = t_j - t_i.
//
// The error state is [dtheta, dp, dv, db_g, db_a] (dR_true = dR Exp(dtheta)). Its covariance is
// propagated with the discrete noise of each interval: gyroscope and accelerometer white noise
// sigma^2 = density^2 / dt and bias random walks sigma^2 = random_walk^2 * dt (Forster et al.,
// "On-Manifold Preintegration", 2017). The first-order Jacobians of the deltas in the biases give
// the bias correction of Eq. 32-34:
//   dR(b) = dR Exp(J_R_bg (b_g - b_g0)),  dp(b) = dp + J_p_bg db_g + J_p_ba db_a, same for dv.
//
// Gaps: an interval whose real readings are more than `max_interval_s` apart (readings lost),
// span s, is integrated all the same, but its readings are only an interpolation, so it gets
// extra noise of the size a brisk hand-held motion could hide: reading errors of
// 10 rad/s^2 * s on the angular velocity and 20 m/s^3 * s on the acceleration. Without it a 0.1 s
// hole biased the camera extrinsic rotation by 5 sigma in simulation.
//
// Readings far apart are resampled first (imu_readings.h: readingsBetween).
//
// The raw samples are kept, so the deltas can be re-integrated at a new linearization point
// (repropagate), which the IMU-intrinsics work needs (report Sec. 2.2).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

#include "mvis/common/time.h"
#include "mvis/inertial/imu_readings.h"
#include "mvis/rig/rig.h"

namespace mvis {

class ImuPreintegration {
 public:
  using Matrix15d = Eigen::Matrix<double, 15, 15>;

  // Error-state order.
  static constexpr int kRotation = 0, kPosition = 3, kVelocity = 6, kBiasGyro = 9, kBiasAccel = 12;

  ImuPreintegration(const ImuNoise& noise, const Eigen::Vector3d& bias_gyro,
                    const Eigen::Vector3d& bias_accel, double max_interval_s = 0.0);

  // Appends a reading; the first one sets the start time t_i. Stamps must increase.
  void add(const ImuMeasurement& measurement);
  // Integrates again from the raw readings at a new bias linearization point.
  void repropagate(const Eigen::Vector3d& bias_gyro, const Eigen::Vector3d& bias_accel);

  TimeNs startNs() const { return samples_.empty() ? 0 : samples_.front().stamp_ns; }
  TimeNs endNs() const { return samples_.empty() ? 0 : samples_.back().stamp_ns; }
  double duration() const { return toSeconds(endNs() - startNs()); }
  const std::vector<ImuMeasurement>& samples() const { return samples_; }

  const Eigen::Quaterniond& deltaR() const { return dR_; }
  const Eigen::Vector3d& deltaP() const { return dp_; }
  const Eigen::Vector3d& deltaV() const { return dv_; }
  const Eigen::Vector3d& biasGyro() const { return bg_; }
  const Eigen::Vector3d& biasAccel() const { return ba_; }
  const Matrix15d& covariance() const { return covariance_; }
  // Jacobian of the error state after integration in the error state before it and in the bias
  // linearization changes (columns 9-14 hold J_*_bg and J_*_ba).
  const Matrix15d& jacobian() const { return jacobian_; }

  // The deltas corrected to other biases to first order (Eq. 32-34).
  Eigen::Quaterniond correctedDeltaR(const Eigen::Vector3d& bias_gyro) const;
  Eigen::Vector3d correctedDeltaP(const Eigen::Vector3d& bias_gyro,
                                  const Eigen::Vector3d& bias_accel) const;
  Eigen::Vector3d correctedDeltaV(const Eigen::Vector3d& bias_gyro,
                                  const Eigen::Vector3d& bias_accel) const;

  // Predicts state j from state i: R_j, p_j, v_j given R_i, p_i, v_i, gravity g [m/s^2].
  void predict(const Eigen::Quaterniond& q_i, const Eigen::Vector3d& p_i,
               const Eigen::Vector3d& v_i, const Eigen::Vector3d& gravity, Eigen::Quaterniond* q_j,
               Eigen::Vector3d* p_j, Eigen::Vector3d* v_j) const;

 private:
  void reset();
  void integrate(const ImuMeasurement& from, const ImuMeasurement& to);

  ImuNoise noise_;
  double max_interval_s_ = 0.0;  // 0: no gap model
  Eigen::Vector3d bg_, ba_;
  std::vector<ImuMeasurement> samples_;
  Eigen::Quaterniond dR_ = Eigen::Quaterniond::Identity();
  Eigen::Vector3d dp_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d dv_ = Eigen::Vector3d::Zero();
  Matrix15d covariance_ = Matrix15d::Zero();
  Matrix15d jacobian_ = Matrix15d::Identity();
};

}  // namespace mvis
