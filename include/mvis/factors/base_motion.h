// The base IMU's motion at a window state, for factors whose sensor clocks are offset from the
// base clock (auxiliary IMUs and gyroscopes, report Eq. 38-39 and 44).
//
// Such a factor's state k is made with the sensor's time offset t_d0 of that moment, so its
// readings from t_k - t_d0 in the sensor clock on happened at base time t_k + delta,
// delta = t_d - t_d0 with t_d the current estimate. The base pose there is state k's, shifted to
// second order with the base readings at t_k (w_m, a_m) and the angular acceleration alpha there:
//   R(t_k + delta) = R_k Exp((w_m - b_g,k) delta + 1/2 alpha delta^2)
//   p(t_k + delta) = p_k + v_k delta + 1/2 (R_k (a_m - b_a,k) + g) delta^2
// delta is the change of the offset estimate while the factor lives (milliseconds), where this
// is exact to far below the noise.
#pragma once

#include <Eigen/Core>

namespace mvis {

struct BaseMotion {
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();                  // w_m at t_k [rad/s]
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();                 // a_m at t_k [m/s^2]
  Eigen::Vector3d angular_acceleration = Eigen::Vector3d::Zero();  // [rad/s^2]
};

}  // namespace mvis
