// One end of an auxiliary sensor's factor (aux_imu_factor.h, gyro_factor.h): the sensor's pose
// and velocity at window state k from the base state, the extrinsic and the time offset, with
// their derivatives by hand. Private to src/core/factors.
//
// With delta = t_d - t_d0,k, the base readings of base_motion.h (w_m, a_m, alpha) and
//   phi = (w_m - b_g,k) delta + 1/2 alpha delta^2,   u = a_m - b_a,k,   a = R_k u + g,
//   R_k' = R_k Exp(phi),   p_k' = p_k + v_k delta + 1/2 a delta^2        (base_motion.h)
//   R_A = R_k' R_AI^T,     p_A = p_k' - R_A p_AI                          (Eq. 38-39)
//   v_A = the aux velocity state (kVelocityState), or (kRigidVelocity, Eq. 78)
//   v_A = v_k + a delta + R_k' y,   y = w x p_IA,   w = R_AI^T (w^A_m - b^A_g,k),
//   p_IA = -R_AI^T p_AI.
// Rotations are perturbed on the right (R Exp(d), state_blocks.h), R_A's derivative is that of
// its right tangent theta_A, and with Jr = Jr(phi), omega = w_m - b_g,k + alpha delta:
//   theta_A: d/dtheta_k = R_AI Exp(phi)^T,  d/db_g = -delta R_AI Jr,  d/dt_d = R_AI Jr omega,
//            d/dtheta_AI = -R_AI
//   p_A:     R_A [p_AI]x d theta_A (every column) plus d/dtheta_k = -1/2 delta^2 R_k [u]x,
//            d/dp_k = I, d/dv_k = delta I, d/db_a = -1/2 delta^2 R_k, d/dg = 1/2 delta^2 I,
//            d/dt_d = v_k + a delta, d/dp_AI = -R_A
//   v_A (rigid): d/dv_k = I, d/dtheta_k = -delta R_k [u]x - R_k' [y]x Exp(phi)^T,
//            d/db_g = delta R_k' [y]x Jr, d/db_a = -delta R_k, d/dg = delta I,
//            d/dt_d = a - R_k' [y]x Jr omega, d/db^A_g = R_k' [p_IA]x R_AI^T,
//            d/dtheta_AI = R_k' [y]x ([w]x[p_IA]x - [p_IA]x[w]x = [w x p_IA]x),
//            d/dp_AI = -R_k' [w]x R_AI^T
//   v_A (state): d/dv_A = I.
// Checked against central differences by the factors' tests (test_aux_factors).
#pragma once

#include <Eigen/Core>

#include "mvis/factors/base_motion.h"

namespace mvis {
namespace aux_end {

// Columns of an end's Jacobian: the base state's rotation, position, velocity, gyroscope and
// accelerometer biases, the extrinsic's rotation and translation, the time offset, gravity, and
// the aux block's own three (v^A with kVelocityState, b^A_g with kRigidVelocity).
enum Column {
  kR = 0,
  kP = 3,
  kV = 6,
  kBg = 9,
  kBa = 12,
  kE = 15,
  kT = 18,
  kTd = 21,
  kG = 22,
  kAux = 25,
  kColumns = 28
};

struct End {
  Eigen::Matrix3d R;  // R_G_A
  Eigen::Vector3d p;  // p_G_A (computed when `position`)
  Eigen::Vector3d v;  // v^A (computed when `velocity`)
  // Rows theta_A 0-2, p_A 3-5, v_A 6-8; filled when asked for.
  Eigen::Matrix<double, 9, kColumns> J;
};

struct Inputs {
  const BaseMotion* motion;
  const double* pose;        // [q_G_I p_G_I] of state k
  const double* speed_bias;  // [v b_g b_a] of state k
  Eigen::Matrix3d R_AI;
  Eigen::Vector3d p_AI;
  double delta;          // t_d - t_d0,k [s]
  Eigen::Vector3d g;     // gravity [m/s^2]
  bool position = true;  // p_A (and the velocity) wanted; the gyroscope only needs R_A
  bool velocity_state = true;
  const double* aux = nullptr;                         // v^A (velocity state) or b^A_g (rigid)
  Eigen::Vector3d aux_gyro = Eigen::Vector3d::Zero();  // w^A_m at the end (rigid)
};

// The end's pose and velocity, and with `jacobian` their derivatives.
End evaluate(const Inputs& in, bool jacobian);

// Where a parameter block's columns sit in a factor's tangent Jacobian D.
struct BlockColumns {
  int column, tangent, ambient;
};

// Writes each requested block's rows of D (N x C, row-major out) in the tangent lift convention
// of state_blocks.h: the columns past the block's tangent are zero.
template <int N, int C>
void writeBlocks(const Eigen::Matrix<double, N, C>& D, const BlockColumns* blocks, int count,
                 double** jacobians) {
  for (int b = 0; b < count; ++b) {
    if (jacobians[b] == nullptr) continue;
    const BlockColumns& l = blocks[b];
    Eigen::Map<Eigen::Matrix<double, N, Eigen::Dynamic, Eigen::RowMajor>> out(jacobians[b], N,
                                                                              l.ambient);
    out.leftCols(l.tangent) = D.middleCols(l.column, l.tangent);
    out.rightCols(l.ambient - l.tangent).setZero();
  }
}

}  // namespace aux_end
}  // namespace mvis
