#include "mvis/camera/camera_model.h"

#include <Eigen/LU>

namespace mvis {

bool projectToPixel(const Camera& camera, const Eigen::Vector3d& p_C, Eigen::Vector2d* uv) {
  if (!(p_C.z() > 1e-9)) return false;
  *uv = projectPoint<double>(camera.distortion_model, camera.intrinsics, camera.distortion_coeffs,
                             p_C);
  return true;
}

bool unprojectPixel(const Camera& camera, const Eigen::Vector2d& uv, Eigen::Vector2d* m,
                    const Eigen::Vector2d* initial) {
  const Eigen::Vector4d& k = camera.intrinsics;
  const Eigen::Vector2d target((uv.x() - k[2]) / k[0], (uv.y() - k[3]) / k[1]);
  // Without a hint the undistorted point starts at the distorted one.
  Eigen::Vector2d x = initial ? *initial : target;
  constexpr double kStep = 1e-7;
  for (int iteration = 0; iteration < 50; ++iteration) {
    const Eigen::Vector2d f = distort<double>(camera.distortion_model, x, camera.distortion_coeffs);
    const Eigen::Vector2d r = f - target;
    if (r.norm() < 1e-12) {
      *m = x;
      return true;
    }
    // Central-difference Jacobian of the 2-D distortion (cheap, and exact enough for Newton).
    Eigen::Matrix2d J;
    for (int i = 0; i < 2; ++i) {
      const Eigen::Vector2d h = Eigen::Vector2d::Unit(i) * kStep;
      J.col(i) = (distort<double>(camera.distortion_model, x + h, camera.distortion_coeffs) -
                  distort<double>(camera.distortion_model, x - h, camera.distortion_coeffs)) /
                 (2 * kStep);
    }
    if (std::abs(J.determinant()) < 1e-12) return false;
    x -= J.inverse() * r;
  }
  const Eigen::Vector2d f = distort<double>(camera.distortion_model, x, camera.distortion_coeffs);
  if ((f - target).norm() < 1e-10) {
    *m = x;
    return true;
  }
  return false;
}

}  // namespace mvis
