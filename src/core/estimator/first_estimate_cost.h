// First-estimate Jacobians (Huang, Mourikis, Roumeliotis): a cost whose Jacobians in some of its
// parameter blocks are taken at those blocks' first estimates instead of their current values.
// Private to src/core/estimator.
//
// Once the marginalization prior holds a block (the next state after the oldest leaves, the tags
// the leaving state saw, gravity), the prior's Jacobian in it stays at the value it had then,
// x0. Factors added later, linearized at newer values, would see the unobservable directions
// (without a board: the world's position and heading) turned slightly against the prior's, and
// the two together would claim information along them that no measurement gave. With every
// factor's Jacobian in such a block taken at its x0 instead, they share one null space:
//   r(x) as it is,  dr/dx_i evaluated at (x with x_i replaced by x0_i) for the blocks with x0.
// The residual itself stays at the current values (the estimate still moves to what the
// measurements say); Gauss-Newton then works with an approximate Jacobian, close while x stays
// near x0. Jacobians in pose blocks are tangent (state_blocks.h's lift), so the current value's
// manifold applies them unchanged.
#pragma once

#include <ceres/cost_function.h>

#include <memory>
#include <unordered_map>
#include <vector>

namespace mvis {

// A block's first estimate (its ambient values), by block address.
using FirstEstimates = std::unordered_map<const double*, std::vector<double>>;

class FirstEstimateCost final : public ceres::CostFunction {
 public:
  // Takes ownership of `inner`; `blocks` are its parameter blocks in order; `first` outlives it.
  FirstEstimateCost(ceres::CostFunction* inner, std::vector<double*> blocks,
                    const FirstEstimates* first)
      : inner_(inner), blocks_(std::move(blocks)), first_(first) {
    set_num_residuals(inner->num_residuals());
    *mutable_parameter_block_sizes() = inner->parameter_block_sizes();
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    if (jacobians == nullptr) return inner_->Evaluate(parameters, residuals, nullptr);
    std::vector<const double*> at(parameters, parameters + blocks_.size());
    bool any = false;
    for (std::size_t i = 0; i < blocks_.size(); ++i) {
      const auto it = first_->find(blocks_[i]);
      if (it == first_->end()) continue;
      at[i] = it->second.data();
      any = true;
    }
    if (!any) return inner_->Evaluate(parameters, residuals, jacobians);
    std::vector<double> unused(static_cast<std::size_t>(num_residuals()));
    if (!inner_->Evaluate(at.data(), unused.data(), jacobians)) return false;
    return inner_->Evaluate(parameters, residuals, nullptr);
  }

  ceres::CostFunction* inner() const { return inner_.get(); }

 private:
  std::unique_ptr<ceres::CostFunction> inner_;
  std::vector<double*> blocks_;
  const FirstEstimates* first_;
};

}  // namespace mvis
