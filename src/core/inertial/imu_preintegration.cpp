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

  // Error-state transition F and noise input G (see the header). F = I + E with E nonzero only
  // in the rotation, position and velocity rows (the biases are random walks), and G the
  // identity on the bias noises: the products below use that structure (a dense 15 x 15
  // product per reading, as F P F^T, cost several times as much).
  Eigen::Matrix<double, 9, 15> E = Eigen::Matrix<double, 9, 15>::Zero();
  E.block<3, 3>(kRotation, kRotation) = dR_step.transpose() - Eigen::Matrix3d::Identity();
  E.block<3, 3>(kRotation, kBiasGyro) = -Jr * dt;
  E.block<3, 3>(kPosition, kRotation) = 0.5 * A_theta * dt * dt;
  E.block<3, 3>(kPosition, kVelocity) = Eigen::Matrix3d::Identity() * dt;
  E.block<3, 3>(kPosition, kBiasGyro) = 0.5 * A_bg * dt * dt;
  E.block<3, 3>(kPosition, kBiasAccel) = 0.5 * A_ba * dt * dt;
  E.block<3, 3>(kVelocity, kRotation) = A_theta * dt;
  E.block<3, 3>(kVelocity, kBiasGyro) = A_bg * dt;
  E.block<3, 3>(kVelocity, kBiasAccel) = A_ba * dt;

  // Noise inputs [n_g, n_a] on the first nine rows; the bias noises [n_bg, n_ba] enter the
  // bias rows through the identity. White noise enters like a bias error.
  Eigen::Matrix<double, 9, 6> Gn = Eigen::Matrix<double, 9, 6>::Zero();
  Gn.block<3, 3>(kRotation, 0) = -Jr * dt;
  Gn.block<3, 3>(kPosition, 0) = 0.5 * A_bg * dt * dt;
  Gn.block<3, 3>(kVelocity, 0) = A_bg * dt;
  Gn.block<3, 3>(kPosition, 3) = 0.5 * A_ba * dt * dt;
  Gn.block<3, 3>(kVelocity, 3) = A_ba * dt;
  const double sg = noise_.gyroscope_noise_density, sa = noise_.accelerometer_noise_density;
  const double wg = noise_.gyroscope_random_walk, wa = noise_.accelerometer_random_walk;
  double gap_w = 0.0, gap_a = 0.0;  // see the header
  const double span = std::max(dt, toSeconds(to.span_ns));
  if (max_interval_s_ > 0.0 && span > max_interval_s_) {
    gap_w = (10.0 * span) * (10.0 * span);
    gap_a = (20.0 * span) * (20.0 * span);
  }
  Eigen::Matrix<double, 6, 1> q;
  q << Eigen::Vector3d::Constant(sg * sg / dt + gap_w),
      Eigen::Vector3d::Constant(sa * sa / dt + gap_a);

  // P' = F P F^T + G Q G^T = P + E P + (E P)^T + (E P) E^T + Gn Qn Gn^T + Q_bias (P symmetric).
  const Eigen::Matrix<double, 9, 15> EP = E.lazyProduct(covariance_);
  const Eigen::Matrix<double, 9, 9> EPE = EP.lazyProduct(E.transpose());
  const Eigen::Matrix<double, 9, 9> GQG = Gn.lazyProduct(q.asDiagonal() * Gn.transpose());
  covariance_.topRows<9>() += EP;
  covariance_.leftCols<9>() += EP.transpose();
  covariance_.topLeftCorner<9, 9>() += EPE + GQG;
  covariance_.diagonal().segment<3>(kBiasGyro).array() += wg * wg * dt;
  covariance_.diagonal().segment<3>(kBiasAccel).array() += wa * wa * dt;
  const Eigen::Matrix<double, 9, 15> EJ = E.lazyProduct(jacobian_);
  jacobian_.topRows<9>() += EJ;

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
