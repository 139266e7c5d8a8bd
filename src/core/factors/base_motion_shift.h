// The shift of include/mvis/factors/base_motion.h on jets or doubles. Private to
// src/core/factors.
#pragma once

#include "mvis/factors/base_motion.h"
#include "../common/tangent_jet.h"

namespace mvis {

// R_k, p_k, v_k, b_g, b_a, g of state k; returns R(t_k + delta) and, if p != nullptr,
// p(t_k + delta).
template <typename T>
void shiftBasePose(const BaseMotion& m, const tangent_jet::Mat3<T>& R_k,
                   const tangent_jet::Vec3<T>& p_k, const tangent_jet::Vec3<T>& v_k,
                   const tangent_jet::Vec3<T>& b_g, const tangent_jet::Vec3<T>& b_a,
                   const tangent_jet::Vec3<T>& g, const T& delta, tangent_jet::Mat3<T>* R,
                   tangent_jet::Vec3<T>* p) {
  const T half_dt2 = T(0.5) * delta * delta;
  const tangent_jet::Vec3<T> phi =
      (m.gyro.cast<T>() - b_g) * delta + m.angular_acceleration.cast<T>() * half_dt2;
  *R = R_k * tangent_jet::expT(phi);
  if (p != nullptr) *p = p_k + v_k * delta + (R_k * (m.accel.cast<T>() - b_a) + g) * half_dt2;
}

}  // namespace mvis
