// Degenerate-motion machinery: the weak directions of a motion's information, the subspace
// manifold that holds them, and the marginalization that forgets them for projected residuals.
#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <map>
#include <random>

#include "factor_test_util.h"
#include "mvis/estimator/estimator.h"
#include "mvis/estimator/observability.h"
#include "mvis/estimator/window_information.h"
#include "mvis/factors/marginalization_factor.h"
#include "mvis/factors/state_blocks.h"
#include "mvis/factors/tangent_prior_factor.h"

namespace mvis {
namespace {

// A linear residual A_1 x_1 + ... + A_k x_k - b over k blocks (fixed matrices).
class LinearCost final : public ceres::CostFunction {
 public:
  LinearCost(std::vector<Eigen::MatrixXd> A, Eigen::VectorXd b)
      : A_(std::move(A)), b_(std::move(b)) {
    set_num_residuals(static_cast<int>(b_.size()));
    for (const auto& a : A_) mutable_parameter_block_sizes()->push_back(static_cast<int>(a.cols()));
  }
  bool Evaluate(double const* const* x, double* residuals, double** jacobians) const override {
    Eigen::Map<Eigen::VectorXd> r(residuals, b_.size());
    r = -b_;
    for (std::size_t i = 0; i < A_.size(); ++i) {
      r += A_[i] * Eigen::Map<const Eigen::VectorXd>(x[i], A_[i].cols());
      if (jacobians != nullptr && jacobians[i] != nullptr) {
        Eigen::Map<test::RowMatrix>(jacobians[i], A_[i].rows(), A_[i].cols()) = A_[i];
      }
    }
    return true;
  }

 private:
  std::vector<Eigen::MatrixXd> A_;
  Eigen::VectorXd b_;
};

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
  const LinearCost a({random(6, 2), random(6, 3)}, random(6, 1));  // on x1 (dropped), x2
  const LinearCost c({random(2, 2)}, random(2, 1));                // on x1
  const LinearCost e({random(4, 3)}, random(4, 1));                // on x2, the old prior
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

  // Without a kept variance (U unknown) and with one (U held within v = 0.04).
  std::map<double, Eigen::MatrixXd> alone;  // per v, the prior without the old one
  for (const double v : {0.0, 0.04})
    for (const bool with_old_prior : {false, true}) {
      Marginalizer m;
      m.setUninformative(x2, u, v > 0.0 ? Eigen::VectorXd::Constant(1, v) : Eigen::VectorXd());
      m.addResidual(&a, nullptr, {x1, x2}, true);
      m.addResidual(&c, nullptr, {x1}, true);
      if (with_old_prior) m.addResidual(&e, nullptr, {x2}, false);
      auto made = m.marginalize({x1});
      ASSERT_TRUE(made.ok()) << made.status().message();
      const MarginalizationFactor& prior = *made.value();
      const Eigen::MatrixXd H = prior.J0().transpose() * prior.J0();
      const Eigen::VectorXd g = prior.J0().transpose() * prior.r0();

      // Dense: forget U = [0; u] in the projected residuals (marginalized with the prior 1/v on
      // it, then what is left along it projected away), add the rest, Schur out x1.
      Eigen::MatrixXd Hp = Ja.transpose() * Ja + Jc.transpose() * Jc;
      Eigen::VectorXd gp = Ja.transpose() * ra + Jc.transpose() * rc;
      Eigen::VectorXd U = Eigen::VectorXd::Zero(5);
      U.tail(3) = u;
      const Eigen::VectorXd HpU = Hp * U;
      const double UHU = U.dot(HpU) + (v > 0.0 ? 1.0 / v : 0.0);
      Eigen::MatrixXd Hf = Hp - HpU * HpU.transpose() / UHU;
      Eigen::VectorXd gf = gp - HpU * U.dot(gp) / UHU;
      if (v > 0.0) {
        const Eigen::MatrixXd P = Eigen::MatrixXd::Identity(5, 5) - U * U.transpose();
        Hf = P * Hf * P;
        gf = P * gf;
      }
      if (with_old_prior) {
        Hf += Je.transpose() * Je;
        gf += Je.transpose() * re;
      }
      const Eigen::MatrixXd H11_inv = Hf.topLeftCorner(2, 2).inverse();
      const Eigen::MatrixXd Hs = Hf.bottomRightCorner(3, 3) -
                                 Hf.bottomLeftCorner(3, 2) * H11_inv * Hf.topRightCorner(2, 3);
      const Eigen::VectorXd gs = gf.tail(3) - Hf.bottomLeftCorner(3, 2) * H11_inv * gf.head(2);
      EXPECT_LT((H - Hs).norm(), 1e-8 * Hs.norm()) << with_old_prior << v;
      EXPECT_LT((g - gs).norm(), 1e-8 * (1.0 + gs.norm())) << with_old_prior << v;
      if (!with_old_prior) {
        // Nothing else informs u: the prior says nothing along it.
        EXPECT_LT((H * u).norm(), 1e-8 * H.norm());
        alone[v] = H;
      } else {
        EXPECT_GT((H * u).norm(), 1e-3 * H.norm());
      }
    }
  // Held within a variance, u keeps what the residuals tell about the rest given it: more than
  // with u unknown, never less.
  const Eigen::MatrixXd more = alone[0.04] - alone[0.0];
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(0.5 * (more + more.transpose()));
  EXPECT_GT(es.eigenvalues().minCoeff(), -1e-9 * alone[0.0].norm());
  EXPECT_GT(es.eigenvalues().maxCoeff(), 1e-3 * alone[0.0].norm());
}

// The window's information about chosen blocks against a dense Schur complement computed here:
// the other variable blocks marginalized, a constant block as known, the chosen blocks' priors
// (on them alone, one block or two) left out, a chosen block's manifold giving its tangent.
TEST(Observability, WindowInformationIsTheSchurComplementWithoutThePriors) {
  std::mt19937 rng(5);
  std::normal_distribution<double> n01;
  const auto random = [&](int r, int c) {
    Eigen::MatrixXd m(r, c);
    for (int i = 0; i < m.size(); ++i) m(i) = n01(rng);
    return m;
  };
  // Nuisance x1 (3), x2 (2), constant z (2); chosen c1 (3 ambient, entry 1 fixed by its
  // manifold: tangent 2) and c2 (1).
  double x1[3] = {0.1, 0.2, 0.3}, x2[2] = {0.0, 1.0}, z[2] = {2.0, -1.0};
  double c1[3] = {0.5, 0.5, 0.5}, c2[1] = {0.0};
  ceres::Problem::Options po;
  po.manifold_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  problem.AddParameterBlock(c1, 3, new ceres::SubsetManifold(3, {1}));
  const Eigen::MatrixXd A1 = random(6, 3), A2 = random(6, 2), Az = random(6, 2), Ac1 = random(6, 3),
                        B2 = random(4, 2), Bc2 = random(4, 1), P1 = random(3, 3),
                        Pc1 = random(3, 3), Pc12a = random(2, 3), Pc12b = random(2, 1);
  problem.AddResidualBlock(new LinearCost({A1, A2, Az, Ac1}, random(6, 1)), nullptr,
                           {x1, x2, z, c1});
  problem.AddResidualBlock(new LinearCost({B2, Bc2}, random(4, 1)), nullptr, {x2, c2});
  problem.AddResidualBlock(new LinearCost({P1}, random(3, 1)), nullptr, {x1});   // kept
  problem.AddResidualBlock(new LinearCost({Pc1}, random(3, 1)), nullptr, {c1});  // priors
  problem.AddResidualBlock(new LinearCost({Pc12a, Pc12b}, random(2, 1)), nullptr, {c1, c2});
  problem.SetParameterBlockConstant(z);

  const auto got = windowInformation(&problem, {c1, c2});
  ASSERT_TRUE(got.ok()) << got.status().message();
  // Columns [x1 (3), x2 (2), c1's tangent (entries 0 and 2), c2]; rows the kept residuals.
  Eigen::MatrixXd T1 = Eigen::MatrixXd::Zero(3, 2);
  T1(0, 0) = T1(2, 1) = 1.0;
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(13, 8);
  J.block(0, 0, 6, 3) = A1;
  J.block(0, 3, 6, 2) = A2;
  J.block(0, 5, 6, 2) = Ac1 * T1;
  J.block(6, 3, 4, 2) = B2;
  J.block(6, 7, 4, 1) = Bc2;
  J.block(10, 0, 3, 3) = P1;
  const Eigen::MatrixXd H = J.transpose() * J;
  const Eigen::MatrixXd expected = H.bottomRightCorner(3, 3) - H.bottomLeftCorner(3, 5) *
                                                                   H.topLeftCorner(5, 5).inverse() *
                                                                   H.topRightCorner(5, 3);
  ASSERT_EQ(got.value().rows(), 3);
  EXPECT_LT((got.value() - expected).norm(), 1e-8 * expected.norm()) << got.value() << "\n"
                                                                     << expected;
  // A constant chosen block is refused.
  problem.SetParameterBlockConstant(c2);
  EXPECT_FALSE(windowInformation(&problem, {c1, c2}).ok());
}

// A direction shared between sensors is named with every sensor's part.
TEST(Observability, SharedDirectionInWords) {
  UnobservableCalibration u;
  u.sensor = "imu0+cam0";
  u.quantity = "shared direction";
  u.shared = {"imu0 intrinsics (theta_x)", "cam0 rotation about (1.00, 0.00, 0.00)"};
  u.advice = "rotate about another axis too";
  EXPECT_EQ(u.text(),
            "shared direction of imu0 intrinsics (theta_x), cam0 rotation about (1.00, 0.00, "
            "0.00): rotate about another axis too");
}

}  // namespace
}  // namespace mvis
