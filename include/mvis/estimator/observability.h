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

}  // namespace mvis
