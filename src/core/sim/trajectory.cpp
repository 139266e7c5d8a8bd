#include "mvis/sim/trajectory.h"

#include <cmath>

namespace mvis {

std::array<double, 3> Signal::evaluate(double t) const {
  std::array<double, 3> out = {offset, 0.0, 0.0};
  for (const auto& s : terms) {
    const double w = 2.0 * M_PI * s.frequency_hz;
    const double arg = w * t + s.phase;
    out[0] += s.amplitude * std::sin(arg);
    out[1] += s.amplitude * w * std::cos(arg);
    out[2] -= s.amplitude * w * w * std::sin(arg);
  }
  return out;
}

TrajectoryState SinusoidTrajectory::evaluate(double t) const {
  TrajectoryState state;
  Eigen::Vector3d p, v, a;
  for (int i = 0; i < 3; ++i) {
    const auto s = position_[i].evaluate(t);
    p[i] = s[0];
    v[i] = s[1];
    a[i] = s[2];
  }
  const auto yaw = euler_[0].evaluate(t), pitch = euler_[1].evaluate(t),
             roll = euler_[2].evaluate(t);
  const double psi = yaw[0], dpsi = yaw[1], ddpsi = yaw[2];
  const double th = pitch[0], dth = pitch[1], ddth = pitch[2];
  const double ph = roll[0], dph = roll[1], ddph = roll[2];
  const Eigen::Matrix3d R_euler = (Eigen::AngleAxisd(psi, Eigen::Vector3d::UnitZ()) *
                                   Eigen::AngleAxisd(th, Eigen::Vector3d::UnitY()) *
                                   Eigen::AngleAxisd(ph, Eigen::Vector3d::UnitX()))
                                      .toRotationMatrix();
  // Body rates of Rz(psi) Ry(theta) Rx(phi), in the frame after the three rotations.
  const double sth = std::sin(th), cth = std::cos(th), sph = std::sin(ph), cph = std::cos(ph);
  const Eigen::Vector3d w_euler(dph - dpsi * sth, dth * cph + dpsi * cth * sph,
                                -dth * sph + dpsi * cth * cph);
  const Eigen::Vector3d dw_euler(ddph - ddpsi * sth - dpsi * dth * cth,
                                 ddth * cph - dth * dph * sph + ddpsi * cth * sph -
                                     dpsi * dth * sth * sph + dpsi * dph * cth * cph,
                                 -ddth * sph - dth * dph * cph + ddpsi * cth * cph -
                                     dpsi * dth * sth * cph - dpsi * dph * cth * sph);
  // R_G_I = R_euler R_offset with R_offset constant: body rates rotate into {I}.
  state.T_G_I = SE3(Eigen::Matrix3d(R_euler * R_offset_), p);
  state.v_G = v;
  state.a_G = a;
  state.w_I = R_offset_.transpose() * w_euler;
  state.dw_I = R_offset_.transpose() * dw_euler;
  return state;
}

}  // namespace mvis
