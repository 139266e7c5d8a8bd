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

namespace {

// Distorted point d of normalized m, with dd/dm (2x2) and dd/dcoeffs (2x4).
void distortWithJacobians(DistortionModel model, const Eigen::Vector2d& m, const double* c,
                          Eigen::Vector2d* d, Eigen::Matrix2d* J_m,
                          Eigen::Matrix<double, 2, 4>* J_c) {
  const double x = m.x(), y = m.y();
  const double r2 = x * x + y * y;
  if (model == DistortionModel::kRadtan) {
    const double radial = 1.0 + c[0] * r2 + c[1] * r2 * r2;
    const double dradial = 2.0 * (c[0] + 2.0 * c[1] * r2);  // d radial / d x = dradial * x
    *d = {x * radial + 2.0 * c[2] * x * y + c[3] * (r2 + 2.0 * x * x),
          y * radial + c[2] * (r2 + 2.0 * y * y) + 2.0 * c[3] * x * y};
    (*J_m) << radial + x * dradial * x + 2.0 * c[2] * y + 6.0 * c[3] * x,
        x * dradial * y + 2.0 * c[2] * x + 2.0 * c[3] * y,
        y * dradial * x + 2.0 * c[2] * x + 2.0 * c[3] * y,
        radial + y * dradial * y + 6.0 * c[2] * y + 2.0 * c[3] * x;
    (*J_c) << x * r2, x * r2 * r2, 2.0 * x * y, r2 + 2.0 * x * x,  //
        y * r2, y * r2 * r2, r2 + 2.0 * y * y, 2.0 * x * y;
    return;
  }
  // Equidistant: d = s m with s = theta_d / r, theta = atan(r).
  if (r2 < 1e-16) {  // on the axis: s -> 1, ds/dm -> 0, dd/dk -> 0
    *d = m;
    J_m->setIdentity();
    J_c->setZero();
    return;
  }
  const double r = std::sqrt(r2);
  const double t = std::atan(r), t2 = t * t, t4 = t2 * t2, t6 = t4 * t2, t8 = t4 * t4;
  const double theta_d = t * (1.0 + c[0] * t2 + c[1] * t4 + c[2] * t6 + c[3] * t8);
  const double dtheta_d =
      1.0 + 3.0 * c[0] * t2 + 5.0 * c[1] * t4 + 7.0 * c[2] * t6 + 9.0 * c[3] * t8;
  const double s = theta_d / r;
  const double ds_dr = (dtheta_d / (1.0 + r2) * r - theta_d) / r2;
  *d = s * m;
  *J_m = s * Eigen::Matrix2d::Identity() + (ds_dr / r) * m * m.transpose();
  J_c->col(0) = (t * t2 / r) * m;
  J_c->col(1) = (t * t4 / r) * m;
  J_c->col(2) = (t * t6 / r) * m;
  J_c->col(3) = (t * t8 / r) * m;
}

}  // namespace

void projectWithJacobians(DistortionModel model, const double* k, const Eigen::Vector3d& p_C,
                          Eigen::Vector2d* uv, Eigen::Matrix<double, 2, 3>* J_point,
                          Eigen::Matrix<double, 2, 8>* J_intrinsics) {
  const double inv_z = 1.0 / p_C.z();
  const Eigen::Vector2d m(p_C.x() * inv_z, p_C.y() * inv_z);
  Eigen::Vector2d d;
  Eigen::Matrix2d J_m;
  Eigen::Matrix<double, 2, 4> J_c;
  distortWithJacobians(model, m, k + 4, &d, &J_m, &J_c);
  *uv = {k[0] * d.x() + k[2], k[1] * d.y() + k[3]};
  Eigen::Matrix<double, 2, 3> dm_dp;
  dm_dp << inv_z, 0.0, -m.x() * inv_z, 0.0, inv_z, -m.y() * inv_z;
  const Eigen::Vector2d f(k[0], k[1]);
  *J_point = f.asDiagonal() * J_m * dm_dp;
  J_intrinsics->setZero();
  (*J_intrinsics)(0, 0) = d.x();
  (*J_intrinsics)(1, 1) = d.y();
  (*J_intrinsics)(0, 2) = 1.0;
  (*J_intrinsics)(1, 3) = 1.0;
  J_intrinsics->rightCols<4>() = f.asDiagonal() * J_c;
}

}  // namespace mvis
