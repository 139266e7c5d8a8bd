#include "mvis/estimator/imu_preintegration.h"

#include <algorithm>
#include <deque>

#include "mvis/common/lie.h"

namespace mvis {

ImuMeasurement interpolateMeasurement(const ImuMeasurement& a, const ImuMeasurement& b, TimeNs t) {
  ImuMeasurement out;
  out.stamp_ns = t;
  const TimeNs span = b.stamp_ns - a.stamp_ns;
  const double s = span > 0 ? static_cast<double>(t - a.stamp_ns) / static_cast<double>(span) : 0.0;
  out.gyro = (1.0 - s) * a.gyro + s * b.gyro;
  out.accel = (1.0 - s) * a.accel + s * b.accel;
  out.span_ns = span;
  return out;
}

ImuMeasurement readingIn(const std::deque<ImuMeasurement>& buffer, TimeNs t,
                         TimeNs max_interval_ns) {
  auto it = std::lower_bound(buffer.begin(), buffer.end(), t,
                             [](const ImuMeasurement& m, TimeNs s) { return m.stamp_ns < s; });
  if (it == buffer.end()) return buffer.back();
  if (it->stamp_ns == t || it == buffer.begin()) return *it;
  const std::size_t k = static_cast<std::size_t>(it - buffer.begin()) - 1;  // k < t < k + 1
  ImuMeasurement out = interpolateMeasurement(buffer[k], buffer[k + 1], t);
  if (max_interval_ns <= 0 || k == 0 || k + 2 >= buffer.size()) return out;
  for (std::size_t i = k; i <= k + 2; ++i) {
    if (buffer[i].stamp_ns - buffer[i - 1].stamp_ns > max_interval_ns) return out;
  }
  // Lagrange weights of the cubic through readings k-1 .. k+2 at t (stamps relative to t).
  double x[4], w[4];
  for (int i = 0; i < 4; ++i) x[i] = toSeconds(buffer[k - 1 + i].stamp_ns - t);
  for (int i = 0; i < 4; ++i) {
    w[i] = 1.0;
    for (int j = 0; j < 4; ++j) {
      if (j != i) w[i] *= x[j] / (x[j] - x[i]);
    }
  }
  out.gyro.setZero();
  out.accel.setZero();
  for (int i = 0; i < 4; ++i) {
    out.gyro += w[i] * buffer[k - 1 + i].gyro;
    out.accel += w[i] * buffer[k - 1 + i].accel;
  }
  return out;
}

std::vector<ImuMeasurement> readingsBetween(const std::deque<ImuMeasurement>& buffer, TimeNs a,
                                            TimeNs b, TimeNs max_step_ns, TimeNs max_interval_ns) {
  std::vector<ImuMeasurement> out;
  out.push_back(readingIn(buffer, a, max_interval_ns));
  // Readings between out.back() and one at `to` (no real reading between them), in steps of at
  // most max_step_ns; not inside a gap, whose noise model counts its span once
  // (imu_preintegration.h).
  const auto fill = [&](TimeNs to) {
    const TimeNs from = out.back().stamp_ns;
    if (max_step_ns <= 0 || to - from <= max_step_ns) return;
    const TimeNs n = (to - from + max_step_ns - 1) / max_step_ns;
    const std::size_t size = out.size();
    for (TimeNs i = 1; i < n; ++i) {
      out.push_back(readingIn(buffer, from + (to - from) * i / n, max_interval_ns));
    }
    if (max_interval_ns > 0 && out[size].span_ns > max_interval_ns) out.resize(size);
  };
  auto it = std::upper_bound(buffer.begin(), buffer.end(), a,
                             [](TimeNs s, const ImuMeasurement& m) { return s < m.stamp_ns; });
  for (; it != buffer.end() && it->stamp_ns < b; ++it) {
    fill(it->stamp_ns);
    out.push_back(*it);
  }
  fill(b);
  out.push_back(readingIn(buffer, b, max_interval_ns));
  return out;
}

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
