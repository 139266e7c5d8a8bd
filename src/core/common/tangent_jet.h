// Forward-mode differentiation in the tangent spaces of the estimator's blocks, for the factor
// that differentiates with ceres::Jet (the tag factor's kinematic and pose-based camera poses);
// expT also serves the inertial re-integration. Private to src/core.
//
// A factor picks a jet dimension per tangent direction of its blocks (pose and extrinsic blocks
// perturbed on the right, R Exp(dtheta), p + dp; plain vectors in their ambient coordinates),
// seeds them with perturbRotation / perturbVector / perturbScalar and evaluates on jets.
#pragma once

#include <ceres/jet.h>
#include <ceres/rotation.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <type_traits>

namespace mvis {
namespace tangent_jet {

template <typename T>
using Mat3 = Eigen::Matrix<T, 3, 3>;
template <typename T>
using Vec3 = Eigen::Matrix<T, 3, 1>;

template <typename T>
Mat3<T> expT(const Vec3<T>& w) {
  Mat3<T> R;
  ceres::AngleAxisToRotationMatrix(w.data(), R.data());  // column major, as Eigen
  return R;
}

template <typename T>
Vec3<T> logT(const Mat3<T>& R) {
  Vec3<T> w;
  ceres::RotationMatrixToAngleAxis(R.data(), w.data());
  return w;
}

// R Exp(delta) with delta the jet directions first..first+2; plain R for doubles.
template <typename T>
Mat3<T> perturbRotation(const Eigen::Quaterniond& q, int first) {
  if constexpr (std::is_same_v<T, double>) {
    return q.toRotationMatrix();
  } else {
    Vec3<T> delta;
    for (int i = 0; i < 3; ++i) delta[i] = T(0.0, first + i);
    return q.toRotationMatrix().cast<T>() * expT(delta);
  }
}

// x[0..2] with the jet directions first..first+2; plain values for doubles.
template <typename T>
Vec3<T> perturbVector(const double* x, int first) {
  Vec3<T> out;
  for (int i = 0; i < 3; ++i) {
    if constexpr (std::is_same_v<T, double>) {
      out[i] = x[i];
    } else {
      out[i] = T(x[i], first + i);
    }
  }
  return out;
}

// One scalar with jet direction `index`; plain for doubles.
template <typename T>
T perturbScalar(double x, int index) {
  if constexpr (std::is_same_v<T, double>) {
    return x;
  } else {
    return T(x, index);
  }
}

}  // namespace tangent_jet
}  // namespace mvis
