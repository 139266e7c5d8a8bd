// Degenerate-motion awareness (report Sec. 5.1, Table 2): which directions of a calibrated
// quantity the recent motion leaves unobservable.
//
// The estimator sums, over the base IMU's readings of the last observability_horizon_s seconds
// (bias-corrected rates w and angular accelerations alpha between 25 ms means), the information
// the rig's rigid motion gives each quantity when the states are known and only the sensor noise
// (density s_n) is left:
//   translation of a camera or aux IMU (its position in {I}):
//       I_p = int (hat(alpha) + hat(w)^2)^T (hat(alpha) + hat(w)^2) dt / s_a^2
//   gyroscope rotation (right perturbation, {I}):  I_R = int hat(w)^T hat(w) dt / s_g^2
//   gyroscope time offset:                         I_t = int |alpha|^2 dt / s_g^2
// (the gyroscope noise's share of hat(alpha)^T hat(alpha) taken out). Their null spaces are the
// report's: rotation about one axis k leaves the translations along k and a gyroscope's rotation
// about k unobservable; no rotation leaves all translations, the gyroscope's rotation and its
// time offset unobservable.
//
// With the quantity's prior standard deviations s (prior information diag(s)^-2), the whitened
// information W = diag(s) I diag(s) says how many times more the motion tells than the prior
// does. Its eigenvalues below `ratio` mark unobservable directions, in tangent coordinates
// diag(s) u for W's eigenvectors u, orthonormalized together. Since I assumes known states, it
// is optimistic, and the estimator's default ratio is large (EstimatorOptions).
#pragma once

#include <Eigen/Core>

namespace mvis {

struct WeakDirections {
  Eigen::MatrixXd directions;  // unit columns, orthonormal, tangent coordinates
  Eigen::VectorXd gains;       // W's eigenvalue per column, ascending
};

WeakDirections weakDirections(const Eigen::MatrixXd& W, const Eigen::VectorXd& prior_std,
                              double ratio);

// Directions held at their value while the estimate goes on, as consider parameters (Schmidt):
// u = U^T y of the stacked tangent vector y is kept at u_h, whose error has the variance
// diag(v) it had when held (its estimate then), while everything else is estimated given u_h:
// E[x | data, u = u_h]. With Sigma the covariance of y with u free (all the information there
// is, u's own included), the error of that estimate has the covariance
//   Sigma' = Sigma + Sigma U S^-1 (diag(v) - S) S^-1 U^T Sigma,   S = U^T Sigma U:
// the conditional covariance Sigma - Sigma U S^-1 U^T Sigma plus what u_h's own error, of
// variance diag(v), moves the rest by (their gain Sigma U S^-1), for a u_h from an estimate that
// the later data only refine (its difference to the estimate with every datum has the variance
// diag(v) - S). U^T Sigma' U = diag(v). Computed as G diag(max(l - 1, 0)) G^T added to Sigma,
// with S = L L^T, L^-1 diag(v) L^-T = Q diag(l) Q^T and G = Sigma U L^-T Q: a direction known
// better now than when held (l < 1: only round-off, or a variance since lowered) adds nothing.
// Sigma unchanged if S is not positive definite. U: orthonormal columns.
Eigen::MatrixXd consideredCovariance(const Eigen::MatrixXd& sigma, const Eigen::MatrixXd& U,
                                     const Eigen::VectorXd& v);

}  // namespace mvis
