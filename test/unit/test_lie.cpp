// SO(3)/SE(3) toolbox against closed forms and central differences.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "mvis/common/lie.h"

namespace mvis {
namespace {

// Central differences with step h have truncation error O(h^2) ~ 1e-12 and round-off
// ~ 1e-16 / h ~ 1e-10 on quantities of order one, so 1e-7 leaves a wide margin yet catches
// any wrong term (those are of order |phi| ~ 0.1 or larger).
constexpr double kStep = 1e-6;
constexpr double kJacobianTol = 1e-7;

Eigen::Vector3d randomRotationVector(std::mt19937& rng, double max_angle) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::Vector3d axis(u(rng), u(rng), u(rng));
  axis.normalize();
  return axis * max_angle * std::abs(u(rng));
}

Vector6d randomTwist(std::mt19937& rng, double max_angle) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Vector6d xi;
  xi.head<3>() = randomRotationVector(rng, max_angle);
  xi.tail<3>() << u(rng), u(rng), u(rng);
  return xi;
}

TEST(Lie, HatVee) {
  const Eigen::Vector3d w(0.1, -0.2, 0.3), v(-1.0, 2.0, 0.5);
  EXPECT_TRUE((lie::hat(w) * v).isApprox(w.cross(v), 1e-15));
  EXPECT_TRUE(lie::vee(lie::hat(w)).isApprox(w));
}

TEST(Lie, ExpLogRoundTripAcrossAngles) {
  std::mt19937 rng(7);
  for (double angle : {0.0, 1e-12, 1e-7, 1e-4, 0.3, 1.5, 3.0, M_PI - 1e-6}) {
    for (int trial = 0; trial < 20; ++trial) {
      Eigen::Vector3d phi = randomRotationVector(rng, 1.0).normalized() * angle;
      if (angle == 0.0) phi.setZero();
      const Eigen::Vector3d back = lie::logSO3(lie::expSO3(phi));
      EXPECT_LT((back - phi).norm(), 1e-9 * std::max(1.0, angle)) << "angle " << angle;
      EXPECT_LT((lie::logQuat(lie::expQuat(phi)) - phi).norm(), 1e-9) << "angle " << angle;
      EXPECT_TRUE(lie::expQuat(phi).toRotationMatrix().isApprox(lie::expSO3(phi), 1e-12));
    }
  }
}

TEST(Lie, ExpIsRotationAboutAxis) {
  const Eigen::Matrix3d R = lie::expSO3(Eigen::Vector3d(0.0, 0.0, M_PI / 2));
  EXPECT_TRUE((R * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY(), 1e-12));
}

TEST(Lie, RightJacobianSO3MatchesNumeric) {
  std::mt19937 rng(11);
  for (double max_angle : {1e-6, 0.5, 2.5}) {
    for (int trial = 0; trial < 10; ++trial) {
      const Eigen::Vector3d phi = randomRotationVector(rng, max_angle);
      const Eigen::Matrix3d R_inv = lie::expSO3(phi).transpose();
      Eigen::Matrix3d numeric;
      for (int i = 0; i < 3; ++i) {
        const Eigen::Vector3d d = Eigen::Vector3d::Unit(i) * kStep;
        numeric.col(i) = (lie::logSO3(R_inv * lie::expSO3(phi + d)) -
                          lie::logSO3(R_inv * lie::expSO3(phi - d))) /
                         (2 * kStep);
      }
      EXPECT_LT((numeric - lie::rightJacobianSO3(phi)).cwiseAbs().maxCoeff(), kJacobianTol);
      EXPECT_LT(
          (lie::rightJacobianInvSO3(phi) * lie::rightJacobianSO3(phi) - Eigen::Matrix3d::Identity())
              .cwiseAbs()
              .maxCoeff(),
          1e-12);
      EXPECT_LT(
          (lie::leftJacobianInvSO3(phi) * lie::leftJacobianSO3(phi) - Eigen::Matrix3d::Identity())
              .cwiseAbs()
              .maxCoeff(),
          1e-12);
    }
  }
}

TEST(Lie, LeftJacobianSO3MatchesNumeric) {
  std::mt19937 rng(12);
  const Eigen::Vector3d phi = randomRotationVector(rng, 1.2);
  const Eigen::Matrix3d R_inv = lie::expSO3(phi).transpose();
  Eigen::Matrix3d numeric;
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d d = Eigen::Vector3d::Unit(i) * kStep;
    numeric.col(i) =
        (lie::logSO3(lie::expSO3(phi + d) * R_inv) - lie::logSO3(lie::expSO3(phi - d) * R_inv)) /
        (2 * kStep);
  }
  EXPECT_LT((numeric - lie::leftJacobianSO3(phi)).cwiseAbs().maxCoeff(), kJacobianTol);
}

TEST(Lie, SE3ExpLogRoundTrip) {
  std::mt19937 rng(13);
  for (double max_angle : {0.0, 1e-8, 0.7, 3.0}) {
    for (int trial = 0; trial < 10; ++trial) {
      const Vector6d xi = randomTwist(rng, max_angle);
      const Vector6d back = lie::logSE3(lie::expSE3(xi));
      EXPECT_LT((back - xi).norm(), 1e-9) << xi.transpose();
    }
  }
}

TEST(Lie, SE3JacobiansMatchNumeric) {
  std::mt19937 rng(17);
  for (double max_angle : {1e-6, 0.4, 2.0}) {
    for (int trial = 0; trial < 8; ++trial) {
      const Vector6d xi = randomTwist(rng, max_angle);
      const SE3 T_inv = lie::expSE3(xi).inverse();
      Matrix6d right, left;
      for (int i = 0; i < 6; ++i) {
        const Vector6d d = Vector6d::Unit(i) * kStep;
        right.col(i) =
            (lie::logSE3(T_inv * lie::expSE3(xi + d)) - lie::logSE3(T_inv * lie::expSE3(xi - d))) /
            (2 * kStep);
        left.col(i) =
            (lie::logSE3(lie::expSE3(xi + d) * T_inv) - lie::logSE3(lie::expSE3(xi - d) * T_inv)) /
            (2 * kStep);
      }
      EXPECT_LT((right - lie::rightJacobianSE3(xi)).cwiseAbs().maxCoeff(), kJacobianTol)
          << "xi " << xi.transpose();
      EXPECT_LT((left - lie::leftJacobianSE3(xi)).cwiseAbs().maxCoeff(), kJacobianTol)
          << "xi " << xi.transpose();
      EXPECT_LT((lie::rightJacobianInvSE3(xi) * lie::rightJacobianSE3(xi) - Matrix6d::Identity())
                    .cwiseAbs()
                    .maxCoeff(),
                1e-12);
    }
  }
}

TEST(Lie, SE3ComposeInverseAndMatrix) {
  std::mt19937 rng(19);
  const SE3 A = lie::expSE3(randomTwist(rng, 2.0));
  const SE3 B = lie::expSE3(randomTwist(rng, 2.0));
  const Eigen::Vector3d x(0.3, -1.2, 2.0);
  EXPECT_TRUE(((A * B) * x).isApprox(A * (B * x), 1e-12));
  EXPECT_TRUE((A.inverse() * (A * x)).isApprox(x, 1e-12));
  EXPECT_TRUE((A.matrix() * B.matrix()).isApprox((A * B).matrix(), 1e-12));
  EXPECT_TRUE(SE3::fromMatrix(A.matrix()).matrix().isApprox(A.matrix(), 1e-14));
}

TEST(Lie, InterpolationFollowsTheReport) {
  const SE3 T0(lie::expQuat(Eigen::Vector3d(0.0, 0.0, 0.2)), Eigen::Vector3d(1.0, 2.0, 3.0));
  const SE3 T1(lie::expQuat(Eigen::Vector3d(0.0, 0.0, 1.0)), Eigen::Vector3d(3.0, 2.0, -1.0));
  const SE3 a = lie::interpolatePose(T0, T1, 0.0);
  const SE3 b = lie::interpolatePose(T0, T1, 1.0);
  EXPECT_TRUE(a.matrix().isApprox(T0.matrix(), 1e-12));
  EXPECT_TRUE(b.matrix().isApprox(T1.matrix(), 1e-12));
  // A quarter of the way: yaw 0.2 + 0.25 * 0.8 = 0.4, position linear.
  const SE3 m = lie::interpolatePose(T0, T1, 0.25);
  EXPECT_NEAR(lie::logQuat(m.q).z(), 0.4, 1e-12);
  EXPECT_NEAR(lie::logQuat(m.q).head<2>().norm(), 0.0, 1e-12);
  EXPECT_TRUE(m.p.isApprox(Eigen::Vector3d(1.5, 2.0, 2.0), 1e-12));
  // Extrapolation continues the geodesic.
  EXPECT_NEAR(lie::logQuat(lie::interpolateSO3(T0.q, T1.q, 1.5)).z(), 1.4, 1e-12);
}

TEST(Lie, NearestRotationProjects) {
  const Eigen::Matrix3d R = lie::expSO3(Eigen::Vector3d(0.3, -0.2, 0.1));
  Eigen::Matrix3d noisy = R;
  noisy(0, 1) += 1e-7;
  const Eigen::Matrix3d fixed = lie::nearestRotation(noisy);
  EXPECT_LT((fixed.transpose() * fixed - Eigen::Matrix3d::Identity()).norm(), 1e-14);
  EXPECT_NEAR(fixed.determinant(), 1.0, 1e-14);
  EXPECT_LT((fixed - R).norm(), 1e-7);
}

}  // namespace
}  // namespace mvis
