#include "mvis/factors/tag_landmark_manifold.h"

#include <Eigen/Core>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>

#include "mvis/common/lie.h"

namespace mvis {
namespace {

using Vector12 = Eigen::Matrix<double, 12, 1>;

// The square's frame (header): rotation, centre, side.
struct Square {
  Eigen::Matrix3d R;
  Eigen::Vector3d c;
  double s = 0.0;
};

Square squareOf(const double* x) {
  const Eigen::Map<const Vector12> p(x);
  Square out;
  out.c = 0.25 * (p.segment<3>(0) + p.segment<3>(3) + p.segment<3>(6) + p.segment<3>(9));
  const Eigen::Vector3d a = p.segment<3>(3) - p.segment<3>(0);
  const Eigen::Vector3d b = p.segment<3>(9) - p.segment<3>(0);
  out.s = a.norm();
  const Eigen::Vector3d ex = a / out.s;
  const Eigen::Vector3d ey = (b - ex.dot(b) * ex).normalized();
  out.R.col(0) = ex;
  out.R.col(1) = ey;
  out.R.col(2) = ex.cross(ey);
  return out;
}

// q_k of the header: the unit square about its centre, in tagCorner's order.
Eigen::Vector3d unitCorner(int k) {
  return Eigen::Vector3d(k == 1 || k == 2 ? 0.5 : -0.5, k >= 2 ? 0.5 : -0.5, 0.0);
}

Eigen::Matrix<double, 12, 7> plusJacobian(const Square& sq) {
  Eigen::Matrix<double, 12, 7> J;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector3d q = unitCorner(k);
    J.block<3, 3>(3 * k, 0) = -sq.s * sq.R * lie::hat(q);
    J.block<3, 3>(3 * k, 3).setIdentity();
    J.block<3, 1>(3 * k, 6) = sq.R * q;
  }
  return J;
}

}  // namespace

bool TagLandmarkManifold::Plus(const double* x, const double* delta, double* x_plus_delta) const {
  const Square sq = squareOf(x);
  if (!(sq.s > 0.0)) return false;
  const Eigen::Map<const Eigen::Matrix<double, 7, 1>> d(delta);
  const Eigen::Matrix3d R = sq.R * lie::expSO3(d.head<3>());
  const Eigen::Vector3d c = sq.c + d.segment<3>(3);
  // A step that would turn the square inside out (Ceres also tries Plus(x, -gradient), far
  // from x) leaves it a point-sized square instead.
  const double s = std::max(sq.s + d[6], 1e-9);
  for (int k = 0; k < 4; ++k) {
    Eigen::Map<Eigen::Vector3d>(x_plus_delta + 3 * k) = c + s * R * unitCorner(k);
  }
  return true;
}

bool TagLandmarkManifold::PlusJacobian(const double* x, double* jacobian) const {
  const Square sq = squareOf(x);
  if (!(sq.s > 0.0)) return false;
  Eigen::Map<Eigen::Matrix<double, 12, 7, Eigen::RowMajor>> out(jacobian);
  out = plusJacobian(sq);
  return true;
}

bool TagLandmarkManifold::Minus(const double* y, const double* x, double* y_minus_x) const {
  const Square a = squareOf(x), b = squareOf(y);
  if (!(a.s > 0.0) || !(b.s > 0.0)) return false;
  Eigen::Map<Eigen::Matrix<double, 7, 1>> d(y_minus_x);
  d.head<3>() = lie::logSO3(a.R.transpose() * b.R);
  d.segment<3>(3) = b.c - a.c;
  d[6] = b.s - a.s;
  return true;
}

bool TagLandmarkManifold::MinusJacobian(const double* x, double* jacobian) const {
  const Square sq = squareOf(x);
  if (!(sq.s > 0.0)) return false;
  const Eigen::Matrix<double, 12, 7> J = plusJacobian(sq);
  const Eigen::Matrix<double, 7, 7> JtJ = J.transpose() * J;
  Eigen::Map<Eigen::Matrix<double, 7, 12, Eigen::RowMajor>> out(jacobian);
  out = JtJ.inverse() * J.transpose();
  return true;
}

}  // namespace mvis
