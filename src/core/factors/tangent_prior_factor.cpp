#include "mvis/factors/tangent_prior_factor.h"

namespace mvis {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

TangentPriorFactor::TangentPriorFactor(const ceres::Manifold* manifold, std::vector<double> x0,
                                       const Eigen::MatrixXd& directions,
                                       const Eigen::VectorXd& std)
    : TangentPriorFactor(std::vector<Block>{{manifold, std::move(x0)}}, directions, std) {}

TangentPriorFactor::TangentPriorFactor(std::vector<Block> blocks, const Eigen::MatrixXd& directions,
                                       const Eigen::VectorXd& std)
    : blocks_(std::move(blocks)), A_(std.cwiseInverse().asDiagonal() * directions.transpose()) {
  set_num_residuals(static_cast<int>(A_.rows()));
  int offset = 0;
  for (const Block& b : blocks_) {
    const int ambient = static_cast<int>(b.x0.size());
    mutable_parameter_block_sizes()->push_back(ambient);
    tangent_.push_back(b.manifold != nullptr ? b.manifold->TangentSize() : ambient);
    offset_.push_back(offset);
    offset += tangent_.back();
  }
}

bool TangentPriorFactor::Evaluate(double const* const* parameters, double* residuals,
                                  double** jacobians) const {
  Eigen::VectorXd d(A_.cols());
  for (std::size_t i = 0; i < blocks_.size(); ++i) {
    const Block& b = blocks_[i];
    if (b.manifold != nullptr) {
      if (!b.manifold->Minus(parameters[i], b.x0.data(), d.data() + offset_[i])) return false;
    } else {
      for (int k = 0; k < tangent_[i]; ++k) d[offset_[i] + k] = parameters[i][k] - b.x0[k];
    }
  }
  Eigen::Map<Eigen::VectorXd>(residuals, A_.rows()) = A_ * d;
  if (jacobians == nullptr) return true;
  for (std::size_t i = 0; i < blocks_.size(); ++i) {
    if (jacobians[i] == nullptr) continue;
    const Block& b = blocks_[i];
    const int ambient = static_cast<int>(b.x0.size());
    Eigen::Map<RowMatrix> J(jacobians[i], A_.rows(), ambient);
    const auto A_i = A_.middleCols(offset_[i], tangent_[i]);
    if (b.manifold != nullptr) {
      RowMatrix minus(tangent_[i], ambient);
      if (!b.manifold->MinusJacobian(parameters[i], minus.data())) return false;
      J = A_i * minus;
    } else {
      J = A_i;
    }
  }
  return true;
}

}  // namespace mvis
