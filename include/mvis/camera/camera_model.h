// Pinhole camera with radtan or equidistant distortion, as Kalibr and OpenVINS define them.
//
// Frames and units: a point p_C = (x, y, z) [m] in the camera's optical frame (z forward) maps
// to the normalized point m = (x / z, y / z), distorted to d = D(m), then to pixels
//   u = fu * d.x + pu,  v = fv * d.y + pv
// with (0, 0) at the centre of the top-left pixel. The intrinsics are k = [fu fv pu pv] [px];
// the distortion coefficients are, for
// - radtan [k1 k2 p1 p2]: r2 = |m|^2, radial = 1 + k1 r2 + k2 r2^2,
//     d.x = m.x radial + 2 p1 m.x m.y + p2 (r2 + 2 m.x^2)
//     d.y = m.y radial + p1 (r2 + 2 m.y^2) + 2 p2 m.x m.y
// - equidistant [k1 k2 k3 k4] (Kannala-Brandt): r = |m|, theta = atan(r),
//     theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8),
//     d = (theta_d / r) m  (d = m as r -> 0)
// Templated on the scalar so Ceres can differentiate through it.
#pragma once

#include <Eigen/Core>
#include <cmath>

#include "mvis/rig/rig.h"

namespace mvis {

template <typename T>
Eigen::Matrix<T, 2, 1> distortRadtan(const Eigen::Matrix<T, 2, 1>& m,
                                     const Eigen::Matrix<T, 4, 1>& c) {
  const T x = m.x(), y = m.y();
  const T r2 = x * x + y * y;
  const T radial = T(1) + c[0] * r2 + c[1] * r2 * r2;
  return Eigen::Matrix<T, 2, 1>(x * radial + T(2) * c[2] * x * y + c[3] * (r2 + T(2) * x * x),
                                y * radial + c[2] * (r2 + T(2) * y * y) + T(2) * c[3] * x * y);
}

template <typename T>
Eigen::Matrix<T, 2, 1> distortEquidistant(const Eigen::Matrix<T, 2, 1>& m,
                                          const Eigen::Matrix<T, 4, 1>& c) {
  using std::atan;
  using std::sqrt;
  const T r2 = m.squaredNorm();
  // theta / r = atan(r) / r -> 1 - r^2 / 3 as r -> 0; use the series below 1e-8 (where the
  // square root's derivative would blow up).
  T theta_over_r;
  T theta2;
  if (r2 < T(1e-16)) {
    theta_over_r = T(1) - r2 / T(3);
    theta2 = r2;
  } else {
    const T r = sqrt(r2);
    const T theta = atan(r);
    theta_over_r = theta / r;
    theta2 = theta * theta;
  }
  const T theta4 = theta2 * theta2;
  const T poly =
      T(1) + c[0] * theta2 + c[1] * theta4 + c[2] * theta4 * theta2 + c[3] * theta4 * theta4;
  return (theta_over_r * poly) * m;
}

template <typename T>
Eigen::Matrix<T, 2, 1> distort(DistortionModel model, const Eigen::Matrix<T, 2, 1>& m,
                               const Eigen::Matrix<T, 4, 1>& coeffs) {
  return model == DistortionModel::kRadtan ? distortRadtan(m, coeffs)
                                           : distortEquidistant(m, coeffs);
}

// Pixel of the camera-frame point p_C. The caller checks p_C.z > 0.
template <typename T>
Eigen::Matrix<T, 2, 1> projectPoint(DistortionModel model, const Eigen::Matrix<T, 4, 1>& k,
                                    const Eigen::Matrix<T, 4, 1>& coeffs,
                                    const Eigen::Matrix<T, 3, 1>& p_C) {
  const Eigen::Matrix<T, 2, 1> m(p_C.x() / p_C.z(), p_C.y() / p_C.z());
  const Eigen::Matrix<T, 2, 1> d = distort(model, m, coeffs);
  return Eigen::Matrix<T, 2, 1>(k[0] * d.x() + k[2], k[1] * d.y() + k[3]);
}

// The pixel of p_C (z > 0) with its analytic Jacobians in p_C (2x3) and in the intrinsics
// [fu fv pu pv d0 d1 d2 d3] (2x8), for the estimator's hot loop (derivatives in the .cpp).
void projectWithJacobians(DistortionModel model, const double* intrinsics,
                          const Eigen::Vector3d& p_C, Eigen::Vector2d* uv,
                          Eigen::Matrix<double, 2, 3>* J_point,
                          Eigen::Matrix<double, 2, 8>* J_intrinsics);

// The camera's projection of p_C [m] to pixels; false when p_C is not in front of the camera.
bool projectToPixel(const Camera& camera, const Eigen::Vector3d& p_C, Eigen::Vector2d* uv);

// Normalized point m (p_C = z * [m; 1]) seen at pixel uv: the distortion inverted by Gauss-
// Newton, starting from `initial` if given (a neighbouring pixel's answer saves iterations).
// False if it does not converge to 1e-10 in normalized units (far outside the distortion
// model's valid field of view).
bool unprojectPixel(const Camera& camera, const Eigen::Vector2d& uv, Eigen::Vector2d* m,
                    const Eigen::Vector2d* initial = nullptr);

}  // namespace mvis
