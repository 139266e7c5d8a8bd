#include "aux_sensors.h"

#include <ceres/normal_prior.h>

#include <algorithm>
#include <sstream>

#include "imu_buffer.h"
#include "mvis/common/lie.h"
#include "mvis/factors/aux_imu_factor.h"
#include "mvis/factors/gyro_factor.h"

namespace mvis {
namespace estimator_internal {

AuxSensors::AuxSensors(const Rig& rig, const EstimatorOptions& options, const ImuBuffer& base,
                       Window& window, CalibrationBlocks& calibration,
                       ImuIntrinsicsBlocks& intrinsics, ObservabilityMonitor& monitor,
                       EstimatorCounters& counters)
    : rig_(rig),
      options_(options),
      base_(base),
      window_(window),
      calibration_(calibration),
      intrinsics_(intrinsics),
      monitor_(monitor),
      counters_(counters) {
  for (std::size_t i = 1; i < rig.inertial.size(); ++i) {
    auto a = std::make_unique<Stream>();
    a->sensor = i;
    a->gyro = rig.inertial[i].type == InertialType::kGyroscope;
    const ImuIntrinsicsBlock* b = intrinsics.block(i);
    // With an intrinsics block even when Tg is held: the held value is tested (inertial_fit.h).
    a->gravity_sensitive = a->gyro && (!rig.inertial[i].intrinsics.Tg.isZero(0.0) || b != nullptr);
    a->block_size = a->gyro ? 3 : AuxImuFactor::auxBlockSize(options.aux_imu_model);
    a->cubic_interval_ns = cubicIntervalNs(rig.inertial[i], options.imu_integration_step_s);
    streams_.push_back(std::move(a));
  }
}

std::string AuxSensors::takeWarning() {
  std::string out;
  out.swap(warning_);
  return out;
}

void AuxSensors::clear() {
  for (auto& a : streams_) {
    a->readings.clear();
    a->last = std::numeric_limits<TimeNs>::min();
    a->stopped = false;
  }
  warning_.clear();
}

void AuxSensors::leaving(const State& oldest, std::vector<double*>* leaving) {
  for (std::size_t i = 0; i < streams_.size(); ++i) {
    AuxState* as = oldest.aux[i].get();
    if (as == nullptr) continue;
    leaving->push_back(as->x);
    // The last estimate of the sensor's biases, for a chain that starts later.
    streams_[i]->bias_gyro = Eigen::Vector3d(streams_[i]->biasGyro(as));
    if (!streams_[i]->gyro) streams_[i]->bias_accel = Eigen::Vector3d(streams_[i]->biasAccel(as));
  }
}

Status AuxSensors::add(std::size_t sensor, const ImuMeasurement& m, bool in_window) {
  Stream& a = *streams_[sensor - 1];
  const InertialSensor& config = rig_.inertial[sensor];
  ImuMeasurement r = m;
  if (a.gyro) r.accel.setZero();  // a gyroscope's messages carry no acceleration
  if (!r.gyro.allFinite() || !r.accel.allFinite()) {
    ++counters_.aux_dropped;
    return Status::Error(config.name + ": non-finite reading dropped");
  }
  r = intrinsics_.arrivalCorrection(sensor).apply(r, a.gyro);
  if (a.last != std::numeric_limits<TimeNs>::min() && r.stamp_ns <= a.last) {
    if (r.stamp_ns >= a.last - kNsPerSecond) {
      ++counters_.aux_dropped;
      return Status::Error(config.name + ": reading out of order or repeated, dropped");
    }
    // Time jumped back (a bag restarted): the base IMU's jump resets the estimator; this
    // sensor's buffer starts over.
    a.readings.clear();
    a.last = std::numeric_limits<TimeNs>::min();
  }
  Status out = Status::Ok();
  if (a.stopped) {
    a.stopped = false;
    std::ostringstream s;
    s << config.name << ": readings again after " << toSeconds(r.stamp_ns - a.last)
      << " s; it rejoins the window";
    out = Status::Error(s.str());
  }
  if (!a.readings.empty()) r.span_ns = r.stamp_ns - a.readings.back().stamp_ns;
  a.last = r.stamp_ns;
  a.readings.push_back(r);
  // Readings wait for the base IMU and cameras; if those stop, the buffer must stay bounded.
  const std::size_t cap =
      std::max<std::size_t>(2000, static_cast<std::size_t>(20.0 * config.update_rate));
  while (a.readings.size() > cap) a.readings.pop_front();
  if (in_window) extend(a);
  return out;
}

void AuxSensors::extend() {
  for (auto& a : streams_) extend(*a);
}

std::shared_ptr<ImuPreintegration> AuxSensors::preintegrate(const Stream& a, TimeNs tau_a,
                                                            TimeNs tau_b, const Eigen::Vector3d& bg,
                                                            const Eigen::Vector3d& ba) const {
  if (a.readings.empty() || tau_b <= tau_a) return nullptr;
  if (a.readings.front().stamp_ns > tau_a || a.readings.back().stamp_ns < tau_b) return nullptr;
  // The cubic over the last interval needs the reading after the one past tau_b.
  const std::size_t n = a.readings.size();
  if (a.cubic_interval_ns > 0 && (n < 2 || a.readings[n - 2].stamp_ns < tau_b)) return nullptr;
  const std::vector<ImuMeasurement> readings = readingsBetween(
      a.readings, tau_a, tau_b, fromSeconds(options_.imu_integration_step_s), a.cubic_interval_ns);
  const TimeNs max_gap = fromSeconds(options_.aux_max_gap_s);
  for (const auto& r : readings) {
    if (r.span_ns > max_gap) return nullptr;
  }
  const InertialSensor& config = rig_.inertial[a.sensor];
  const double max_interval = config.update_rate > 0.0 ? 2.5 / config.update_rate : 0.0;
  auto pre = std::make_shared<ImuPreintegration>(config.noise, bg, ba, max_interval);
  if (a.gravity_sensitive) {
    std::vector<ImuMeasurement> with_force = readings;
    if (!specificForce(a, &with_force)) return nullptr;
    for (const auto& r : with_force) pre->add(r);
    return pre;
  }
  for (const auto& r : readings) pre->add(r);
  return pre;
}

bool AuxSensors::specificForce(const Stream& a, std::vector<ImuMeasurement>* readings) const {
  const std::size_t idx = a.sensor - 1;
  if (base_.empty() || window_.states().empty() || readings->empty()) return false;
  const TimeNs td = fromSeconds(calibration_.aux(idx).time_offset[0]);
  if (readings->front().stamp_ns + td < base_.firstStamp() ||
      !base_.reaches(readings->back().stamp_ns + td)) {
    return false;
  }
  Eigen::Matrix3d R_AI;
  Eigen::Vector3d p_AI;
  calibration_.aux(idx).extrinsicParts(&R_AI, &p_AI);
  const Eigen::Vector3d p_IA = -R_AI.transpose() * p_AI;
  // The base readings as stored (configured intrinsics applied), or raw while the base's are
  // estimated: then corrected by the current estimate, the biases likewise.
  const bool raw = intrinsics_.block(0) != nullptr;
  const State& newest = *window_.states().back();
  Eigen::Vector3d bg = newest.biasGyro(), ba = newest.biasAccel();
  if (raw) intrinsics_.baseBiases(newest.biasGyro(), newest.biasAccel(), &bg, &ba);
  const auto reading = [&](TimeNs t) {
    ImuMeasurement m = base_.at(t);
    return raw ? intrinsics_.baseCorrection().apply(m, false) : m;
  };
  const Eigen::Matrix3d& gravity = intrinsics_.arrivalCorrection(a.sensor).gravity;
  for (auto& r : *readings) {
    const TimeNs t = r.stamp_ns + td;
    const ImuMeasurement m = reading(t);
    const Eigen::Vector3d w = m.gyro - bg;
    const Eigen::Vector3d alpha = base_.angularAcceleration(t);
    r.accel = R_AI * (m.accel - ba + alpha.cross(p_IA) + w.cross(w.cross(p_IA)));
    r.gyro -= gravity * r.accel;  // configured Tg (zero while it is estimated)
  }
  return true;
}

bool AuxSensors::needsBaseReadings() const {
  for (const auto& a : streams_) {
    if (a->gravity_sensitive) return true;
  }
  return false;
}

void AuxSensors::extend(Stream& a) {
  const auto& states = window_.states();
  if (states.size() < 2) return;
  const std::size_t idx = a.sensor - 1;
  const TimeNs td = fromSeconds(calibration_.aux(idx).time_offset[0]);
  // A sensor whose readings stopped leaves the window, once, with a warning.
  const TimeNs behind = states.back()->t - td - a.last;
  if (!a.stopped && a.last != std::numeric_limits<TimeNs>::min() &&
      behind > fromSeconds(options_.aux_timeout_s)) {
    a.stopped = true;
    ++counters_.aux_dropouts;
    std::ostringstream s;
    s << rig_.inertial[a.sensor].name << ": no readings for " << toSeconds(behind)
      << " s; it leaves the window until they return";
    warning_ = s.str();
  }
  std::size_t newest = states.size();  // the newest window state with a state of a
  for (std::size_t k = states.size(); k-- > 0;) {
    if (states[k]->aux[idx]) {
      newest = k;
      break;
    }
  }
  if (newest < states.size()) {
    for (std::size_t k = newest + 1; k < states.size(); ++k) {
      if (!states[k - 1]->aux[idx]) break;
      append(a, k);
      if (!states[k]->aux[idx]) break;  // readings do not reach it yet
    }
    return;
  }
  // No chain: start one at the first run of window states the readings cover.
  auto tauOf = [&](std::size_t k) { return states[k]->t - td; };
  const Eigen::Vector3d bg = a.bias_gyro, ba = a.bias_accel;
  std::size_t k0 = 0;
  while (k0 + 1 < states.size() && !preintegrate(a, tauOf(k0), tauOf(k0 + 1), bg, ba)) ++k0;
  if (k0 + 1 >= states.size()) return;
  std::size_t k1 = k0 + 1;
  while (k1 + 1 < states.size() && preintegrate(a, tauOf(k1), tauOf(k1 + 1), bg, ba)) ++k1;
  startChain(a, k0, k1);
}

void AuxSensors::startChain(Stream& a, std::size_t k0, std::size_t k1) {
  const std::size_t idx = a.sensor - 1;
  const InertialSensor& config = rig_.inertial[a.sensor];
  const double td = calibration_.aux(idx).time_offset[0];
  const TimeNs td_ns = fromSeconds(td);
  Eigen::Matrix3d R_AI;
  Eigen::Vector3d p_AI;
  calibration_.aux(idx).extrinsicParts(&R_AI, &p_AI);
  const Eigen::Vector3d g(calibration_.gravity());
  const std::size_t n = k1 - k0 + 1;
  std::vector<TimeNs> tau(n);
  std::vector<Eigen::Matrix3d> R_A(n);
  std::vector<Eigen::Vector3d> p_A(n);
  for (std::size_t i = 0; i < n; ++i) {
    const State& s = window_.state(k0 + i);
    tau[i] = s.t - td_ns;
    R_A[i] = poseRotation(s.pose).toRotationMatrix() * R_AI.transpose();
    p_A[i] = posePosition(s.pose) - R_A[i] * p_AI;
  }

  // Gyroscope bias, Eq. 41: J_R_bg db = Log(dR(b0)^T R_A,k^T R_A,k+1) over the intervals, with
  // the rotation noise of each and the bias prior as weights.
  const double sg = config.noise.gyroscope_noise_density;
  Eigen::Matrix3d N =
      Eigen::Matrix3d::Identity() / (options_.bias_gyro_prior * options_.bias_gyro_prior);
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  using P = ImuPreintegration;
  for (std::size_t i = 0; i + 1 < n; ++i) {
    auto pre = preintegrate(a, tau[i], tau[i + 1], a.bias_gyro, a.bias_accel);
    const Eigen::Matrix3d H = pre->jacobian().block<3, 3>(P::kRotation, P::kBiasGyro);
    const Eigen::Vector3d y =
        lie::logSO3(pre->deltaR().toRotationMatrix().transpose() * R_A[i].transpose() * R_A[i + 1]);
    const double w = 1.0 / (sg * sg * pre->duration() + 1e-12);
    N += w * H.transpose() * H;
    rhs += w * H.transpose() * y;
  }
  const Eigen::Vector3d bg = a.bias_gyro + N.ldlt().solve(rhs);

  // Velocities from the rigid-body relation, Eq. 40, and the accelerometer bias, Eq. 42-43.
  std::vector<Eigen::Vector3d> v_A(n, Eigen::Vector3d::Zero());
  Eigen::Vector3d ba = a.bias_accel;
  if (!a.gyro) {
    const Eigen::Vector3d p_IA = -R_AI.transpose() * p_AI;
    for (std::size_t i = 0; i < n; ++i) {
      const State& s = window_.state(k0 + i);
      const Eigen::Vector3d w_I =
          R_AI.transpose() * (readingIn(a.readings, tau[i], a.cubic_interval_ns).gyro - bg);
      v_A[i] = Eigen::Vector3d(s.speed_bias) + poseRotation(s.pose) * w_I.cross(p_IA);
    }
    const double sa = config.noise.accelerometer_noise_density;
    Eigen::Matrix3d Na =
        Eigen::Matrix3d::Identity() / (options_.bias_accel_prior * options_.bias_accel_prior);
    Eigen::Vector3d rhs_a = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i + 1 < n; ++i) {
      auto pre = preintegrate(a, tau[i], tau[i + 1], bg, a.bias_accel);
      const double T = pre->duration();
      const Eigen::Matrix3d Rt = R_A[i].transpose();
      const Eigen::Vector3d yv = Rt * (v_A[i + 1] - v_A[i] - g * T) - pre->deltaV();
      const Eigen::Vector3d yp =
          Rt * (p_A[i + 1] - p_A[i] - v_A[i] * T - 0.5 * g * T * T) - pre->deltaP();
      const Eigen::Matrix3d Hv = pre->jacobian().block<3, 3>(P::kVelocity, P::kBiasAccel);
      const Eigen::Matrix3d Hp = pre->jacobian().block<3, 3>(P::kPosition, P::kBiasAccel);
      const double wv = 1.0 / (sa * sa * T + 1e-12), wp = 3.0 / (sa * sa * T * T * T + 1e-12);
      Na += wv * Hv.transpose() * Hv + wp * Hp.transpose() * Hp;
      rhs_a += wv * Hv.transpose() * yv + wp * Hp.transpose() * yp;
    }
    ba = a.bias_accel + Na.ldlt().solve(rhs_a);
  }

  for (std::size_t i = 0; i < n; ++i) {
    auto st = std::make_unique<AuxState>();
    st->td0 = td;
    if (a.block_size == 9) Eigen::Map<Eigen::Vector3d>{st->x} = v_A[i];
    Eigen::Map<Eigen::Vector3d>{a.biasGyro(st.get())} = bg;
    if (!a.gyro) Eigen::Map<Eigen::Vector3d>{a.biasAccel(st.get())} = ba;
    State& s = window_.state(k0 + i);
    s.aux[idx] = std::move(st);
    window_.problem()->AddParameterBlock(s.aux[idx]->x, a.block_size);
  }
  for (std::size_t i = 0; i + 1 < n; ++i) {
    addFactor(a, k0 + i, preintegrate(a, tau[i], tau[i + 1], bg, ba));
  }
  // A weak prior on the first state: what a short stretch of motion cannot pin down.
  Eigen::VectorXd inv_std(a.block_size);
  int at = 0;
  if (a.block_size == 9) {
    inv_std.head<3>().setConstant(1.0 / options_.aux_velocity_prior);
    at = 3;
  }
  inv_std.segment<3>(at).setConstant(1.0 / options_.bias_gyro_prior);
  if (!a.gyro) inv_std.segment<3>(at + 3).setConstant(1.0 / options_.bias_accel_prior);
  AuxState* first = window_.state(k0).aux[idx].get();
  const Eigen::VectorXd mean = Eigen::Map<const Eigen::VectorXd>(first->x, a.block_size);
  window_.addRecord(&window_.state(k0), new ceres::NormalPrior(inv_std.asDiagonal(), mean), nullptr,
                    {first->x});
  ++counters_.aux_starts;
}

void AuxSensors::append(Stream& a, std::size_t k) {
  const std::size_t idx = a.sensor - 1;
  AuxState* prev = window_.state(k - 1).aux[idx].get();
  const double td = calibration_.aux(idx).time_offset[0];
  const TimeNs tau = window_.state(k).t - fromSeconds(td);
  const Eigen::Vector3d bg(a.biasGyro(prev));
  const Eigen::Vector3d ba = a.gyro ? Eigen::Vector3d::Zero() : Eigen::Vector3d(a.biasAccel(prev));
  const TimeNs prev_tau = window_.state(k - 1).t - fromSeconds(prev->td0);
  auto pre = preintegrate(a, prev_tau, tau, bg, ba);
  if (!pre) return;
  auto st = std::make_unique<AuxState>();
  st->td0 = td;
  std::copy(prev->x, prev->x + a.block_size, st->x);
  if (a.block_size == 9) {
    // The velocity as the readings predict it from the previous aux pose.
    Eigen::Matrix3d R_AI;
    Eigen::Vector3d p_AI;
    calibration_.aux(idx).extrinsicParts(&R_AI, &p_AI);
    const State& sp = window_.state(k - 1);
    const Eigen::Quaterniond q_A(poseRotation(sp.pose).toRotationMatrix() * R_AI.transpose());
    const Eigen::Vector3d p_A = posePosition(sp.pose) - q_A * p_AI;
    Eigen::Quaterniond q;
    Eigen::Vector3d p, v;
    pre->predict(q_A, p_A, Eigen::Vector3d(prev->x), Eigen::Vector3d(calibration_.gravity()), &q,
                 &p, &v);
    Eigen::Map<Eigen::Vector3d>{st->x} = v;
  }
  State& s = window_.state(k);
  s.aux[idx] = std::move(st);
  window_.problem()->AddParameterBlock(s.aux[idx]->x, a.block_size);
  if (changes_ != nullptr) addEvidence(a, window_.state(k - 1), s.t);
  addFactor(a, k - 1, pre);
}

void AuxSensors::addEvidence(const Stream& a, const State& from, TimeNs to) {
  const std::size_t idx = a.sensor - 1;
  const AuxCalibration& cal = calibration_.aux(idx);
  const InertialSensor& sensor = rig_.inertial[a.sensor];
  const InertialSensor& base = rig_.inertial[0];
  const AuxState* aux = from.aux[idx].get();
  // Tested against a saved calibration only (estimator_changes.cpp, changeSlot).
  if (aux == nullptr || !(sensor.update_rate > 0.0) || !sensor.std || cal.moved) return;
  // Each reading's noise, and the base reading's carried to it (a reading's white noise is its
  // density times the square root of its rate).
  const double rate = sensor.update_rate;
  const double sigma_g = std::sqrt(rate * (std::pow(sensor.noise.gyroscope_noise_density, 2) +
                                           std::pow(base.noise.gyroscope_noise_density, 2)));
  const double sigma_a = std::sqrt(rate * (std::pow(sensor.noise.accelerometer_noise_density, 2) +
                                           std::pow(base.noise.accelerometer_noise_density, 2)));
  if (!(sigma_g > 0.0) || (!a.gyro && !(sigma_a > 0.0))) return;
  Eigen::Matrix3d R;  // R_AI
  Eigen::Vector3d p_AI;
  cal.extrinsicParts(&R, &p_AI);
  const Eigen::Vector3d r = -R.transpose() * p_AI;  // the sensor's origin in {I}
  Eigen::Vector3d bg_base, ba_base;
  intrinsics_.baseBiases(from.biasGyro(), from.biasAccel(), &bg_base, &ba_base);
  AuxState* aux_values = const_cast<AuxState*>(aux);
  const Eigen::Vector3d bg(a.biasGyro(aux_values));
  const Eigen::Vector3d ba =
      a.gyro ? Eigen::Vector3d::Zero() : Eigen::Vector3d(a.biasAccel(aux_values));
  const TimeNs td = fromSeconds(cal.time_offset[0]);
  const int rows = a.gyro ? 3 : 6;
  Eigen::VectorXd res(rows);
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(rows, ChangeDetector::kAll);
  // The readings as the current intrinsics estimate has them (arrival leaves them raw while they
  // are estimated: a scale error of 0.4% looked like the sensor turned by 0.2-0.4 deg), and a
  // gyroscope's gravity sensitivity applied to the specific force at it.
  const std::optional<ImuCorrection> estimated = intrinsics_.estimatedCorrection(a.sensor);
  const Eigen::Matrix3d& gravity =
      estimated ? estimated->gravity : intrinsics_.arrivalCorrection(a.sensor).gravity;
  for (const ImuMeasurement& raw : a.readings) {
    const TimeNs t = raw.stamp_ns + td;
    if (t <= from.t || t > to) continue;
    ImuMeasurement m = estimated ? estimated->apply(raw, a.gyro) : raw;
    const ImuMeasurement at = intrinsics_.baseCorrection().apply(base_.smoothedAt(t), false);
    const Eigen::Vector3d w = at.gyro - bg_base;
    const Eigen::Vector3d alpha = base_.angularAcceleration(t);
    const Eigen::Matrix3d K = lie::hat(alpha) + lie::hat(w) * lie::hat(w);
    const Eigen::Vector3d u = at.accel - ba_base + K * r;  // specific force at the sensor, {I}
    if (a.gyro) m.gyro -= gravity * (R * u);
    // Gyroscope: w_A = R Exp(dtheta) w_I(t + dt) + b_g (right perturbation of T_i_b).
    res.head<3>() = (m.gyro - R * w - bg) / sigma_g;
    J.block<3, 3>(0, 0) = R * lie::hat(w) / sigma_g;
    J.block<3, 1>(0, ChangeDetector::kAll - 1) = -R * alpha / sigma_g;  // a nuisance
    J.block<3, 3>(0, 7) = -Eigen::Matrix3d::Identity() / sigma_g;
    if (!a.gyro) {
      // Accelerometer: f_A = R (f_I + K r) + b_a with K = [alpha]x + [w]x[w]x and, perturbed,
      // R -> R Exp(dtheta), r -> r + [r]x dtheta - R^T dp.
      res.tail<3>() = (m.accel - R * u - ba) / sigma_a;
      // The specific force's rate, for the time offset (a central difference over 10 ms of
      // smoothed readings).
      constexpr TimeNs kHalfSpanNs = 5000000;
      const Eigen::Vector3d jerk =
          (base_.smoothedAt(t + kHalfSpanNs).accel - base_.smoothedAt(t - kHalfSpanNs).accel) /
          toSeconds(2 * kHalfSpanNs);
      J.block<3, 1>(3, ChangeDetector::kAll - 1) = -R * jerk / sigma_a;
      J.block<3, 3>(3, 0) = (R * lie::hat(u) - R * K * lie::hat(r)) / sigma_a;
      J.block<3, 3>(3, 3) = R * K * R.transpose() / sigma_a;
      J.block<3, 3>(3, 10) = -Eigen::Matrix3d::Identity() / sigma_a;
    }
    changes_->add(first_slot_ + idx, t, res, J);
  }
}

void AuxSensors::addFactor(Stream& a, std::size_t k, std::shared_ptr<const ImuPreintegration> pre) {
  const std::size_t idx = a.sensor - 1;
  AuxCalibration& cal = calibration_.aux(idx);
  State* si = &window_.state(k);
  State* sj = &window_.state(k + 1);
  AuxState* ai = si->aux[idx].get();
  AuxState* aj = sj->aux[idx].get();
  monitor_.addReadingMoments(a.sensor, sj->t, pre->samples());
  double* intrinsics = intrinsics_.values(a.sensor);
  const IntrinsicsLinearization mode = options_.imu_intrinsics_linearization;
  if (a.gyro) {
    std::vector<double*> blocks = {si->pose, si->speed_bias, sj->pose,     sj->speed_bias,
                                   ai->x,    aj->x,          cal.rotation, cal.time_offset};
    ceres::CostFunction* cost = nullptr;
    if (intrinsics != nullptr) {
      cost = new GyroFactor(std::move(pre), ai->td0, aj->td0, si->motion, sj->motion,
                            intrinsics_.block(a.sensor)->frame, mode,
                            intrinsics_.block(a.sensor)->initial);
      blocks.push_back(intrinsics);
    } else {
      cost = new GyroFactor(std::move(pre), ai->td0, aj->td0, si->motion, sj->motion);
    }
    window_.addRecord(si, cost, nullptr, std::move(blocks), static_cast<int>(a.sensor));
    return;
  }
  std::vector<double*> blocks = {si->pose,       si->speed_bias,  sj->pose,
                                 sj->speed_bias, ai->x,           aj->x,
                                 cal.extrinsic,  cal.time_offset, calibration_.gravity()};
  ceres::CostFunction* cost = nullptr;
  if (intrinsics != nullptr) {
    cost = new AuxImuFactor(options_.aux_imu_model, std::move(pre), ai->td0, aj->td0, si->motion,
                            sj->motion, intrinsics_.block(a.sensor)->frame, mode,
                            intrinsics_.block(a.sensor)->initial);
    blocks.push_back(intrinsics);
  } else {
    cost = new AuxImuFactor(options_.aux_imu_model, std::move(pre), ai->td0, aj->td0, si->motion,
                            sj->motion);
  }
  window_.addRecord(si, cost, nullptr, std::move(blocks), static_cast<int>(a.sensor));
}

void AuxSensors::trim(TimeNs from) {
  for (auto& a : streams_) {
    if (a->readings.empty()) continue;
    TimeNs keep = from == std::numeric_limits<TimeNs>::max()
                      ? a->readings.back().stamp_ns - 2 * kNsPerSecond
                      : from - fromSeconds(calibration_.aux(a->sensor - 1).time_offset[0]);
    keep -= fromSeconds(0.05);
    while (a->readings.size() > 2 && a->readings[1].stamp_ns < keep) a->readings.pop_front();
  }
}

}  // namespace estimator_internal
}  // namespace mvis
