#include "mvis/factors/tangent_prior_factor.h"

namespace mvis {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

TangentPriorFactor::TangentPriorFactor(const ceres::Manifold* manifold, std::vector<double> x0,
                                       const Eigen::MatrixXd& directions,
                                       const Eigen::VectorXd& std)
    : manifold_(manifold),
      x0_(std::move(x0)),
      tangent_(static_cast<int>(directions.rows())),
      A_(std.cwiseInverse().asDiagonal() * directions.transpose()) {
  set_num_residuals(static_cast<int>(A_.rows()));
  mutable_parameter_block_sizes()->push_back(static_cast<int>(x0_.size()));
}

bool TangentPriorFactor::Evaluate(double const* const* parameters, double* residuals,
                                  double** jacobians) const {
  const int ambient = static_cast<int>(x0_.size());
  Eigen::VectorXd d(tangent_);
  if (manifold_ != nullptr) {
    if (!manifold_->Minus(parameters[0], x0_.data(), d.data())) return false;
  } else {
    for (int i = 0; i < ambient; ++i) d[i] = parameters[0][i] - x0_[i];
  }
  Eigen::Map<Eigen::VectorXd>(residuals, A_.rows()) = A_ * d;
  if (jacobians != nullptr && jacobians[0] != nullptr) {
    Eigen::Map<RowMatrix> J(jacobians[0], A_.rows(), ambient);
    if (manifold_ != nullptr) {
      RowMatrix minus(tangent_, ambient);
      if (!manifold_->MinusJacobian(parameters[0], minus.data())) return false;
      J = A_ * minus;
    } else {
      J = A_;
    }
  }
  return true;
}

}  // namespace mvis
