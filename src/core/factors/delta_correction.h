// Deltas of ImuDeltas (mvis/inertial/imu_reintegration.h) at other biases and intrinsics, for
// the factors that differentiate with ceres::Jet. Private to src/core/factors.
//
// To first order about the integration point x0 (exact value and derivatives at x = x0):
//   dR(x) = dR Exp(J_theta (x - x0)),  dp(x) = dp + J_p (x - x0),  dv(x) = dv + J_v (x - x0).
#pragma once

#include <type_traits>

#include "mvis/inertial/imu_reintegration.h"
#include "../common/tangent_jet.h"

namespace mvis {

template <typename T>
struct CorrectedDeltas {
  tangent_jet::Mat3<T> dR;
  tangent_jet::Vec3<T> dp, dv;
};

// x: the 30 variables [b_g b_a intrinsics] as T.
template <typename T>
CorrectedDeltas<T> correctDeltas(const ImuDeltas& d,
                                 const Eigen::Matrix<T, kDeltaVariables, 1>& x) {
  Eigen::Matrix<T, 9, 1> lin;
  if constexpr (std::is_same_v<T, double>) {
    lin = d.J * (x - d.x0);
  } else {
    // Values and derivatives apart, as doubles: J (x - x0) and J dx/d(directions).
    constexpr int kDirections = decltype(T::v)::RowsAtCompileTime;
    Eigen::Matrix<double, kDeltaVariables, 1> a;
    Eigen::Matrix<double, kDeltaVariables, kDirections> V;
    for (int i = 0; i < kDeltaVariables; ++i) {
      a[i] = x[i].a - d.x0[i];
      V.row(i) = x[i].v.transpose();
    }
    const Eigen::Matrix<double, 9, 1> la = d.J * a;
    const Eigen::Matrix<double, 9, kDirections> lv = d.J * V;
    for (int i = 0; i < 9; ++i) {
      lin[i].a = la[i];
      lin[i].v = lv.row(i).transpose();
    }
  }
  CorrectedDeltas<T> out;
  out.dR = d.dR.cast<T>() * tangent_jet::expT<T>(lin.template head<3>());
  out.dp = d.dp.cast<T>() + lin.template segment<3>(3);
  out.dv = d.dv.cast<T>() + lin.template tail<3>();
  return out;
}

}  // namespace mvis
