#include "mvis/sim/imu_simulator.h"

#include <cmath>
#include <random>

namespace mvis {

void trueInertialMotion(const InertialSensor& sensor, const TrajectoryState& base,
                        Eigen::Vector3d* w_i, Eigen::Vector3d* f_i) {
  const Eigen::Matrix3d R_i_b = sensor.T_i_b.rotation();
  const Eigen::Vector3d p_b_i = sensor.T_i_b.inverse().p;  // sensor i's origin in {I}
  const Eigen::Vector3d& w = base.w_I;
  *w_i = R_i_b * w;
  *f_i = R_i_b * (base.specificForce() + base.dw_I.cross(p_b_i) + w.cross(w.cross(p_b_i)));
}

std::vector<ImuSample> simulateImu(const InertialSensor& sensor, const TrajectoryFunction& base,
                                   TimeNs t0_ns, TimeNs start_ns, TimeNs end_ns,
                                   const ImuSimulationOptions& options) {
  std::vector<ImuSample> samples;
  if (!(sensor.update_rate > 0.0) || end_ns < start_ns) return samples;
  const TimeNs period_ns = fromSeconds(1.0 / sensor.update_rate);
  const double dt = toSeconds(period_ns);
  std::mt19937_64 rng(options.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const auto gaussian3 = [&]() { return Eigen::Vector3d(normal(rng), normal(rng), normal(rng)); };
  const ImuNoise& n = sensor.noise;
  const ImuIntrinsics& in = sensor.intrinsics;
  const bool has_accel = sensor.type == InertialType::kImu;
  Eigen::Vector3d bg = options.initial_bias_gyro;
  Eigen::Vector3d ba = has_accel ? options.initial_bias_accel : Eigen::Vector3d::Zero();
  const TimeNs offset_ns = fromSeconds(sensor.time_offset);
  samples.reserve(static_cast<std::size_t>((end_ns - start_ns) / period_ns) + 1);
  for (TimeNs stamp = start_ns; stamp <= end_ns; stamp += period_ns) {
    // Sampled at sensor time `stamp`, i.e. base time stamp + time_offset.
    const TrajectoryState state = base(toSeconds(stamp + offset_ns - t0_ns));
    Eigen::Vector3d w_i, f_i;
    trueInertialMotion(sensor, state, &w_i, &f_i);
    ImuSample s;
    s.stamp_ns = stamp;
    s.gyro = in.Tw * in.R_IMUtoGYRO * w_i + in.Tg * f_i + bg;
    if (has_accel) s.accel = in.Ta * in.R_IMUtoACC * f_i + ba;
    if (options.noise) {
      s.gyro += n.gyroscope_noise_density / std::sqrt(dt) * gaussian3();
      if (has_accel) s.accel += n.accelerometer_noise_density / std::sqrt(dt) * gaussian3();
    }
    s.bias_gyro = bg;
    s.bias_accel = ba;
    samples.push_back(s);
    if (options.biases) {
      bg += n.gyroscope_random_walk * std::sqrt(dt) * gaussian3();
      if (has_accel) ba += n.accelerometer_random_walk * std::sqrt(dt) * gaussian3();
    }
  }
  return samples;
}

}  // namespace mvis
