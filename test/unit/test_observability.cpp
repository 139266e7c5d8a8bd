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

    // Dense: forget U = [0; u] in the projected residuals (marginalized as unknown), add the
    // rest, Schur out x1.
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

// consideredCovariance against the error of the estimate it describes, derived independently:
// a linear Gaussian model, y = (x in R^3, u in R^2). Truth y ~ N(0, P); a first measurement z0 =
// A0 y + n0 gives the estimate m0 (information L0 = P^-1 + A0^T A0), whose u part is held: u_h =
// m0_u with V = (L0^-1)_uu. A second z1 = A1 y + n1 then updates x alone, as the window does
// with the prior (m0, L0) and u constant: x_hat minimizes (y - m0)^T L0 (y - m0) + |z1 - A1 y|^2
// with u = u_h. Every quantity is linear in w = (y, n0, n1) ~ N(0, blkdiag(P, I, I)), so the
// error e = (x_hat - x, u_h - u) = M w has the covariance M Cov(w) M^T exactly. The function gets
// only Sigma = (L0 + A1^T A1)^-1 (the information with u free), U and V. The conditional
// covariance alone (u as known) must be far off for the test to mean anything.
TEST(Observability, ConsideredCovarianceIsTheHeldEstimatesErrorCovariance) {
  std::mt19937 rng(7);
  std::normal_distribution<double> g;
  const auto random = [&](int r, int c) {
    Eigen::MatrixXd m(r, c);
    for (int i = 0; i < r; ++i) {
      for (int j = 0; j < c; ++j) m(i, j) = g(rng);
    }
    return m;
  };
  const int nx = 3, nu = 2, n = nx + nu, m0 = 6, m1 = 7;
  const Eigen::MatrixXd R = random(n, n);
  const Eigen::MatrixXd P = R * R.transpose() + Eigen::MatrixXd::Identity(n, n);
  const Eigen::MatrixXd A0 = random(m0, n), A1 = random(m1, n);
  const Eigen::MatrixXd L0 = P.inverse() + A0.transpose() * A0;
  const Eigen::MatrixXd K0 = L0.inverse() * A0.transpose();  // m0 = K0 z0
  const Eigen::MatrixXd V = L0.inverse().bottomRightCorner(nu, nu);
  // x_hat = H^-1 (L0_xx m0_x - L0_xu (u_h - m0_u) + A1x^T (z1 - A1u u_h)), u_h - m0_u = 0.
  const Eigen::MatrixXd H =
      L0.topLeftCorner(nx, nx) + A1.leftCols(nx).transpose() * A1.leftCols(nx);
  const Eigen::MatrixXd Hinv = H.inverse();
  const Eigen::MatrixXd uh_of_z0 = K0.bottomRows(nu);
  const Eigen::MatrixXd xh_of_z0 =
      Hinv * (L0.topLeftCorner(nx, nx) * K0.topRows(nx) -
              A1.leftCols(nx).transpose() * A1.rightCols(nu) * uh_of_z0);
  const Eigen::MatrixXd xh_of_z1 = Hinv * A1.leftCols(nx).transpose();
  // e = M w, w = (y, n0, n1); z0 = A0 y + n0, z1 = A1 y + n1.
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n, n + m0 + m1);
  M.topLeftCorner(nx, n) = xh_of_z0 * A0 + xh_of_z1 * A1;
  M.topLeftCorner(nx, nx) -= Eigen::MatrixXd::Identity(nx, nx);
  M.block(0, n, nx, m0) = xh_of_z0;
  M.block(0, n + m0, nx, m1) = xh_of_z1;
  M.bottomLeftCorner(nu, n) = uh_of_z0 * A0;
  M.block(nx, nx, nu, nu) -= Eigen::MatrixXd::Identity(nu, nu);
  M.block(nx, n, nu, m0) = uh_of_z0;
  Eigen::MatrixXd W = Eigen::MatrixXd::Identity(n + m0 + m1, n + m0 + m1);
  W.topLeftCorner(n, n) = P;
  const Eigen::MatrixXd truth = M * W * M.transpose();

  const Eigen::MatrixXd sigma = (L0 + A1.transpose() * A1).inverse();
  // U: u's coordinates, turned to V's eigenvectors (a hold keeps its variance per direction).
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(V);
  Eigen::MatrixXd U = Eigen::MatrixXd::Zero(n, nu);
  U.bottomRows(nu) = eig.eigenvectors();
  const Eigen::MatrixXd got = consideredCovariance(sigma, U, eig.eigenvalues());
  EXPECT_LT((got - truth).norm(), 1e-9 * truth.norm()) << got << "\n\n" << truth;
  // u keeps its variance when held.
  EXPECT_LT((got.bottomRightCorner(nu, nu) - V).norm(), 1e-9 * V.norm());
  // As known (conditioned on u): the x block misses a large share.
  const Eigen::MatrixXd conditional = H.inverse();
  EXPECT_GT((conditional - truth.topLeftCorner(nx, nx)).norm(),
            0.1 * truth.topLeftCorner(nx, nx).norm());
  // With u free, Sigma itself: not it either.
  EXPECT_GT((sigma - truth).norm(), 0.1 * truth.norm());
}

}  // namespace
}  // namespace mvis
