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
  double sxx = 0.0;  // sum of (time - mean time)^2 over the readings [s^2]: slope variance 1/sxx
};

bool fitLocalLines(const std::deque<ImuMeasurement>& readings, TimeNs t, LocalLines* out,
                   double half_span_s = 0.01) {
  const TimeNs half = fromSeconds(half_span_s);
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
  out->sxx = denominator / n;
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

double ImuBuffer::timeOffsetInformation(TimeNs a, TimeNs b) const {
  // Lines through the readings of [a, b] (their slopes at its middle): the most readings there
  // are on both sides of a time the buffer has passed.
  LocalLines lines;
  const TimeNs middle = a + (b - a) / 2;
  if (!(rate_hz_ > 0.0) || b <= a ||
      !fitLocalLines(readings_, middle, &lines, 0.5 * toSeconds(b - a))) {
    return 0.0;
  }
  // A slope's noise adds 3 sigma^2 / sxx to its squared norm on average (sigma^2 = q^2 rate, one
  // reading's variance per axis): taken out, so that noise is not counted as motion. Not clipped
  // at zero here: where the rig hardly moves that would keep the noise's upper half (the floor
  // from translation-only motion came out 0.036 ms against the truth's 0.051 ms); the sum over
  // a run is unbiased.
  const auto term = [&](const Eigen::Vector3d& slope, double q) {
    if (!(q > 0.0)) return 0.0;
    const double noise = 3.0 * q * q * rate_hz_ / lines.sxx;
    return (slope.squaredNorm() - noise) / (q * q);
  };
  return (term(lines.gyro_slope, noise_.gyroscope_noise_density) +
          term(lines.accel_slope, noise_.accelerometer_noise_density)) *
         toSeconds(b - a);
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
