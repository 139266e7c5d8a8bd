// A tag's landmark block [p_0 p_1 p_2 p_3] (its corners in the world frame, kTagLandmarkSize,
// TagReprojectionFactor::useLandmarkBlock) kept a square: a printed tag is one, of a size not
// known. Seven degrees of freedom instead of twelve: the square's rotation, centre and side.
//
// A square block has side s = |p_1 - p_0|, axes e_x = (p_1 - p_0) / s, e_y = (p_3 - p_0) / s
// (made orthogonal to e_x, against round-off), e_z = e_x x e_y, R = [e_x e_y e_z], centre c (the
// corners' mean) and fixed coordinates q_k = R^T (p_k - c) / s (tagCorner's square about its
// centre: (-1/2, -1/2, 0), (1/2, -1/2, 0), (1/2, 1/2, 0), (-1/2, 1/2, 0)). With the tangent
// d = [dtheta, dc, ds] (rotation on the right, centre, side):
//   Plus(x, d)_k  = c + dc + (s + ds) R Exp(dtheta) q_k   (s + ds at least 1e-9)
//   PlusJacobian  (12 x 7, at d = 0): rows of corner k [-s R [q_k]x, I, R q_k]
//   Minus(y, x)   = [Log(R_x^T R_y), c_y - c_x, s_y - s_x]
//   MinusJacobian (7 x 12, at y = x): (P^T P)^-1 P^T with P = PlusJacobian, so that
//                 MinusJacobian PlusJacobian = I.
// The side moves additively: the square scaled about a camera's centre (the direction one view
// of it cannot tell) is then a straight line in the tangent, dc proportional to ds.
// The block should start as a square (PnP's corners at one side are; Plus(x, 0) makes one).
#pragma once

#include <ceres/manifold.h>

namespace mvis {

class TagLandmarkManifold final : public ceres::Manifold {
 public:
  int AmbientSize() const override { return 12; }
  int TangentSize() const override { return 7; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override;
  bool PlusJacobian(const double* x, double* jacobian) const override;
  bool Minus(const double* y, const double* x, double* y_minus_x) const override;
  bool MinusJacobian(const double* x, double* jacobian) const override;
};

}  // namespace mvis
