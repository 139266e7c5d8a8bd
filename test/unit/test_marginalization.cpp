// Marginalization prior: exact on a linear problem (the reduced problem has the full problem's
// solution), equal to a dense Schur complement on a small nonlinear problem with manifolds (also
// with blocks eliminated alone, and semi-definite, and through the pseudo-inverse when the
// dropped blocks' information is singular), and a correct linear model when evaluated away from
// its linearization point; its Cholesky form splits into row groups with the same cost.
#include <ceres/ceres.h>
#include <ceres/normal_prior.h>
#include <ceres/sphere_manifold.h>
#include <gtest/gtest.h>

#include <random>

#include "factor_test_util.h"
#include "mvis/inertial/imu_preintegration.h"
#include "mvis/factors/state_blocks.h"
#include "mvis/factors/imu_factor.h"
#include "mvis/factors/marginalization_factor.h"
#include "mvis/factors/pose_prior_factor.h"

namespace mvis {
namespace {

// r = sum_b A_b x_b - z over Euclidean blocks.
class LinearCost final : public ceres::CostFunction {
 public:
  LinearCost(std::vector<Eigen::MatrixXd> A, Eigen::VectorXd z) : A_(std::move(A)), z_(z) {
    set_num_residuals(static_cast<int>(z_.size()));
    for (const auto& a : A_) mutable_parameter_block_sizes()->push_back(static_cast<int>(a.cols()));
  }
  const Eigen::MatrixXd& jacobian(std::size_t b) const { return A_[b]; }
  Eigen::VectorXd residual(const std::vector<const double*>& x) const {
    Eigen::VectorXd r = -z_;
    for (std::size_t b = 0; b < A_.size(); ++b) {
      r += A_[b] * Eigen::Map<const Eigen::VectorXd>(x[b], A_[b].cols());
    }
    return r;
  }
  bool Evaluate(double const* const* x, double* residuals, double** jacobians) const override {
    Eigen::VectorXd r = -z_;
    for (std::size_t b = 0; b < A_.size(); ++b) {
      r += A_[b] * Eigen::Map<const Eigen::VectorXd>(x[b], A_[b].cols());
      if (jacobians != nullptr && jacobians[b] != nullptr) {
        Eigen::Map<test::RowMatrix>(jacobians[b], A_[b].rows(), A_[b].cols()) = A_[b];
      }
    }
    Eigen::Map<Eigen::VectorXd>(residuals, r.size()) = r;
    return true;
  }

 private:
  std::vector<Eigen::MatrixXd> A_;
  Eigen::VectorXd z_;
};

Eigen::MatrixXd randomMatrix(int rows, int cols, std::mt19937* rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::MatrixXd M(rows, cols);
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < cols; ++j) M(i, j) = n(*rng);
  }
  return M;
}

void solve(ceres::Problem* problem) {
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.function_tolerance = 1e-16;
  options.gradient_tolerance = 1e-16;
  options.parameter_tolerance = 1e-16;
  ceres::Solver::Summary summary;
  ceres::Solve(options, problem, &summary);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.BriefReport();
}

TEST(Marginalization, LinearProblemKeepsTheFullSolution) {
  std::mt19937 rng(7);
  const LinearCost a({randomMatrix(4, 2, &rng), randomMatrix(4, 3, &rng)},
                     randomMatrix(4, 1, &rng));
  const LinearCost b({randomMatrix(3, 3, &rng), randomMatrix(3, 2, &rng)},
                     randomMatrix(3, 1, &rng));
  const LinearCost c({randomMatrix(2, 2, &rng)}, randomMatrix(2, 1, &rng));
  const LinearCost d({randomMatrix(3, 2, &rng)}, randomMatrix(3, 1, &rng));

  // Full problem over x1 (2), x2 (3), x3 (2).
  double x1[2] = {0, 0}, x2[3] = {0, 0, 0}, x3[2] = {0, 0};
  auto add = [](ceres::Problem* p, const LinearCost& cost, std::vector<double*> blocks) {
    p->AddResidualBlock(const_cast<LinearCost*>(&cost), nullptr, blocks);
  };
  ceres::Problem::Options borrowed;
  borrowed.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem full(borrowed);
  add(&full, a, {x1, x2});
  add(&full, b, {x2, x3});
  add(&full, c, {x1});
  add(&full, d, {x3});
  solve(&full);
  const Eigen::Vector3d x2_full(x2);
  const Eigen::Vector2d x3_full(x3);

  // Marginalize x1 at an arbitrary point (the problem is linear, so the point does not matter).
  double y1[2] = {0.3, -1.2}, y2[3] = {1.0, 2.0, -0.5}, y3[2] = {0.1, 0.2};
  Marginalizer marginalizer;
  marginalizer.addResidual(&a, nullptr, {y1, y2});
  marginalizer.addResidual(&c, nullptr, {y1});
  auto prior = marginalizer.marginalize({y1});
  ASSERT_TRUE(prior.ok()) << prior.status().message();
  ASSERT_EQ(prior.value()->parameterBlocks(), std::vector<double*>{y2});
  ceres::Problem reduced(borrowed);
  std::unique_ptr<MarginalizationFactor> owned = std::move(prior).value();
  reduced.AddResidualBlock(owned.get(), nullptr, owned->parameterBlocks());
  add(&reduced, b, {y2, y3});
  add(&reduced, d, {y3});
  solve(&reduced);
  EXPECT_LT((Eigen::Vector3d(y2) - x2_full).norm(), 1e-9);
  EXPECT_LT((Eigen::Vector2d(y3) - x3_full).norm(), 1e-9);
}

// A dropped block that its residuals see in two of its three directions: H_mm is singular, the
// Cholesky route refuses it and the pseudo-inverse takes it; the prior is then the dense Schur
// complement through H_mm's pseudo-inverse (the unseen direction tells the kept blocks nothing).
TEST(Marginalization, SingularDroppedBlocksGoThroughThePseudoInverse) {
  std::mt19937 rng(11);
  Eigen::MatrixXd A_x = randomMatrix(5, 3, &rng);
  A_x.col(2).setZero();  // x's third coordinate is in no residual
  const LinearCost a({A_x, randomMatrix(5, 4, &rng)}, randomMatrix(5, 1, &rng));
  const LinearCost b({randomMatrix(3, 2, &rng), randomMatrix(3, 4, &rng)},
                     randomMatrix(3, 1, &rng));
  const LinearCost c({Eigen::MatrixXd::Identity(4, 4)}, randomMatrix(4, 1, &rng));
  double x[3] = {0.2, -0.4, 0.7}, u[2] = {1.0, 0.5}, y[4] = {0.1, -0.3, 0.2, 0.4};
  Marginalizer marginalizer;
  marginalizer.addResidual(&a, nullptr, {x, y});
  marginalizer.addResidual(&b, nullptr, {u, y});
  marginalizer.addResidual(&c, nullptr, {y});
  auto made = marginalizer.marginalize({x, u});
  ASSERT_TRUE(made.ok()) << made.status().message();
  ASSERT_EQ(made.value()->parameterBlocks(), std::vector<double*>{y});

  // Dense reference over [x 3, u 2 | y 4].
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(12, 9);
  J.block(0, 0, 5, 3) = a.jacobian(0);
  J.block(0, 5, 5, 4) = a.jacobian(1);
  J.block(5, 3, 3, 2) = b.jacobian(0);
  J.block(5, 5, 3, 4) = b.jacobian(1);
  J.block(8, 5, 4, 4) = c.jacobian(0);
  Eigen::VectorXd r(12);
  r << a.residual({x, y}), b.residual({u, y}), c.residual({y});
  const Eigen::MatrixXd H = J.transpose() * J;
  const Eigen::VectorXd g = J.transpose() * r;
  const Eigen::MatrixXd Hmm_pinv =
      H.topLeftCorner(5, 5).completeOrthogonalDecomposition().pseudoInverse();
  ASSERT_LT(std::abs(H.topLeftCorner(5, 5).determinant()), 1e-12);
  const Eigen::MatrixXd Hs =
      H.bottomRightCorner(4, 4) - H.bottomLeftCorner(4, 5) * Hmm_pinv * H.topRightCorner(5, 4);
  const Eigen::VectorXd gs = g.tail(4) - H.bottomLeftCorner(4, 5) * Hmm_pinv * g.head(5);
  const MarginalizationFactor& prior = *made.value();
  EXPECT_LT((prior.J0().transpose() * prior.J0() - Hs).cwiseAbs().maxCoeff(),
            1e-9 * Hs.cwiseAbs().maxCoeff());
  EXPECT_LT((prior.J0().transpose() * prior.r0() - gs).cwiseAbs().maxCoeff(),
            1e-9 * gs.cwiseAbs().maxCoeff());
}

// A small visual-inertial-like problem: two states, gravity, an IMU factor and priors.
struct SmallProblem {
  std::vector<std::vector<double>> blocks;  // pose_i, sb_i, pose_j, sb_j, g
  std::shared_ptr<ImuPreintegration> pre;
  std::unique_ptr<ImuFactor> imu;
  std::unique_ptr<PosePriorFactor> pose_prior;
  std::unique_ptr<ceres::NormalPrior> sb_prior;
};

SmallProblem makeSmallProblem() {
  SmallProblem s;
  ImuNoise noise{2e-3, 3e-3, 1.7e-4, 1.9e-5};
  s.pre = std::make_shared<ImuPreintegration>(noise, Eigen::Vector3d(1e-3, 0, 0),
                                              Eigen::Vector3d(0, 0.01, 0));
  for (int k = 0; k <= 50; ++k) {
    const double t = k / 500.0;
    s.pre->add({fromSeconds(t), Eigen::Vector3d(0.3 * std::sin(3 * t), 0.2, -0.1 * t),
                Eigen::Vector3d(0.5 * std::cos(2 * t), 0.1, 9.7)});
  }
  s.imu = std::make_unique<ImuFactor>(s.pre);
  SE3 T_i(lie::expQuat(Eigen::Vector3d(0.1, -0.2, 0.3)), Eigen::Vector3d(0.5, 0.2, 1.0));
  SE3 T_j(T_i.q * lie::expQuat(Eigen::Vector3d(0.03, 0.02, -0.01)),
          T_i.p + Eigen::Vector3d(0.01, 0.02, -0.01));
  s.blocks.assign(5, {});
  s.blocks[0].resize(7);
  s.blocks[2].resize(7);
  se3ToPose(T_i, s.blocks[0].data());
  se3ToPose(T_j, s.blocks[2].data());
  s.blocks[1] = {0.1, 0.2, -0.1, 1e-3, 2e-3, 0, 0.01, 0.02, -0.01};
  s.blocks[3] = {0.12, 0.18, -0.09, 1.1e-3, 2e-3, 0, 0.01, 0.021, -0.01};
  s.blocks[4] = {0.2, -0.1, -9.806};
  s.pose_prior.reset(PosePriorFactor::fromStd(
      SE3(T_i.q * lie::expQuat(Eigen::Vector3d(0.01, 0, 0)), T_i.p + Eigen::Vector3d(0, 0.01, 0)),
      Eigen::Vector3d::Constant(0.05), Eigen::Vector3d::Constant(0.1)));
  Eigen::Matrix<double, 9, 1> sb_mean = Eigen::Matrix<double, 9, 1>::Zero();
  s.sb_prior = std::make_unique<ceres::NormalPrior>(
      Eigen::MatrixXd(Eigen::Matrix<double, 9, 1>::Constant(10.0).asDiagonal()), sb_mean);
  return s;
}

// A prior on the second state's pose: with it (and one on its speed and biases) the Schur
// complement is positive definite.
std::unique_ptr<PosePriorFactor> secondPosePrior(SmallProblem* s) {
  return std::unique_ptr<PosePriorFactor>(
      PosePriorFactor::fromStd(poseToSE3(s->blocks[2].data()), Eigen::Vector3d::Constant(0.02),
                               Eigen::Vector3d::Constant(0.05)));
}

// The small problem's factors around the first state, ready to marginalize it.
Marginalizer smallMarginalizer(SmallProblem* s, const PoseManifold& pose,
                               const ceres::SphereManifold<3>& sphere) {
  auto ptr = [&](int b) { return s->blocks[b].data(); };
  Marginalizer m;
  m.setManifold(ptr(0), &pose);
  m.setManifold(ptr(2), &pose);
  m.setManifold(ptr(4), &sphere);
  m.addResidual(s->imu.get(), nullptr, {ptr(0), ptr(1), ptr(2), ptr(3), ptr(4)});
  m.addResidual(s->pose_prior.get(), nullptr, {ptr(0)});
  m.addResidual(s->sb_prior.get(), nullptr, {ptr(1)});
  return m;
}

// A Schur complement of rank 2 over 5 kept values (x1 dropped, 3 values, by 5 rows): factored
// as semi-definite (allowSemidefinite) it has one row per kept pivot, upper trapezoidal, and
// the same information and gradient as the dense reference; informationOnly keeps no rows and
// the same information.
TEST(Marginalization, SemidefinitePriorKeepsItsInformationInTriangularRows) {
  std::mt19937 rng(11);
  const LinearCost a({randomMatrix(5, 3, &rng), randomMatrix(5, 2, &rng), randomMatrix(5, 3, &rng)},
                     randomMatrix(5, 1, &rng));
  double x1[3] = {0.1, 0.2, 0.3}, x2[2] = {-0.4, 0.5}, x3[3] = {0.6, -0.7, 0.8};
  Eigen::MatrixXd J(5, 8);
  J << a.jacobian(0), a.jacobian(1), a.jacobian(2);
  const Eigen::VectorXd r = a.residual({x1, x2, x3});
  const Eigen::MatrixXd H = J.transpose() * J;
  const Eigen::VectorXd g = J.transpose() * r;
  const Eigen::MatrixXd Hmm_inv = H.topLeftCorner(3, 3).inverse();
  const Eigen::MatrixXd Hs =
      H.bottomRightCorner(5, 5) - H.bottomLeftCorner(5, 3) * Hmm_inv * H.topRightCorner(3, 5);
  const Eigen::VectorXd gs = g.tail(5) - H.bottomLeftCorner(5, 3) * Hmm_inv * g.head(3);
  const double scale = Hs.cwiseAbs().maxCoeff();
  for (const bool information_only : {false, true}) {
    Marginalizer m;
    m.allowSemidefinite();
    if (information_only) m.informationOnly();
    m.addResidual(&a, nullptr, {x1, x2, x3});
    auto made = m.marginalize({x1});
    ASSERT_TRUE(made.ok()) << made.status().message();
    const MarginalizationFactor& prior = *made.value();
    EXPECT_LT((prior.information() - Hs).cwiseAbs().maxCoeff(), 1e-10 * scale);
    EXPECT_LT((prior.gradient() - gs).cwiseAbs().maxCoeff(), 1e-10 * scale);
    if (information_only) {
      EXPECT_EQ(prior.J0().rows(), 0);
      continue;
    }
    const Eigen::MatrixXd& J0 = prior.J0();
    ASSERT_EQ(J0.rows(), 2);  // the rank: 5 rows less the 3 that x1 took
    EXPECT_EQ(J0(1, 0), 0.0);  // upper trapezoidal
    EXPECT_LT((J0.transpose() * J0 - Hs).cwiseAbs().maxCoeff(), 1e-10 * scale);
    EXPECT_LT((J0.transpose() * prior.r0() - gs).cwiseAbs().maxCoeff(), 1e-10 * scale);
  }
}

TEST(Marginalization, MatchesDenseSchurComplement) {
  SmallProblem s = makeSmallProblem();
  const PoseManifold pose;
  const ceres::SphereManifold<3> sphere;
  const std::vector<const ceres::Manifold*> manifolds = {&pose, nullptr, &pose, nullptr, &sphere};
  auto ptr = [&](int b) { return s.blocks[b].data(); };

  Marginalizer marginalizer = smallMarginalizer(&s, pose, sphere);
  auto made = marginalizer.marginalize({ptr(0), ptr(1)});
  ASSERT_TRUE(made.ok()) << made.status().message();
  const MarginalizationFactor& prior = *made.value();
  ASSERT_EQ(prior.parameterBlocks(), (std::vector<double*>{ptr(2), ptr(3), ptr(4)}));

  // Dense reference: the stacked tangent Jacobian of all three factors over
  // [pose_i 6, sb_i 9 | pose_j 6, sb_j 9, g 2].
  const int n = 32, m = 15;
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(15 + 6 + 9, n);
  Eigen::VectorXd r(15 + 6 + 9);
  const int offsets[5] = {0, 6, 15, 21, 30};
  const auto imu_J = test::analyticTangentJacobians(*s.imu, s.blocks, manifolds);
  for (int b = 0; b < 5; ++b) J.block(0, offsets[b], 15, imu_J[b].cols()) = imu_J[b];
  r.head(15) = test::evaluateResiduals(*s.imu, s.blocks);
  const auto prior_J = test::analyticTangentJacobians(*s.pose_prior, {s.blocks[0]}, {&pose});
  J.block(15, 0, 6, 6) = prior_J[0];
  r.segment(15, 6) = test::evaluateResiduals(*s.pose_prior, {s.blocks[0]});
  J.block(21, 6, 9, 9) = test::analyticTangentJacobians(*s.sb_prior, {s.blocks[1]}, {nullptr})[0];
  r.tail(9) = test::evaluateResiduals(*s.sb_prior, {s.blocks[1]});
  const Eigen::MatrixXd H = J.transpose() * J;
  const Eigen::VectorXd g = J.transpose() * r;
  const Eigen::MatrixXd Hmm_inv = H.topLeftCorner(m, m).inverse();
  const Eigen::MatrixXd Hs = H.bottomRightCorner(n - m, n - m) -
                             H.bottomLeftCorner(n - m, m) * Hmm_inv * H.topRightCorner(m, n - m);
  const Eigen::VectorXd gs = g.tail(n - m) - H.bottomLeftCorner(n - m, m) * Hmm_inv * g.head(m);

  const Eigen::MatrixXd H_prior = prior.J0().transpose() * prior.J0();
  const Eigen::VectorXd g_prior = prior.J0().transpose() * prior.r0();
  // Same arithmetic in another order. The Schur complement cancels terms as large as the
  // kept blocks' own information (bias random walk ~1e10 here), so compare relative to that
  // scale: Jacobi-scaled by D = diag(H_kk), the differences are round-off, ~1e-16 * cond.
  const Eigen::VectorXd inv_sqrt_d = H.diagonal().tail(n - m).cwiseSqrt().cwiseInverse();
  const Eigen::MatrixXd scaled_error =
      inv_sqrt_d.asDiagonal() * (H_prior - Hs) * inv_sqrt_d.asDiagonal();
  EXPECT_LT(scaled_error.cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_LT((inv_sqrt_d.asDiagonal() * (g_prior - gs)).cwiseAbs().maxCoeff(), 1e-10);
  // Evaluated at its linearization point the prior is r0; moved by dx in the tangent, it is
  // r0 + J0 dx (the Minus of each manifold undoes its Plus).
  auto kept = std::vector<std::vector<double>>{s.blocks[2], s.blocks[3], s.blocks[4]};
  EXPECT_LT((test::evaluateResiduals(prior, kept) - prior.r0()).norm(), 1e-12);
  Eigen::VectorXd dx(17);
  for (int i = 0; i < 17; ++i) dx[i] = 1e-3 * std::sin(1.0 + i);
  auto moved = kept;
  pose.Plus(kept[0].data(), dx.data(), moved[0].data());
  for (int i = 0; i < 9; ++i) moved[1][i] += dx[6 + i];
  sphere.Plus(kept[2].data(), dx.data() + 15, moved[2].data());
  EXPECT_LT((test::evaluateResiduals(prior, moved) - (prior.r0() + prior.J0() * dx)).norm(),
            1e-6 * (prior.J0() * dx).norm());
  // At the linearization point its Jacobians match central differences through the manifolds
  // (away from it they stay J0: the first-estimate approximation, off by O(|dx|)).
  const std::vector<const ceres::Manifold*> kept_manifolds = {&pose, nullptr, &sphere};
  EXPECT_LT(
      test::jacobianMismatch(test::analyticTangentJacobians(prior, kept, kept_manifolds),
                             test::numericTangentJacobians(prior, kept, kept_manifolds, 1e-6)),
      1e-5);

  // With gravity held constant for the run (setFixed) it is left out, conditioned on: the prior
  // spans the second state only, and is the dense Schur complement's block on it.
  Marginalizer without_gravity = smallMarginalizer(&s, pose, sphere);
  without_gravity.setFixed(ptr(4));
  auto conditioned = without_gravity.marginalize({ptr(0), ptr(1)});
  ASSERT_TRUE(conditioned.ok()) << conditioned.status().message();
  const MarginalizationFactor& on_state = *conditioned.value();
  ASSERT_EQ(on_state.parameterBlocks(), (std::vector<double*>{ptr(2), ptr(3)}));
  const Eigen::MatrixXd H_state = on_state.J0().transpose() * on_state.J0();
  const Eigen::VectorXd g_state = on_state.J0().transpose() * on_state.r0();
  const Eigen::VectorXd d_state = inv_sqrt_d.head(15);
  EXPECT_LT((d_state.asDiagonal() * (H_state - Hs.topLeftCorner(15, 15)) * d_state.asDiagonal())
                .cwiseAbs()
                .maxCoeff(),
            1e-10);
  EXPECT_LT((d_state.asDiagonal() * (g_state - gs.head(15))).cwiseAbs().maxCoeff(), 1e-10);
}

// With priors on the kept blocks too, the Schur complement is positive definite: the prior comes
// from its Cholesky factor, upper triangular over [pose_j 6, sb_j 9, g 2], and splits into one
// residual block per kept block whose costs add up to the whole prior's.
TEST(Marginalization, CholeskyPriorIsTriangularAndSplitsByBlock) {
  SmallProblem s = makeSmallProblem();
  const PoseManifold pose;
  const ceres::SphereManifold<3> sphere;
  auto ptr = [&](int b) { return s.blocks[b].data(); };
  const std::unique_ptr<PosePriorFactor> pose_j_prior = secondPosePrior(&s);

  Marginalizer marginalizer = smallMarginalizer(&s, pose, sphere);
  marginalizer.addResidual(pose_j_prior.get(), nullptr, {ptr(2)});
  marginalizer.addResidual(s.sb_prior.get(), nullptr, {ptr(3)});
  auto made = marginalizer.marginalize({ptr(0), ptr(1)});
  ASSERT_TRUE(made.ok()) << made.status().message();
  const MarginalizationFactor& prior = *made.value();
  const Eigen::MatrixXd& J0 = prior.J0();
  ASSERT_EQ(J0.rows(), 17);
  ASSERT_EQ(J0.cols(), 17);
  // Upper triangular (exact zeros below the diagonal), with a positive diagonal.
  EXPECT_EQ(J0.triangularView<Eigen::StrictlyLower>().toDenseMatrix().cwiseAbs().maxCoeff(), 0.0);
  EXPECT_GT(J0.diagonal().minCoeff(), 0.0);

  // Equal to the dense Schur complement (the same check as above, now full rank).
  const std::vector<const ceres::Manifold*> manifolds = {&pose, nullptr, &pose, nullptr, &sphere};
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(15 + 6 + 9 + 6 + 9, 32);
  Eigen::VectorXd r(J.rows());
  const int offsets[5] = {0, 6, 15, 21, 30};
  const auto imu_J = test::analyticTangentJacobians(*s.imu, s.blocks, manifolds);
  for (int b = 0; b < 5; ++b) J.block(0, offsets[b], 15, imu_J[b].cols()) = imu_J[b];
  r.head(15) = test::evaluateResiduals(*s.imu, s.blocks);
  J.block(15, 0, 6, 6) = test::analyticTangentJacobians(*s.pose_prior, {s.blocks[0]}, {&pose})[0];
  r.segment(15, 6) = test::evaluateResiduals(*s.pose_prior, {s.blocks[0]});
  J.block(21, 6, 9, 9) = test::analyticTangentJacobians(*s.sb_prior, {s.blocks[1]}, {nullptr})[0];
  r.segment(21, 9) = test::evaluateResiduals(*s.sb_prior, {s.blocks[1]});
  J.block(30, 15, 6, 6) = test::analyticTangentJacobians(*pose_j_prior, {s.blocks[2]}, {&pose})[0];
  r.segment(30, 6) = test::evaluateResiduals(*pose_j_prior, {s.blocks[2]});
  J.block(36, 21, 9, 9) = test::analyticTangentJacobians(*s.sb_prior, {s.blocks[3]}, {nullptr})[0];
  r.segment(36, 9) = test::evaluateResiduals(*s.sb_prior, {s.blocks[3]});
  const Eigen::MatrixXd H = J.transpose() * J;
  const Eigen::VectorXd g = J.transpose() * r;
  const int m = 15, k = 17;
  const Eigen::MatrixXd Hmm_inv = H.topLeftCorner(m, m).inverse();
  const Eigen::MatrixXd Hs =
      H.bottomRightCorner(k, k) - H.bottomLeftCorner(k, m) * Hmm_inv * H.topRightCorner(m, k);
  const Eigen::VectorXd gs = g.tail(k) - H.bottomLeftCorner(k, m) * Hmm_inv * g.head(m);
  const Eigen::VectorXd inv_sqrt_d = H.diagonal().tail(k).cwiseSqrt().cwiseInverse();
  EXPECT_LT((inv_sqrt_d.asDiagonal() * (J0.transpose() * J0 - Hs) * inv_sqrt_d.asDiagonal())
                .cwiseAbs()
                .maxCoeff(),
            1e-10);
  EXPECT_LT((inv_sqrt_d.asDiagonal() * (J0.transpose() * prior.r0() - gs)).cwiseAbs().maxCoeff(),
            1e-10);

  // A dropped block eliminated on its own first (eliminateAlone: the estimator's landmarks that
  // leave with their observations) gives the same Schur complement, here with one or both of the
  // leaving state's blocks alone (the latter leaves nothing for the dense step).
  for (const std::vector<int>& alone :
       {std::vector<int>{0}, std::vector<int>{1}, std::vector<int>{0, 1}}) {
    Marginalizer m_alone = smallMarginalizer(&s, pose, sphere);
    m_alone.addResidual(pose_j_prior.get(), nullptr, {ptr(2)});
    m_alone.addResidual(s.sb_prior.get(), nullptr, {ptr(3)});
    for (int b : alone) m_alone.eliminateAlone(ptr(b));
    auto other = m_alone.marginalize({ptr(0), ptr(1)});
    ASSERT_TRUE(other.ok()) << other.status().message();
    const MarginalizationFactor& p = *other.value();
    ASSERT_EQ(p.parameterBlocks(), (std::vector<double*>{ptr(2), ptr(3), ptr(4)}));
    EXPECT_LT((inv_sqrt_d.asDiagonal() * (p.J0().transpose() * p.J0() - Hs) *
               inv_sqrt_d.asDiagonal())
                  .cwiseAbs()
                  .maxCoeff(),
              1e-10)
        << alone.size();
    EXPECT_LT((inv_sqrt_d.asDiagonal() * (p.J0().transpose() * p.r0() - gs)).cwiseAbs().maxCoeff(),
              1e-10)
        << alone.size();
  }

  // Split: one factor per kept block, on that block and the ones after it.
  const auto parts = prior.splitRows();
  ASSERT_EQ(parts.size(), 3u);
  EXPECT_EQ(parts[0]->parameterBlocks(), (std::vector<double*>{ptr(2), ptr(3), ptr(4)}));
  EXPECT_EQ(parts[1]->parameterBlocks(), (std::vector<double*>{ptr(3), ptr(4)}));
  EXPECT_EQ(parts[2]->parameterBlocks(), (std::vector<double*>{ptr(4)}));
  EXPECT_EQ(parts[0]->num_residuals() + parts[1]->num_residuals() + parts[2]->num_residuals(), 17);
  // Their costs add up to the whole prior's away from the linearization point.
  std::vector<std::vector<double>> moved = {s.blocks[2], s.blocks[3], s.blocks[4]};
  Eigen::VectorXd dx(17);
  for (int i = 0; i < 17; ++i) dx[i] = 1e-2 * std::cos(0.5 + i);
  std::vector<double> tmp = moved[0];
  pose.Plus(tmp.data(), dx.data(), moved[0].data());
  for (int i = 0; i < 9; ++i) moved[1][i] += dx[6 + i];
  tmp = moved[2];
  sphere.Plus(tmp.data(), dx.data() + 15, moved[2].data());
  const double whole = test::evaluateResiduals(prior, moved).squaredNorm();
  double sum = 0.0;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    sum += test::evaluateResiduals(*parts[i],
                                   std::vector<std::vector<double>>(moved.begin() + i, moved.end()))
               .squaredNorm();
  }
  EXPECT_GT(whole, 1.0);
  EXPECT_LT(std::abs(sum - whole), 1e-9 * whole);
}

// Marginalizing again: an earlier prior added through the information it keeps (addPrior) gives
// the same prior as its rows added as a residual, away from its linearization point (where its
// gradient has moved by H* dx), from its Cholesky form and from its eigen-decomposition form
// (rank-deficient).
TEST(Marginalization, AnEarlierPriorAddsThroughItsInformationAsThroughItsRows) {
  for (const bool full_rank : {true, false}) {
    SmallProblem s = makeSmallProblem();
    const PoseManifold pose;
    const ceres::SphereManifold<3> sphere;
    auto ptr = [&](int b) { return s.blocks[b].data(); };
    const std::unique_ptr<PosePriorFactor> pose_j_prior = secondPosePrior(&s);
    Marginalizer first = smallMarginalizer(&s, pose, sphere);
    if (full_rank) {
      first.addResidual(pose_j_prior.get(), nullptr, {ptr(2)});
      first.addResidual(s.sb_prior.get(), nullptr, {ptr(3)});
    }
    auto made = first.marginalize({ptr(0), ptr(1)});
    ASSERT_TRUE(made.ok()) << made.status().message();
    const MarginalizationFactor& prior = *made.value();
    ASSERT_EQ(prior.information().rows(), 17);
    // Away from x0.
    Eigen::VectorXd dx(17);
    for (int i = 0; i < 17; ++i) dx[i] = 2e-2 * std::sin(0.3 + i);
    std::vector<double> tmp = s.blocks[2];
    pose.Plus(tmp.data(), dx.data(), ptr(2));
    for (int i = 0; i < 9; ++i) s.blocks[3][i] += dx[6 + i];
    tmp = s.blocks[4];
    sphere.Plus(tmp.data(), dx.data() + 15, ptr(4));
    // Drop sb_j, keep pose_j and gravity, with a measurement on sb_j and gravity too.
    const std::unique_ptr<ceres::NormalPrior> tie(new ceres::NormalPrior(
        Eigen::MatrixXd::Identity(3, 3) * 5.0, Eigen::Vector3d(0.1, 0.2, -9.8)));
    Eigen::MatrixXd rows[2];
    Eigen::VectorXd residual[2];
    for (int way = 0; way < 2; ++way) {
      Marginalizer again;
      again.setManifold(ptr(2), &pose);
      again.setManifold(ptr(4), &sphere);
      again.addResidual(tie.get(), nullptr, {ptr(4)});
      if (way == 0) {
        again.addResidual(&prior, nullptr, prior.parameterBlocks());
      } else {
        again.addPrior(&prior);
      }
      auto out = again.marginalize({ptr(3)});
      ASSERT_TRUE(out.ok()) << out.status().message();
      rows[way] = out.value()->J0().transpose() * out.value()->J0();
      residual[way] = out.value()->J0().transpose() * out.value()->r0();
    }
    const Eigen::VectorXd inv_sqrt_d = rows[0].diagonal().cwiseSqrt().cwiseInverse();
    EXPECT_GT((residual[0]).norm(), 1.0) << full_rank;  // away from x0: a gradient
    EXPECT_LT((inv_sqrt_d.asDiagonal() * (rows[1] - rows[0]) * inv_sqrt_d.asDiagonal())
                  .cwiseAbs()
                  .maxCoeff(),
              1e-10)
        << full_rank;
    EXPECT_LT((inv_sqrt_d.asDiagonal() * (residual[1] - residual[0])).cwiseAbs().maxCoeff(), 1e-9)
        << full_rank;
  }
}

TEST(PosePriorFactor, JacobiansMatchCentralDifferences) {
  const std::unique_ptr<PosePriorFactor> f(PosePriorFactor::fromStd(
      SE3(lie::expQuat(Eigen::Vector3d(0.3, 0.1, -0.2)), Eigen::Vector3d(1, 2, 3)),
      Eigen::Vector3d(0.01, 0.02, 0.03), Eigen::Vector3d(0.1, 0.2, 0.3)));
  std::vector<std::vector<double>> blocks = {std::vector<double>(7)};
  se3ToPose(SE3(lie::expQuat(Eigen::Vector3d(0.5, -0.2, 0.1)), Eigen::Vector3d(1.1, 2, 2.9)),
            blocks[0].data());
  const PoseManifold pose;
  EXPECT_LT(test::jacobianMismatch(test::analyticTangentJacobians(*f, blocks, {&pose}),
                                   test::numericTangentJacobians(*f, blocks, {&pose}, 1e-6)),
            1e-6);
}

}  // namespace
}  // namespace mvis
