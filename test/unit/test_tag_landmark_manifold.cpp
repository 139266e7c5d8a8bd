// TagLandmarkManifold: a tag's four corners kept a square. Plus moves a square to a square (its
// rotation, centre and size only), PlusJacobian is Plus's derivative (central differences),
// Minus undoes Plus and MinusJacobian is PlusJacobian's left inverse.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "mvis/factors/tag_landmark_manifold.h"
#include "mvis/rig/rig.h"

namespace mvis {
namespace {

using Vector12 = Eigen::Matrix<double, 12, 1>;
using Vector7 = Eigen::Matrix<double, 7, 1>;

// A 0.088 m tag at a pose, corners as tagCorner has them.
Vector12 square() {
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.3, -0.5, 0.8).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(0.4, -1.2, 0.9);
  Vector12 x;
  for (int k = 0; k < 4; ++k) x.segment<3>(3 * k) = R * tagCorner(k, 0.088) + t;
  return x;
}

// Side lengths, diagonals and the out-of-plane distance of the fourth corner: a square's sides
// are equal, its diagonals sqrt(2) times them, and it is flat.
void expectSquare(const Vector12& x, double side) {
  auto p = [&](int k) { return Eigen::Vector3d(x.segment<3>(3 * k)); };
  for (int k = 0; k < 4; ++k) EXPECT_NEAR((p((k + 1) % 4) - p(k)).norm(), side, 1e-12);
  EXPECT_NEAR((p(2) - p(0)).norm(), std::sqrt(2.0) * side, 1e-12);
  EXPECT_NEAR((p(3) - p(1)).norm(), std::sqrt(2.0) * side, 1e-12);
  const Eigen::Vector3d n = (p(1) - p(0)).cross(p(3) - p(0)).normalized();
  EXPECT_NEAR(n.dot(p(2) - p(0)), 0.0, 1e-12);
}

TEST(TagLandmarkManifold, PlusKeepsASquareAndMinusUndoesIt) {
  const TagLandmarkManifold m;
  const Vector12 x = square();
  Vector7 d;
  d << 0.02, -0.03, 0.05, 0.01, 0.002, -0.004, 0.1;
  Vector12 y;
  ASSERT_TRUE(m.Plus(x.data(), d.data(), y.data()));
  expectSquare(y, 0.088 + 0.1);
  Vector7 back;
  ASSERT_TRUE(m.Minus(y.data(), x.data(), back.data()));
  EXPECT_LT((back - d).norm(), 1e-12);
  const Vector7 zero = Vector7::Zero();
  Vector12 same;
  ASSERT_TRUE(m.Plus(x.data(), zero.data(), same.data()));
  EXPECT_LT((same - x).norm(), 1e-15);
}

TEST(TagLandmarkManifold, JacobiansMatchCentralDifferencesAndInvert) {
  const TagLandmarkManifold m;
  const Vector12 x = square();
  Eigen::Matrix<double, 12, 7, Eigen::RowMajor> P;
  ASSERT_TRUE(m.PlusJacobian(x.data(), P.data()));
  const double h = 1e-6;
  for (int j = 0; j < 7; ++j) {
    Vector7 d = Vector7::Zero();
    Vector12 up, down;
    d[j] = h;
    ASSERT_TRUE(m.Plus(x.data(), d.data(), up.data()));
    d[j] = -h;
    ASSERT_TRUE(m.Plus(x.data(), d.data(), down.data()));
    // Central differences err by O(h^2) times Plus's third derivative (sizes ~0.1 m): ~1e-13.
    EXPECT_LT(((up - down) / (2 * h) - P.col(j)).cwiseAbs().maxCoeff(), 1e-8) << j;
  }
  Eigen::Matrix<double, 7, 12, Eigen::RowMajor> M;
  ASSERT_TRUE(m.MinusJacobian(x.data(), M.data()));
  EXPECT_LT((M * P - Eigen::Matrix<double, 7, 7>::Identity()).cwiseAbs().maxCoeff(), 1e-12);
  // And the derivative of Minus(y, x) in y at y = x, on a move within the squares.
  Vector7 d;
  d << 1e-7, -2e-7, 3e-7, 1e-7, 2e-7, -1e-7, 2e-7;
  Vector12 y;
  ASSERT_TRUE(m.Plus(x.data(), d.data(), y.data()));
  EXPECT_LT((M * (y - x) - d).cwiseAbs().maxCoeff(), 1e-12);
}

}  // namespace
}  // namespace mvis
