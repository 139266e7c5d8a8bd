#include "mvis/inertial/imu_preintegration.h"

#include "mvis/common/lie.h"

namespace mvis {

ImuPreintegration::ImuPreintegration(const ImuNoise& noise, const Eigen::Vector3d& bias_gyro,
                                     const Eigen::Vector3d& bias_accel, double max_interval_s)
    : noise_(noise), max_interval_s_(max_interval_s), bg_(bias_gyro), ba_(bias_accel) {}

void ImuPreintegration::reset() {
  dR_.setIdentity();
  dp_.setZero();
  dv_.setZero();
  covariance_.setZero();
  jacobian_.setIdentity();
}

void ImuPreintegration::add(const ImuMeasurement& measurement) {
  if (!samples_.empty()) integrate(samples_.back(), measurement);
  samples_.push_back(measurement);
}

void ImuPreintegration::repropagate(const Eigen::Vector3d& bias_gyro,
                                    const Eigen::Vector3d& bias_accel) {
  bg_ = bias_gyro;
  ba_ = bias_accel;
  reset();
  for (std::size_t k = 1; k < samples_.size(); ++k) integrate(samples_[k - 1], samples_[k]);
}

void ImuPreintegration::integrate(const ImuMeasurement& from, const ImuMeasurement& to) {
  const double dt = toSeconds(to.stamp_ns - from.stamp_ns);
  if (dt <= 0.0) return;
  const Eigen::Vector3d w = 0.5 * (from.gyro + to.gyro) - bg_;
  const Eigen::Vector3d a0 = from.accel - ba_;
  const Eigen::Vector3d a1 = to.accel - ba_;
  const Eigen::Vector3d phi = w * dt;
  const Eigen::Matrix3d R0 = dR_.toRotationMatrix();
  const Eigen::Matrix3d dR_step = lie::expSO3(phi);
  const Eigen::Matrix3d R1 = R0 * dR_step;
  const Eigen::Matrix3d Jr = lie::rightJacobianSO3(phi);
  // Acceleration in the start frame, trapezoidal over the interval.
  const Eigen::Vector3d a_rot = 0.5 * (R0 * a0 + R1 * a1);
  // Its derivatives in dtheta (at R0), b_g and b_a.
  const Eigen::Matrix3d A_theta =
      -0.5 * R0 * lie::hat(a0) - 0.5 * R1 * lie::hat(a1) * dR_step.transpose();
  const Eigen::Matrix3d A_bg = 0.5 * R1 * lie::hat(a1) * Jr * dt;
  const Eigen::Matrix3d A_ba = -0.5 * (R0 + R1);

  // Error-state transition F and noise input G (see the header).
  Matrix15d F = Matrix15d::Identity();
  F.block<3, 3>(kRotation, kRotation) = dR_step.transpose();
  F.block<3, 3>(kRotation, kBiasGyro) = -Jr * dt;
  F.block<3, 3>(kPosition, kRotation) = 0.5 * A_theta * dt * dt;
  F.block<3, 3>(kPosition, kVelocity) = Eigen::Matrix3d::Identity() * dt;
  F.block<3, 3>(kPosition, kBiasGyro) = 0.5 * A_bg * dt * dt;
  F.block<3, 3>(kPosition, kBiasAccel) = 0.5 * A_ba * dt * dt;
  F.block<3, 3>(kVelocity, kRotation) = A_theta * dt;
  F.block<3, 3>(kVelocity, kBiasGyro) = A_bg * dt;
  F.block<3, 3>(kVelocity, kBiasAccel) = A_ba * dt;

  // Noise inputs [n_g, n_a, n_bg, n_ba]: white noise enters like a bias error.
  Eigen::Matrix<double, 15, 12> G = Eigen::Matrix<double, 15, 12>::Zero();
  G.block<3, 3>(kRotation, 0) = -Jr * dt;
  G.block<3, 3>(kPosition, 0) = 0.5 * A_bg * dt * dt;
  G.block<3, 3>(kVelocity, 0) = A_bg * dt;
  G.block<3, 3>(kPosition, 3) = 0.5 * A_ba * dt * dt;
  G.block<3, 3>(kVelocity, 3) = A_ba * dt;
  G.block<3, 3>(kBiasGyro, 6).setIdentity();
  G.block<3, 3>(kBiasAccel, 9).setIdentity();
  const double sg = noise_.gyroscope_noise_density, sa = noise_.accelerometer_noise_density;
  const double wg = noise_.gyroscope_random_walk, wa = noise_.accelerometer_random_walk;
  Eigen::Matrix<double, 12, 1> q;
  double gap_w = 0.0, gap_a = 0.0;  // see the header
  const double span = std::max(dt, toSeconds(to.span_ns));
  if (max_interval_s_ > 0.0 && span > max_interval_s_) {
    gap_w = (10.0 * span) * (10.0 * span);
    gap_a = (20.0 * span) * (20.0 * span);
  }
  q << Eigen::Vector3d::Constant(sg * sg / dt + gap_w),
      Eigen::Vector3d::Constant(sa * sa / dt + gap_a), Eigen::Vector3d::Constant(wg * wg * dt),
      Eigen::Vector3d::Constant(wa * wa * dt);

  covariance_ = F * covariance_ * F.transpose() + G * q.asDiagonal() * G.transpose();
  jacobian_ = F * jacobian_;

  dp_ += dv_ * dt + 0.5 * a_rot * dt * dt;
  dv_ += a_rot * dt;
  dR_ = (dR_ * lie::expQuat(phi)).normalized();
}

Eigen::Quaterniond ImuPreintegration::correctedDeltaR(const Eigen::Vector3d& bias_gyro) const {
  const Eigen::Matrix3d J = jacobian_.block<3, 3>(kRotation, kBiasGyro);
  return (dR_ * lie::expQuat(J * (bias_gyro - bg_))).normalized();
}

Eigen::Vector3d ImuPreintegration::correctedDeltaP(const Eigen::Vector3d& bias_gyro,
                                                   const Eigen::Vector3d& bias_accel) const {
  return dp_ + jacobian_.block<3, 3>(kPosition, kBiasGyro) * (bias_gyro - bg_) +
         jacobian_.block<3, 3>(kPosition, kBiasAccel) * (bias_accel - ba_);
}

Eigen::Vector3d ImuPreintegration::correctedDeltaV(const Eigen::Vector3d& bias_gyro,
                                                   const Eigen::Vector3d& bias_accel) const {
  return dv_ + jacobian_.block<3, 3>(kVelocity, kBiasGyro) * (bias_gyro - bg_) +
         jacobian_.block<3, 3>(kVelocity, kBiasAccel) * (bias_accel - ba_);
}

void ImuPreintegration::predict(const Eigen::Quaterniond& q_i, const Eigen::Vector3d& p_i,
                                const Eigen::Vector3d& v_i, const Eigen::Vector3d& gravity,
                                Eigen::Quaterniond* q_j, Eigen::Vector3d* p_j,
                                Eigen::Vector3d* v_j) const {
  const double T = duration();
  *q_j = (q_i * dR_).normalized();
  *p_j = p_i + v_i * T + 0.5 * gravity * T * T + q_i * dp_;
  *v_j = v_i + gravity * T + q_i * dv_;
}

}  // namespace mvis
