#include "mvis/inertial/imu_readings.h"

#include <algorithm>

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

}  // namespace mvis
