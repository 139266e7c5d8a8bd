// Degenerate-motion machinery: the weak directions of a motion's information, the subspace
// manifold that holds them, and the marginalization that forgets them for projected residuals.
#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include <random>

#include "factor_test_util.h"
#include "mvis/estimator/observability.h"
#include "mvis/factors/state_blocks.h"
#include "mvis/factors/marginalization_factor.h"
#include "mvis/factors/tangent_prior_factor.h"

namespace mvis {
namespace {

// Rotation about one axis k: int hat(w)^T hat(w) has k as its null space (report Table 2).
TEST(Observability, OneAxisRotationLeavesTheAxis) {
  const Eigen::Vector3d k = Eigen::Vector3d(1.0, 2.0, -0.5).normalized();
  Eigen::Matrix3d I = Eigen::Matrix3d::Zero();
  for (int i = 0; i < 100; ++i) {
    const Eigen::Vector3d w = std::sin(0.1 * i) * 2.0 * k;
    I += 0.01 * lie::hat(w).transpose() * lie::hat(w) / (1e-3 * 1e-3);
  }
  const Eigen::Vector3d prior_std(0.1, 0.1, 0.05);
  const Eigen::Matrix3d W = prior_std.asDiagonal() * I * prior_std.asDiagonal();
  const WeakDirections weak = weakDirections(W, prior_std, 500.0);
  ASSERT_EQ(weak.directions.cols(), 1);
  EXPECT_GT(std::abs(weak.directions.col(0).dot(k)), 1.0 - 1e-9);
  EXPECT_NEAR(weak.gains[0], 0.0, 1e-6);
  // Rotation about every axis: nothing is weak.
  Eigen::Matrix3d full = I;
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d w = Eigen::Vector3d::Unit(i);
    full += lie::hat(w).transpose() * lie::hat(w) / (1e-3 * 1e-3);
  }
  const Eigen::Matrix3d Wf = prior_std.asDiagonal() * full * prior_std.asDiagonal();
  EXPECT_EQ(weakDirections(Wf, prior_std, 500.0).directions.cols(), 0);
}

TEST(Observability, SubspaceManifoldMovesOnlyAlongItsBasis) {
  PoseManifold pose;
  // Rotations free, translations only in the plane orthogonal to R z (R z held).
  const Eigen::Matrix3d R = lie::expQuat(Eigen::Vector3d(0.2, -0.1, 0.3)).toRotationMatrix();
  Eigen::MatrixXd B = Eigen::MatrixXd::Identity(6, 5);
  B.block<3, 2>(3, 3) = R.leftCols(2);
  const SubspaceManifold m(&pose, 7, B);
  ASSERT_EQ(m.TangentSize(), 5);
  double x[7];
  se3ToPose(SE3(lie::expQuat(Eigen::Vector3d(0.3, 0.1, -0.2)), Eigen::Vector3d(1, 2, 3)), x);
  const double delta[5] = {0.01, -0.02, 0.03, 0.4, -0.5};
  double y[7];
  ASSERT_TRUE(m.Plus(x, delta, y));
  // Nothing moved along the held direction R z.
  EXPECT_NEAR((posePosition(y) - posePosition(x)).dot(R.col(2)), 0.0, 1e-12);
  double back[5];
  ASSERT_TRUE(m.Minus(y, x, back));
  for (int i = 0; i < 5; ++i) EXPECT_NEAR(back[i], delta[i], 1e-9);
  test::RowMatrix J(7, 5);
  ASSERT_TRUE(m.PlusJacobian(x, J.data()));
  EXPECT_LT((J.topRows(6) - Eigen::MatrixXd(B)).norm(), 1e-12);
  EXPECT_LT(J.row(6).norm(), 1e-12);
}

// r = A1 x1 + A2 x2 - z.
class LinearCost final : public ceres::CostFunction {
 public:
  LinearCost(Eigen::MatrixXd A1, Eigen::MatrixXd A2, Eigen::VectorXd z)
      : A1_(std::move(A1)), A2_(std::move(A2)), z_(std::move(z)) {
    set_num_residuals(static_cast<int>(z_.size()));
    mutable_parameter_block_sizes()->push_back(static_cast<int>(A1_.cols()));
    if (A2_.size() > 0) mutable_parameter_block_sizes()->push_back(static_cast<int>(A2_.cols()));
  }
  bool Evaluate(double const* const* x, double* residuals, double** jacobians) const override {
    Eigen::VectorXd r = A1_ * Eigen::Map<const Eigen::VectorXd>(x[0], A1_.cols()) - z_;
    if (A2_.size() > 0) r += A2_ * Eigen::Map<const Eigen::VectorXd>(x[1], A2_.cols());
    Eigen::Map<Eigen::VectorXd>(residuals, r.size()) = r;
    if (jacobians != nullptr) {
      if (jacobians[0] != nullptr) {
        Eigen::Map<test::RowMatrix>(jacobians[0], A1_.rows(), A1_.cols()) = A1_;
      }
      if (A2_.size() > 0 && jacobians[1] != nullptr) {
        Eigen::Map<test::RowMatrix>(jacobians[1], A2_.rows(), A2_.cols()) = A2_;
      }
    }
    return true;
  }

 private:
  Eigen::MatrixXd A1_, A2_;
  Eigen::VectorXd z_;
};

// A projected residual's information along an uninformative direction u of a kept block is
// marginalized out before the dropped block is: the prior equals that dense computation, and
// u is in its null space when nothing else informs it; an unprojected residual is unchanged.
// The prior on held directions (used while computing covariances): its value is the scaled
// tangent difference along them, its Jacobians at the mean match central differences through
// the pose manifold, and its information there is D diag(1/s^2) D^T in the tangent.
TEST(TangentPriorFactor, ValueAndJacobiansThroughTheManifold) {
  const PoseManifold pose;
  std::vector<double> x0(7), x(7);
  se3ToPose(SE3(lie::expQuat(Eigen::Vector3d(0.3, -0.1, 0.2)), Eigen::Vector3d(0.1, 0.2, 0.3)),
            x0.data());
  Eigen::Matrix<double, 6, 1> delta;
  delta << 0.01, -0.02, 0.005, 0.003, -0.001, 0.002;
  pose.Plus(x0.data(), delta.data(), x.data());
  Eigen::MatrixXd D = Eigen::MatrixXd::Zero(6, 2);
  D(5, 0) = 1.0;                       // translation z
  D(0, 1) = D(1, 1) = std::sqrt(0.5);  // rotation about (1, 1, 0)
  const Eigen::Vector2d s(0.1, 0.05);
  TangentPriorFactor f(&pose, x0, D, s);
  const Eigen::VectorXd r = test::evaluateResiduals(f, {x});
  EXPECT_NEAR(r[0], delta[5] / 0.1, 1e-12);
  EXPECT_NEAR(r[1], (delta[0] + delta[1]) * std::sqrt(0.5) / 0.05, 1e-12);
  // First-estimate Jacobians: exact at the prior's mean, where the estimator evaluates them.
  EXPECT_LT(test::jacobianMismatch(test::analyticTangentJacobians(f, {x0}, {&pose}),
                                   test::numericTangentJacobians(f, {x0}, {&pose}, 1e-6)),
            1e-6);
  const Eigen::MatrixXd J = test::analyticTangentJacobians(f, {x0}, {&pose})[0];
  const Eigen::MatrixXd info = D * s.cwiseInverse().cwiseAbs2().asDiagonal() * D.transpose();
  EXPECT_LT((J.transpose() * J - info).norm(), 1e-9 * info.norm());
}

TEST(Marginalization, ProjectedResidualsForgetUninformativeDirections) {
  std::mt19937 rng(11);
  std::normal_distribution<double> n(0.0, 1.0);
  auto random = [&](int r, int c) {
    Eigen::MatrixXd m(r, c);
    for (int i = 0; i < r; ++i)
      for (int j = 0; j < c; ++j) m(i, j) = n(rng);
    return m;
  };
  const LinearCost a(random(6, 2), random(6, 3), random(6, 1));       // on x1 (dropped), x2
  const LinearCost c(random(2, 2), Eigen::MatrixXd(), random(2, 1));  // on x1
  const LinearCost e(random(4, 3), Eigen::MatrixXd(), random(4, 1));  // on x2, the old prior
  double x1[2] = {0.2, -0.3}, x2[3] = {0.5, 1.0, -1.5};
  const Eigen::Vector3d u = Eigen::Vector3d(1.0, -2.0, 0.5).normalized();

  auto linear = [&](const LinearCost& cost, std::vector<double*> blocks, Eigen::MatrixXd* J,
                    Eigen::VectorXd* r) {
    // Columns: x1 (2), x2 (3).
    const int rows = cost.num_residuals();
    std::vector<test::RowMatrix> jac;
    std::vector<double*> ptr;
    for (int size : cost.parameter_block_sizes()) jac.emplace_back(rows, size);
    for (auto& j : jac) ptr.push_back(j.data());
    r->resize(rows);
    std::vector<const double*> p(blocks.begin(), blocks.end());
    ASSERT_TRUE(cost.Evaluate(p.data(), r->data(), ptr.data()));
    *J = Eigen::MatrixXd::Zero(rows, 5);
    for (std::size_t b = 0; b < blocks.size(); ++b) {
      J->middleCols(blocks[b] == x1 ? 0 : 2, jac[b].cols()) = jac[b];
    }
  };
  Eigen::MatrixXd Ja, Jc, Je;
  Eigen::VectorXd ra, rc, re;
  linear(a, {x1, x2}, &Ja, &ra);
  linear(c, {x1}, &Jc, &rc);
  linear(e, {x2}, &Je, &re);

  for (const bool with_old_prior : {false, true}) {
    Marginalizer m;
    m.setUninformative(x2, u);
    m.addResidual(&a, nullptr, {x1, x2}, true);
    m.addResidual(&c, nullptr, {x1}, true);
    if (with_old_prior) m.addResidual(&e, nullptr, {x2}, false);
    auto made = m.marginalize({x1});
    ASSERT_TRUE(made.ok()) << made.status().message();
    const MarginalizationFactor& prior = *made.value();
    const Eigen::MatrixXd H = prior.J0().transpose() * prior.J0();
    const Eigen::VectorXd g = prior.J0().transpose() * prior.r0();

    // Dense: forget U = [0; u] in the projected residuals, add the rest, Schur out x1.
    Eigen::MatrixXd Hp = Ja.transpose() * Ja + Jc.transpose() * Jc;
    Eigen::VectorXd gp = Ja.transpose() * ra + Jc.transpose() * rc;
    Eigen::VectorXd U = Eigen::VectorXd::Zero(5);
    U.tail(3) = u;
    const Eigen::VectorXd HpU = Hp * U;
    const double UHU = U.dot(HpU);
    Eigen::MatrixXd Hf = Hp - HpU * HpU.transpose() / UHU;
    Eigen::VectorXd gf = gp - HpU * U.dot(gp) / UHU;
    if (with_old_prior) {
      Hf += Je.transpose() * Je;
      gf += Je.transpose() * re;
    }
    const Eigen::MatrixXd H11_inv = Hf.topLeftCorner(2, 2).inverse();
    const Eigen::MatrixXd Hs =
        Hf.bottomRightCorner(3, 3) - Hf.bottomLeftCorner(3, 2) * H11_inv * Hf.topRightCorner(2, 3);
    const Eigen::VectorXd gs = gf.tail(3) - Hf.bottomLeftCorner(3, 2) * H11_inv * gf.head(2);
    EXPECT_LT((H - Hs).norm(), 1e-8 * Hs.norm()) << with_old_prior;
    EXPECT_LT((g - gs).norm(), 1e-8 * (1.0 + gs.norm())) << with_old_prior;
    if (!with_old_prior) {
      // Nothing else informs u: the prior says nothing along it.
      EXPECT_LT((H * u).norm(), 1e-8 * H.norm());
    } else {
      EXPECT_GT((H * u).norm(), 1e-3 * H.norm());
    }
  }
}

}  // namespace
}  // namespace mvis
