#include "mvis/estimator/odometry_propagator.h"

#include <algorithm>
#include <limits>
#include <sstream>

#include "imu_buffer.h"
#include "mvis/common/time.h"

namespace mvis {

struct OdometryPropagator::Readings {
  Readings(const InertialSensor& base, double integration_step_s, double keep_s)
      : buffer(base, integration_step_s),
        keep_ns(fromSeconds(keep_s)),
        // The cubic at the anchor needs two readings before it.
        margin_ns(
            fromSeconds(std::max(0.05, base.update_rate > 0.0 ? 3.0 / base.update_rate : 0.0))) {}
  estimator_internal::ImuBuffer buffer;  // raw readings: the anchor's correction is applied
  TimeNs keep_ns;
  TimeNs margin_ns;
  // The anchor's state to the last reading propagated to; null after a new anchor.
  std::shared_ptr<ImuPreintegration> pre;
};

OdometryPropagator::OdometryPropagator(const InertialSensor& base, double integration_step_s,
                                       double keep_s)
    : readings_(std::make_unique<Readings>(base, integration_step_s, keep_s)) {}

OdometryPropagator::~OdometryPropagator() = default;
OdometryPropagator::OdometryPropagator(OdometryPropagator&&) noexcept = default;
OdometryPropagator& OdometryPropagator::operator=(OdometryPropagator&&) noexcept = default;

void OdometryPropagator::setAnchor(const PropagationAnchor& anchor) {
  anchor_ = anchor;
  readings_->pre.reset();
}

void OdometryPropagator::reset() {
  readings_->buffer.clear();
  readings_->pre.reset();
  anchor_ = PropagationAnchor();
  ++epoch_;
}

struct PreparedAnchor::Impl {
  PropagationAnchor anchor;
  std::uint64_t epoch = 0;
  std::optional<estimator_internal::ImuBuffer> readings;  // a copy, until integrated
  std::shared_ptr<ImuPreintegration> pre;                 // the anchor to `last`
  TimeNs last = std::numeric_limits<TimeNs>::min();
};

PreparedAnchor::PreparedAnchor() : impl_(std::make_unique<Impl>()) {}
PreparedAnchor::~PreparedAnchor() = default;
PreparedAnchor::PreparedAnchor(PreparedAnchor&&) noexcept = default;
PreparedAnchor& PreparedAnchor::operator=(PreparedAnchor&&) noexcept = default;

void PreparedAnchor::integrate() {
  if (!impl_->readings) return;
  const PropagationAnchor& a = impl_->anchor;
  impl_->last = impl_->readings->lastStamp();
  impl_->pre = impl_->readings->preintegrate(a.state.stamp_ns, impl_->last, a.corrected_bias_gyro,
                                             a.corrected_bias_accel, &a.correction);
  impl_->readings.reset();
}

PreparedAnchor OdometryPropagator::prepare(const PropagationAnchor& anchor) const {
  PreparedAnchor out;
  out.impl_->anchor = anchor;
  out.impl_->epoch = epoch_;
  const estimator_internal::ImuBuffer& buffer = readings_->buffer;
  if (anchor.valid && !buffer.empty() && buffer.firstStamp() <= anchor.state.stamp_ns &&
      buffer.lastStamp() > anchor.state.stamp_ns) {
    out.impl_->readings = buffer;
  }
  return out;
}

void OdometryPropagator::install(PreparedAnchor&& prepared) {
  PreparedAnchor::Impl& p = *prepared.impl_;
  if (p.epoch != epoch_) return;
  setAnchor(p.anchor);
  if (!p.pre) return;  // not integrated, or nothing to integrate yet: the next add() does it
  readings_->pre = std::move(p.pre);
  for (const ImuMeasurement& m : readings_->buffer.readings()) {
    if (m.stamp_ns > p.last) readings_->pre->add(anchor_.correction.apply(m, false));
  }
}

std::optional<EstimatorState> OdometryPropagator::add(const ImuMeasurement& raw) {
  why_.clear();
  if (!raw.gyro.allFinite() || !raw.accel.allFinite()) {
    why_ = "non-finite reading";
    return std::nullopt;
  }
  estimator_internal::ImuBuffer& buffer = readings_->buffer;
  if (!buffer.empty() && raw.stamp_ns <= buffer.lastStamp()) {
    if (raw.stamp_ns >= buffer.lastStamp() - kNsPerSecond) {
      why_ = "reading out of order or repeated";
      return std::nullopt;
    }
    reset();  // the clock jumped back: what came before belongs to another run
  }
  buffer.push(raw);
  TimeNs keep_from = raw.stamp_ns - readings_->keep_ns;
  if (anchor_.valid) {
    keep_from = std::max(keep_from, anchor_.state.stamp_ns - readings_->margin_ns);
  }
  buffer.trimBefore(keep_from);
  if (!anchor_.valid) {
    why_ = "no state to propagate yet";
    return std::nullopt;
  }
  const TimeNs from = anchor_.state.stamp_ns;
  if (raw.stamp_ns <= from) {
    why_ = "reading before the newest state";
    return std::nullopt;
  }
  if (buffer.firstStamp() > from) {
    std::ostringstream s;
    s << "the newest state is " << toSeconds(raw.stamp_ns - from)
      << " s old, older than the readings kept";
    why_ = s.str();
    return std::nullopt;
  }
  std::shared_ptr<ImuPreintegration>& pre = readings_->pre;
  const ImuMeasurement corrected = anchor_.correction.apply(raw, false);
  if (!pre) {
    pre = buffer.preintegrate(from, raw.stamp_ns, anchor_.corrected_bias_gyro,
                              anchor_.corrected_bias_accel, &anchor_.correction);
  } else {
    pre->add(corrected);
  }
  angular_velocity_ = corrected.gyro - anchor_.corrected_bias_gyro;
  EstimatorState out;
  out.stamp_ns = raw.stamp_ns;
  Eigen::Quaterniond q;
  Eigen::Vector3d p, v;
  pre->predict(anchor_.state.T_G_I.q, anchor_.state.T_G_I.p, anchor_.state.v_G, anchor_.gravity_G,
               &q, &p, &v);
  out.T_G_I = SE3(q, p);
  out.v_G = v;
  out.bias_gyro = anchor_.state.bias_gyro;
  out.bias_accel = anchor_.state.bias_accel;
  return out;
}

}  // namespace mvis
