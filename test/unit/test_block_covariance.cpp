// BlockCovariance against the inverse information computed densely, on a small linear problem:
// a listed block x (2 values) and a block y (3 values) that residuals also reach. When nothing
// measures one direction of y (as a tag's corner seen from one state only), x's covariance is
// still given, and equals the one with that direction left out; when x itself has a direction
// without information, it is refused.
#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include "block_covariance.h"

namespace mvis::estimator_internal {
namespace {

// r = A [x; y] - b, fixed A (rows x 5).
class Linear : public ceres::CostFunction {
 public:
  explicit Linear(Eigen::MatrixXd A) : A_(std::move(A)) {
    set_num_residuals(static_cast<int>(A_.rows()));
    mutable_parameter_block_sizes()->push_back(2);
    mutable_parameter_block_sizes()->push_back(3);
  }
  bool Evaluate(double const* const* p, double* r, double** J) const override {
    Eigen::Matrix<double, 5, 1> v;
    v << p[0][0], p[0][1], p[1][0], p[1][1], p[1][2];
    Eigen::Map<Eigen::VectorXd>(r, A_.rows()) = A_ * v;
    if (J != nullptr) {
      for (int i = 0; i < A_.rows(); ++i) {
        for (int k = 0; k < 2; ++k) {
          if (J[0] != nullptr) J[0][i * 2 + k] = A_(i, k);
        }
        for (int k = 0; k < 3; ++k) {
          if (J[1] != nullptr) J[1][i * 3 + k] = A_(i, 2 + k);
        }
      }
    }
    return true;
  }

 private:
  Eigen::MatrixXd A_;
};

Eigen::MatrixXd jacobian(bool x_unmeasured) {
  // Rows reach x and y's first two values; y's third value (column 4) is in none.
  Eigen::MatrixXd A(6, 5);
  A << 1.0, 0.2, 0.5, 0.0, 0.0,  //
      0.3, 1.1, 0.0, 0.7, 0.0,   //
      0.0, 0.4, 1.2, 0.1, 0.0,   //
      0.6, 0.0, 0.3, 0.9, 0.0,   //
      0.2, 0.5, 0.0, 0.0, 0.0,   //
      0.0, 0.0, 0.8, 0.4, 0.0;
  if (x_unmeasured) A.col(1).setZero();
  return A;
}

TEST(BlockCovariance, GivesTheListedBlocksWhereAnotherHasADirectionWithoutInformation) {
  const Eigen::MatrixXd A = jacobian(false);
  double x[2] = {0.1, -0.2}, y[3] = {0.3, 0.4, 0.5};
  ceres::Problem problem;
  problem.AddResidualBlock(new Linear(A), nullptr, x, y);
  BlockCovariance cov;
  ASSERT_TRUE(cov.compute({{x, x}}, &problem));
  // Expected: the information without y's unmeasured value, inverted, its x block.
  const Eigen::MatrixXd B = A.leftCols(4);
  const Eigen::MatrixXd expected = (B.transpose() * B).inverse().topLeftCorner(2, 2);
  Eigen::Matrix2d got;
  ASSERT_TRUE(cov.GetCovarianceBlock(x, x, got.data()));
  EXPECT_LT((got - expected).norm(), 1e-9 * expected.norm()) << got << "\n" << expected;
  // y's own covariance is not asked for: listing it is refused (a direction of it unmeasured).
  BlockCovariance both;
  EXPECT_FALSE(both.compute({{x, x}, {y, y}}, &problem));
}

TEST(BlockCovariance, RefusesAListedBlockWithADirectionWithoutInformation) {
  double x[2] = {0.1, -0.2}, y[3] = {0.3, 0.4, 0.5};
  ceres::Problem problem;
  problem.AddResidualBlock(new Linear(jacobian(true)), nullptr, x, y);
  BlockCovariance cov;
  EXPECT_FALSE(cov.compute({{x, x}}, &problem));
}

}  // namespace
}  // namespace mvis::estimator_internal
