// Checking a Ceres cost function's Jacobians against central differences through the manifolds
// of its parameter blocks.
#pragma once

#include <ceres/cost_function.h>
#include <ceres/manifold.h>
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <vector>

namespace mvis::test {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Residuals of `cost` at `blocks`.
inline Eigen::VectorXd evaluateResiduals(const ceres::CostFunction& cost,
                                         const std::vector<std::vector<double>>& blocks) {
  std::vector<const double*> params;
  for (const auto& b : blocks) params.push_back(b.data());
  Eigen::VectorXd r(cost.num_residuals());
  EXPECT_TRUE(cost.Evaluate(params.data(), r.data(), nullptr));
  return r;
}

// Analytic tangent Jacobians (ambient Jacobian times PlusJacobian) of every block but `skip`
// (its Jacobian not asked for, left empty); the same evaluation's residuals in `residuals`.
inline std::vector<Eigen::MatrixXd> analyticTangentJacobians(
    const ceres::CostFunction& cost, const std::vector<std::vector<double>>& blocks,
    const std::vector<const ceres::Manifold*>& manifolds, Eigen::VectorXd* residuals = nullptr,
    int skip = -1) {
  const int rows = cost.num_residuals();
  std::vector<const double*> params;
  std::vector<RowMatrix> ambient;
  std::vector<double*> jac;
  for (const auto& b : blocks) {
    params.push_back(b.data());
    ambient.emplace_back(rows, static_cast<int>(b.size()));
  }
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    jac.push_back(static_cast<int>(i) == skip ? nullptr : ambient[i].data());
  }
  Eigen::VectorXd r(rows);
  EXPECT_TRUE(cost.Evaluate(params.data(), r.data(), jac.data()));
  if (residuals != nullptr) *residuals = r;
  std::vector<Eigen::MatrixXd> out;
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    if (static_cast<int>(i) == skip) {
      out.emplace_back();
      continue;
    }
    if (manifolds[i] == nullptr) {
      out.emplace_back(ambient[i]);
      continue;
    }
    RowMatrix plus(manifolds[i]->AmbientSize(), manifolds[i]->TangentSize());
    manifolds[i]->PlusJacobian(blocks[i].data(), plus.data());
    out.emplace_back(ambient[i] * plus);
  }
  return out;
}

// Central differences in each tangent direction: (r(x [+] h e) - r(x [+] -h e)) / 2h.
inline std::vector<Eigen::MatrixXd> numericTangentJacobians(
    const ceres::CostFunction& cost, const std::vector<std::vector<double>>& blocks,
    const std::vector<const ceres::Manifold*>& manifolds, double h) {
  std::vector<Eigen::MatrixXd> out;
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    const int n = manifolds[i] ? manifolds[i]->TangentSize() : static_cast<int>(blocks[i].size());
    Eigen::MatrixXd J(cost.num_residuals(), n);
    for (int k = 0; k < n; ++k) {
      Eigen::VectorXd r[2];
      for (int side = 0; side < 2; ++side) {
        auto moved = blocks;
        Eigen::VectorXd delta = Eigen::VectorXd::Zero(n);
        delta[k] = side == 0 ? h : -h;
        if (manifolds[i] != nullptr) {
          manifolds[i]->Plus(blocks[i].data(), delta.data(), moved[i].data());
        } else {
          moved[i][k] += delta[k];
        }
        r[side] = evaluateResiduals(cost, moved);
      }
      J.col(k) = (r[0] - r[1]) / (2.0 * h);
    }
    out.push_back(J);
  }
  return out;
}

// Largest |analytic - numeric| over all blocks, relative to max(1, |numeric|) per entry.
inline double jacobianMismatch(const std::vector<Eigen::MatrixXd>& analytic,
                               const std::vector<Eigen::MatrixXd>& numeric) {
  double worst = 0.0;
  for (std::size_t i = 0; i < analytic.size(); ++i) {
    EXPECT_EQ(analytic[i].rows(), numeric[i].rows());
    EXPECT_EQ(analytic[i].cols(), numeric[i].cols());
    const Eigen::ArrayXXd scale = numeric[i].array().abs().max(1.0);
    worst = std::max(worst, ((analytic[i] - numeric[i]).array().abs() / scale).maxCoeff());
  }
  return worst;
}

}  // namespace mvis::test
