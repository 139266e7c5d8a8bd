#include "imu_buffer.h"

#include <algorithm>

namespace mvis {
namespace estimator_internal {

TimeNs cubicIntervalNs(const InertialSensor& sensor, double integration_step_s) {
  const double rate = sensor.update_rate;
  if (!(integration_step_s > 0.0) || !(rate > 0.0)) return 0;
  return fromSeconds(2.5 / rate);
}

ImuBuffer::ImuBuffer(const InertialSensor& base, double integration_step_s)
    : noise_(base.noise),
      rate_hz_(base.update_rate),
      step_s_(integration_step_s),
      cubic_interval_ns_(cubicIntervalNs(base, integration_step_s)) {}

void ImuBuffer::push(ImuMeasurement m) {
  if (!readings_.empty()) m.span_ns = m.stamp_ns - readings_.back().stamp_ns;
  readings_.push_back(m);
}

bool ImuBuffer::reaches(TimeNs t) const {
  if (readings_.empty() || readings_.back().stamp_ns < t) return false;
  const std::size_t n = readings_.size();
  return !(n > 1 && readings_[n - 2].stamp_ns < t &&
           readings_.back().stamp_ns - readings_[n - 2].stamp_ns <= cubic_interval_ns_);
}

ImuMeasurement ImuBuffer::at(TimeNs t) const { return readingIn(readings_, t, cubic_interval_ns_); }

std::vector<ImuMeasurement> ImuBuffer::between(TimeNs a, TimeNs b) const {
  return readingsBetween(readings_, a, b);
}

std::vector<ImuMeasurement> ImuBuffer::toIntegrate(TimeNs a, TimeNs b) const {
  return readingsBetween(readings_, a, b, fromSeconds(step_s_), cubic_interval_ns_);
}

std::shared_ptr<ImuPreintegration> ImuBuffer::preintegrate(TimeNs a, TimeNs b,
                                                           const Eigen::Vector3d& bg,
                                                           const Eigen::Vector3d& ba,
                                                           const ImuCorrection* correction) const {
  auto pre = std::make_shared<ImuPreintegration>(noise_, bg, ba, maxInterval());
  for (const auto& m : toIntegrate(a, b)) {
    pre->add(correction != nullptr ? correction->apply(m, false) : m);
  }
  return pre;
}

bool ImuBuffer::insideGap(TimeNs t) const {
  const double max_interval = maxInterval();
  if (max_interval <= 0.0 || readings_.empty()) return false;
  auto after = std::lower_bound(readings_.begin(), readings_.end(), t,
                                [](const ImuMeasurement& m, TimeNs s) { return m.stamp_ns < s; });
  if (after == readings_.end() || after == readings_.begin()) return false;
  return toSeconds(after->stamp_ns - std::prev(after)->stamp_ns) > max_interval;
}

double ImuBuffer::maxInterval() const { return rate_hz_ > 0.0 ? 2.5 / rate_hz_ : 0.0; }

namespace {

// Least-squares lines through the gyroscope and accelerometer readings within 10 ms of t, in
// time relative to t: their values and slopes at t. False with fewer than three readings.
struct LocalLines {
  Eigen::Vector3d gyro, gyro_slope, accel, accel_slope;
};

bool fitLocalLines(const std::deque<ImuMeasurement>& readings, TimeNs t, LocalLines* out) {
  const TimeNs half = fromSeconds(0.01);
  double st = 0.0, stt = 0.0;
  Eigen::Vector3d sw = Eigen::Vector3d::Zero(), stw = Eigen::Vector3d::Zero();
  Eigen::Vector3d sa = Eigen::Vector3d::Zero(), sta = Eigen::Vector3d::Zero();
  int n = 0;
  const auto first =
      std::lower_bound(readings.begin(), readings.end(), t - half,
                       [](const ImuMeasurement& m, TimeNs s) { return m.stamp_ns < s; });
  for (auto it = first; it != readings.end(); ++it) {
    const ImuMeasurement& m = *it;
    if (m.stamp_ns > t + half) break;
    const double x = toSeconds(m.stamp_ns - t);
    st += x;
    stt += x * x;
    sw += m.gyro;
    stw += x * m.gyro;
    sa += m.accel;
    sta += x * m.accel;
    ++n;
  }
  const double denominator = n * stt - st * st;
  if (n < 3 || denominator <= 0.0) return false;
  out->gyro_slope = (n * stw - st * sw) / denominator;
  out->accel_slope = (n * sta - st * sa) / denominator;
  out->gyro = (sw - out->gyro_slope * st) / n;
  out->accel = (sa - out->accel_slope * st) / n;
  return true;
}

}  // namespace

Eigen::Vector3d ImuBuffer::angularAcceleration(TimeNs t) const {
  LocalLines lines;
  return fitLocalLines(readings_, t, &lines) ? lines.gyro_slope : Eigen::Vector3d::Zero();
}

ImuMeasurement ImuBuffer::smoothedAt(TimeNs t) const {
  ImuMeasurement m = at(t);
  LocalLines lines;
  if (fitLocalLines(readings_, t, &lines)) {
    m.gyro = lines.gyro;
    m.accel = lines.accel;
  }
  return m;
}

void ImuBuffer::trimBefore(TimeNs keep_from) {
  while (readings_.size() > 2 && readings_[1].stamp_ns < keep_from) readings_.pop_front();
}

}  // namespace estimator_internal
}  // namespace mvis
