// Tag-corner reprojection factor: every known board corner seen in one camera frame (report
// Eq. 24-26), through a pose interpolation between window states.
//
// A frame stamped t_c in the camera's clock happened at base time t = t_c + t_d. The base-IMU
// pose at t comes from the window states in one of three ways:
//   kinematic (report Appendix A.1; state k next to the frame):
//     dt = t - t_k,  R(t) = R_k Exp((w_m - b_g,k) dt),  p(t) = p_k + v_k dt
//     with w_m the base gyroscope reading at t_k;
//   pose-based (report Appendix A.2; between bounding states k and k+1):
//     s = (t - t_k) / (t_k+1 - t_k),  R(t) = R_k Exp(s Log(R_k^T R_k+1)),
//     p(t) = p_k + s (p_k+1 - p_k);
//   IMU-propagated (mvis's default): the IMU readings are preintegrated from t_k to an anchor
//     time t_a (the frame's base time when the factor was made), with the bias correction of
//     ImuPreintegration (T_a = t_a - t_k, biases b of state k, gravity g):
//       R_a = R_k dR(b_g),  p_a = p_k + v_k T_a + 1/2 g T_a^2 + R_k dp(b),
//       v_a = v_k + g T_a + R_k dv(b)
//     and the remaining dt = t - t_a (the time offset's change since) is covered to second
//     order with the readings at t_a (w_m, a_m; the estimator gives w_m as a line's value at t_a
//     fitted to the gyroscope within 10 ms, not one noisy reading) and the angular
//     acceleration alpha there:
//       R(t) = R_a Exp((w_m - b_g) dt + 1/2 alpha dt^2)
//       p(t) = p_a + v_a dt + 1/2 (R_a (a_m - b_a) + g) dt^2
//     With the IMU intrinsics estimated the deltas also depend on them (x_I, the sensor's
//     intrinsics block, imu_reintegration.h), to first order about x_I0 where they were made:
//       dR = dR0 Exp(J_R_bg db_g) Exp(J_R_I dx_I),  dp += J_p_I dx_I,  dv += J_v_I dx_I
//     so that the frames between states cannot pin the biases along what only the intrinsics
//     and biases together are seen to change (a gravity sensitivity column against a gyroscope
//     bias when one axis stays near vertical).
//     Linear (pose-based) interpolation errs by ~|a| T^2 / 8 between 30 Hz states, ~0.1 px at
//     1 m on the VI-Rig, which biased its extrinsics by ~2 mm in simulation; this does not.
//     The readings' own noise over [t_k, t_a] (optional block n = [n_theta, n_p, n_v], 9 values,
//     with a prior N(0, Sigma) from the preintegration's covariance, made by the estimator):
//       dR = dR0 Exp(n_theta),  dp += n_p,  dv += n_v     (after the intrinsics' change)
//     Without it a frame between states would take the propagation as exact: its corners would
//     know state k's pose better than the readings do, and the time offsets their share of it
//     (with 0.05 px corners the time offsets' std came out below what the base IMU's noise
//     allows along the motion, evaluation.h's timeOffsetFloor).
// A corner p_G is then seen at
//   p_C = R_C_I R(t)^T (p_G - p(t)) + p_C_I
//   z = pi(k, d, p_C) + n,  n ~ N(0, sigma^2 I2)
// with pi the pinhole projection and distortion of mvis/camera/camera_model.h. The residual is
// (pi(...) - z) / sigma for each corner, 2 N residuals. p_G is either a known board point (world =
// board frame) or, without a board (report Eq. 11), a landmark state: the factor then takes one
// more block, a tag's four corners [p_G,0 .. p_G,3] (12 values, world frame), and each corner
// names its index in it; dz/dp_G = dpi/dp_C R_C_G.
//
// Robust loss per corner (optional, useCornerLoss(c), c in sigmas): a corner whose whitened
// residual r (2 values) has n = |r| > c contributes Huber's rho(n^2) = 2 c n - c^2 instead of
// n^2: its residual becomes r' = g u with g = sqrt(2 c n - c^2) and u = r / n, so that |r'|^2 =
// rho, and its Jacobian rows J' = M J with
//   M = dr'/dr = (c / g) u u^T + (g / n) (I - u u^T)
// (M = I at n = c). Corners within c sigmas count fully; a wrong corner weighs like ~c/n of one.
// Without it the estimator may put a loss on the factor's whole squared norm instead
// (EstimatorOptions::robust_loss).
//
// Compressed rows (compressRows(), board factors of the sliding window): Gauss-Newton and
// Levenberg-Marquardt need of a factor only J^T J, J^T r and |r|^2 (Ceres's model, its Jacobi
// scaling, the step's predicted and actual cost change and a loss on the factor's squared norm
// are all functions of these), and the marginalization and covariances only J^T J and J^T r.
// Every corner moves with the camera pose's tangent [omega; v] (R_C_G -> Exp(omega) R_C_G, t_C_G
// -> Exp(omega) t_C_G + v: dp_C = -[p_C]x omega + v) and the camera's intrinsics, so J = Z G
// with Z = [J_6 J_k] (2N x 14, the per-corner loss applied; 2N x 6 without J_k when the
// intrinsics are not estimated) and G the fixed map from the blocks' tangents to those columns.
// With H = Z^T Z = P^T L D L^T P (pivoted LDL^T) and g = Z^T r:
//   rows  S G,  S = D^1/2 L^T P      (S^T S = H)
//   residuals  e = D^-1/2 L^-1 P g   (S^T e = g; pivots under 1e-12 of the largest: 0)
//   and one more residual sqrt(|r|^2 - |e|^2) with zero Jacobian,
// 15 (7) rows in place of 2N (~100-300 on the VI-Rig) with the same J^T J, J^T r and cost, to
// rounding. Without Jacobians only the cost is needed: [|r|, 0, ...]. A compressed factor's
// residuals are not per corner (the batch's residual summary and clustered covariance, and the
// frame gate, evaluate factors that are not compressed).
//
// Parameters:
//   kinematic:       pose_k [7], speed_bias_k [9], extrinsic T_C_I [7], time_offset [1],
//                    intrinsics [8]
//   pose-based:      pose_k [7], pose_k+1 [7], extrinsic [7], time_offset [1], intrinsics [8]
//   IMU-propagated:  pose_k [7], speed_bias_k [9], gravity [3], extrinsic [7], time_offset [1],
//                    intrinsics [8], with the IMU intrinsics the base IMU's block [24], with
//                    the propagation noise its block [9]
//   then, with landmarks, the tag's corners [12]
// Jacobians: the camera pose R_C_G, t_C_G is differentiated once per frame (IMU-propagated: by
// hand, imuCameraTangent; kinematic and pose-based: by forward-mode automatic differentiation)
// in the tangent directions of the blocks (pose and extrinsic
// perturbations on the right, see state_blocks.h; speed and biases; gravity in its ambient
// coordinates; t_d), turned into the camera pose's own tangent [omega; v] (G, 6 x directions:
// omega from dR R^T, v = dt + t x omega), then chained per corner with the projection's analytic
// Jacobian in p_C and in the intrinsics (projectWithJacobians). The IMU intrinsics enter through 9
// more directions, perturbations of the anchor's deltas, chained with J_*_I, as does the
// propagation noise (its rotation part through the right Jacobian of Exp). Pose-block Jacobians are
// written in the tangent lift convention of state_blocks.h.
#pragma once

#include <ceres/cost_function.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>
#include <vector>

#include "mvis/inertial/imu_preintegration.h"
#include "mvis/inertial/imu_reintegration.h"
#include "mvis/rig/rig.h"

namespace mvis {

struct CornerObservation {
  Eigen::Vector3d p_G = Eigen::Vector3d::Zero();  // board point [m] (unused with a landmark)
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();   // detected pixel
  int landmark = -1;  // with a landmark block: the corner's index in it (0-3)
};

// Values in a tag's landmark block: four corners x [x y z] in the world frame.
constexpr int kTagLandmarkSize = 12;
// Values in a frame's propagation-noise block: [n_theta, n_p, n_v] of the anchor's deltas.
constexpr int kPropagationNoiseSize = 9;

class TagReprojectionFactor final : public ceres::CostFunction {
 public:
  enum class Interpolation { kKinematic, kPoseBased, kImuPropagated };

  // What the IMU-propagated interpolation needs from the readings between t_k and t_a.
  struct ImuAnchor {
    double T_a = 0.0;         // t_a - t_k [s]
    double dt_nominal = 0.0;  // t_c - t_a [s] (t_d is added at evaluation)
    Eigen::Quaterniond dR = Eigen::Quaterniond::Identity();
    Eigen::Vector3d dp = Eigen::Vector3d::Zero(), dv = Eigen::Vector3d::Zero();
    Eigen::Vector3d bias_gyro0 = Eigen::Vector3d::Zero(), bias_accel0 = Eigen::Vector3d::Zero();
    Eigen::Matrix3d J_R_bg = Eigen::Matrix3d::Zero(), J_p_bg = Eigen::Matrix3d::Zero(),
                    J_p_ba = Eigen::Matrix3d::Zero(), J_v_bg = Eigen::Matrix3d::Zero(),
                    J_v_ba = Eigen::Matrix3d::Zero();
    Eigen::Vector3d gyro = Eigen::Vector3d::Zero();                  // w_m at t_a [rad/s]
    Eigen::Vector3d accel = Eigen::Vector3d::Zero();                 // a_m at t_a [m/s^2]
    Eigen::Vector3d angular_acceleration = Eigen::Vector3d::Zero();  // [rad/s^2]
    // With the IMU intrinsics: the deltas' Jacobian in them ([dtheta; dp; dv] rows) and where
    // it was taken.
    bool with_intrinsics = false;
    Eigen::Matrix<double, 9, kImuIntrinsicsSize> J_intrinsics =
        Eigen::Matrix<double, 9, kImuIntrinsicsSize>::Zero();
    Eigen::Matrix<double, kImuIntrinsicsSize, 1> intrinsics0 =
        Eigen::Matrix<double, kImuIntrinsicsSize, 1>::Zero();
  };

  // Kinematic: `dt_nominal` = t_c - t_k [s] (t_d added at evaluation), `gyro_k` the base gyroscope
  // reading at t_k.
  static TagReprojectionFactor* kinematic(DistortionModel model,
                                          std::vector<CornerObservation> corners,
                                          double pixel_sigma, double dt_nominal,
                                          const Eigen::Vector3d& gyro_k);
  // Pose-based: `dt_nominal` = t_c - t_k [s], `interval` = t_k+1 - t_k [s].
  static TagReprojectionFactor* poseBased(DistortionModel model,
                                          std::vector<CornerObservation> corners,
                                          double pixel_sigma, double dt_nominal, double interval);

  // The anchor from the readings preintegrated from t_k to t_a, the readings at t_a and the
  // angular acceleration there.
  static ImuAnchor makeAnchor(const ImuPreintegration& pre, double dt_nominal,
                              const Eigen::Vector3d& gyro, const Eigen::Vector3d& accel,
                              const Eigen::Vector3d& angular_acceleration);
  // The anchor from deltas re-integrated from the raw readings (imu_reintegration.h), with
  // their intrinsics columns when `with_intrinsics`.
  static ImuAnchor makeAnchor(const ImuDeltas& deltas, bool with_intrinsics, double dt_nominal,
                              const Eigen::Vector3d& gyro, const Eigen::Vector3d& accel,
                              const Eigen::Vector3d& angular_acceleration);
  static TagReprojectionFactor* imuPropagated(DistortionModel model,
                                              std::vector<CornerObservation> corners,
                                              double pixel_sigma, const ImuAnchor& anchor);

  // The camera pose (stage 1 below) of one frame, shared by the factors of its tags (landmark
  // mode: one factor per tag), computed once per set of parameter values.
  struct SharedCameraPose;
  static std::shared_ptr<SharedCameraPose> makeSharedCameraPose();
  // Shares `shared` with the other factors of the same frame (same anchor and blocks but the
  // landmark). Only with a landmark block; call after useLandmarkBlock.
  void shareCameraPose(std::shared_ptr<SharedCameraPose> shared);

  // The readings' noise over [t_k, t_a] as a block (IMU-propagated only): appends a block of
  // kPropagationNoiseSize values [n_theta, n_p, n_v]. Call before useLandmarkBlock.
  void usePropagationNoise();

  // The corners are landmark states: appends the tag's landmark block (kTagLandmarkSize) as the
  // last parameter; every corner must name its index in it. Call before adding the factor.
  void useLandmarkBlock();

  // Huber loss on each corner's whitened residual at `threshold` sigmas (see the header).
  void useCornerLoss(double threshold) { corner_loss_ = threshold; }

  // Compressed rows (see the header): only without a landmark block and with more corners than
  // half the compressed rows; returns whether the factor is compressed. Without
  // `with_intrinsics` the intrinsics block must stay constant (7 rows instead of 15; a request
  // for its Jacobian fails the evaluation). Call last.
  bool compressRows(bool with_intrinsics);
  static constexpr int kMaxCompressedRows = 15;

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;
  // Every corner's whitened residual (2 per corner, the per-corner loss applied), compressed or
  // not; `residuals` holds 2 x corners().size().
  bool cornerResiduals(double const* const* parameters, double* residuals) const;

  const std::vector<CornerObservation>& corners() const { return corners_; }
  // The index of the landmark block among the parameters, -1 without (useLandmarkBlock).
  int landmarkBlock() const { return landmark_block_; }

 private:
  TagReprojectionFactor(Interpolation interpolation, DistortionModel model,
                        std::vector<CornerObservation> corners, double pixel_sigma,
                        double dt_nominal, double interval, const Eigen::Vector3d& gyro_k);
  // Evaluate with Dim jet directions: 25 (kStageDim), or 34 with the anchor's deltas.
  // per_corner: every corner's residual even when compressed (no Jacobians then).
  template <int Dim>
  bool evaluate(double const* const* parameters, double* residuals, double** jacobians,
                bool per_corner = false) const;
  // The per-corner loss: a whitened residual r beyond the threshold becomes g u and its
  // Jacobian rows M J (see the header); false (nothing changed) within it.
  bool cornerLoss(Eigen::Vector2d* r, Eigen::Matrix2d* M) const;
  // Columns of the compressed rows: the camera pose's tangent (6) and the intrinsics (8).
  static constexpr int kPoseColumns = 6;
  // The camera pose R_C_G, t_C_G at the frame and their derivatives in Dim jet directions.
  template <int Dim>
  struct CameraPose {
    Eigen::Matrix3d R;
    Eigen::Vector3d t;
    Eigen::Matrix<double, 3, Dim> dR[3], dT;  // dR[j]: of R's column j
  };
  template <int Dim>
  void cameraPose(double const* const* parameters, const Eigen::Matrix<double, 9, 1>& lin,
                  CameraPose<Dim>* out) const;
  // IMU-propagated: R_C_G, t_C_G and the camera pose's tangent per jet direction (G), by hand.
  template <int Dim>
  void imuCameraTangent(double const* const* parameters, const Eigen::Matrix<double, 9, 1>& lin,
                        Eigen::Matrix3d* R_CG, Eigen::Vector3d* t_CG,
                        Eigen::Matrix<double, 6, Dim>* G) const;
  // R_C_G, t_C_G on jets or, for the cost alone, doubles; kDeltas: with the anchor's deltas'
  // change (IMU intrinsics or propagation noise).
  template <typename T, bool kDeltas>
  void cameraPose(double const* const* parameters, const Eigen::Matrix<double, 9, 1>& lin,
                  Eigen::Matrix<T, 3, 3>* R_CG, Eigen::Matrix<T, 3, 1>* t_CG) const;
  // Jet offset, tangent columns and ambient size of each parameter block but the intrinsics.
  struct BlockLayout {
    int jet_offset, columns, ambient;
  };
  std::vector<BlockLayout> layout_;
  ImuAnchor anchor_;
  int landmark_block_ = -1;     // index of the landmark block, -1 without
  int noise_block_ = -1;        // index of the propagation-noise block, -1 without
  double corner_loss_ = 0.0;    // Huber threshold per corner [sigma], 0: plain squares
  int compressed_columns_ = 0;  // compressRows(): 6, 14, or 0 (not compressed)
  std::shared_ptr<SharedCameraPose> shared_;

  Interpolation interpolation_;
  DistortionModel model_;
  std::vector<CornerObservation> corners_;
  double sigma_;
  double dt_nominal_;
  double interval_;
  Eigen::Vector3d gyro_k_;
};

}  // namespace mvis
