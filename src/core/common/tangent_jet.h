// Forward-mode differentiation in the tangent spaces of the estimator's blocks, shared by the
// factors that differentiate with ceres::Jet. Private to src/core (src/core/factors and the
// inertial re-integration).
//
// A factor picks a jet dimension per tangent direction of its blocks (pose and extrinsic blocks
// perturbed on the right, R Exp(dtheta), p + dp; plain vectors in their ambient coordinates),
// seeds them with perturbRotation / perturbVector, evaluates its residual on jets and writes the
// derivatives with writeJacobians, in the tangent-lift convention of state_blocks.h (the
// columns past a block's tangent are zero).
#pragma once

#include <ceres/jet.h>
#include <ceres/rotation.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <type_traits>
#include <vector>

namespace mvis {
namespace tangent_jet {

template <typename T>
using Mat3 = Eigen::Matrix<T, 3, 3>;
template <typename T>
using Vec3 = Eigen::Matrix<T, 3, 1>;

template <typename T>
Mat3<T> expT(const Vec3<T>& w) {
  Mat3<T> R;
  ceres::AngleAxisToRotationMatrix(w.data(), R.data());  // column major, as Eigen
  return R;
}

template <typename T>
Vec3<T> logT(const Mat3<T>& R) {
  Vec3<T> w;
  ceres::RotationMatrixToAngleAxis(R.data(), w.data());
  return w;
}

template <typename T>
Mat3<T> hatT(const Vec3<T>& w) {
  Mat3<T> W;
  W << T(0.0), -w[2], w[1], w[2], T(0.0), -w[0], -w[1], w[0], T(0.0);
  return W;
}

// R Exp(delta) with delta the jet directions first..first+2; plain R for doubles.
template <typename T>
Mat3<T> perturbRotation(const Eigen::Quaterniond& q, int first) {
  if constexpr (std::is_same_v<T, double>) {
    return q.toRotationMatrix();
  } else {
    Vec3<T> delta;
    for (int i = 0; i < 3; ++i) delta[i] = T(0.0, first + i);
    return q.toRotationMatrix().cast<T>() * expT(delta);
  }
}

// x[0..2] with the jet directions first..first+2; plain values for doubles.
template <typename T>
Vec3<T> perturbVector(const double* x, int first) {
  Vec3<T> out;
  for (int i = 0; i < 3; ++i) {
    if constexpr (std::is_same_v<T, double>) {
      out[i] = x[i];
    } else {
      out[i] = T(x[i], first + i);
    }
  }
  return out;
}

// One scalar with jet direction `index`; plain for doubles.
template <typename T>
T perturbScalar(double x, int index) {
  if constexpr (std::is_same_v<T, double>) {
    return x;
  } else {
    return T(x, index);
  }
}

// As perturbScalar, but a direction the jet type does not have (a factor's optional block
// while it is differentiated without it) leaves x plain.
template <typename T>
T perturbScalarIfPresent(double x, int index) {
  if constexpr (std::is_same_v<T, double>) {
    return x;
  } else {
    return index < T::DIMENSION ? T(x, index) : T(x);
  }
}

// Where a parameter block's tangent directions sit in the jet, how many there are, and the
// block's ambient size.
struct BlockLayout {
  int jet_offset, columns, ambient;
};

// Residual values and row-major Jacobians of every requested block from jet residuals r.
template <typename Jet>
void writeJacobians(const Jet* r, int n_residuals, const std::vector<BlockLayout>& layout,
                    double* residuals, double** jacobians) {
  for (int i = 0; i < n_residuals; ++i) residuals[i] = r[i].a;
  if (jacobians == nullptr) return;
  for (std::size_t b = 0; b < layout.size(); ++b) {
    if (jacobians[b] == nullptr) continue;
    const BlockLayout& l = layout[b];
    for (int i = 0; i < n_residuals; ++i) {
      double* row = jacobians[b] + l.ambient * i;
      for (int j = 0; j < l.columns; ++j) row[j] = r[i].v[l.jet_offset + j];
      for (int j = l.columns; j < l.ambient; ++j) row[j] = 0.0;
    }
  }
}

}  // namespace tangent_jet
}  // namespace mvis
