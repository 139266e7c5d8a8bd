// IMU intrinsics as estimator states, and the re-integration of raw readings with them (report
// Eq. 1-4 and Sec. 2.2).
//
// Intrinsics block of one inertial sensor (24 doubles, kImuIntrinsicsSize):
//   [0..5]   Dw = Tw^-1, upper triangular, column-wise: d11 d12 d22 d13 d23 d33
//   [6..11]  Da = Ta^-1, the same
//   [12..20] Tg, row-major [rad/s per m/s^2]
//   [21..23] theta [rad]: R_ACCtoIMU = R0 Exp(theta), R0 = R_IMUtoACC^T of the configuration
// so that a reading (w_m, a_m) with biases (b_g, b_a) corrects to (report Eq. 3-4)
//   a = R_ACCtoIMU Da (a_m - b_a),   w = Dw (w_m - b_g - Tg a).
// A gyroscope has no accelerometer: w = Dw (w_m - b_g - Tg a) with a the specific force at the
// gyroscope in its frame, given as the reading's accel (the base IMU's brought to it,
// aux_sensors.h; zero when its Tg is not modelled); Da and theta are unused, and its deltas dp,
// dv zero.
// Identity intrinsics are Dw = Da = I, Tg = 0, theta = 0.
//
// The kalibr model (rig.h; ImuIntrinsicsFrame::kalibr) uses the same block for its own
// parametrization: Dw, Da lower triangular, stored as their transposes' upper entries (entry
// upperIndex(r, c) is D(c, r)), and the rotation on the gyroscope instead:
//   [21..23] theta [rad]: R_GYROtoIMU = R0 Exp(theta), R0 = R_IMUtoGYRO^T of the configuration
//   a = Da (a_m - b_a),   w = R_GYROtoIMU Dw (w_m - b_g - Tg a).
//
// Re-integration: the deltas dR, dp, dv of ImuPreintegration (same midpoint scheme) computed from
// the raw readings at given biases and intrinsics, x = [b_g(3) b_a(3) intrinsics(24)]
// (kDeltaVariables), with their exact derivatives in x propagated by hand along the integration
// (each reading's corrected values differentiated in x, then carried through the midpoint step):
// J (9 x 30), rows [dtheta; dp; dv] with dR(x + d) = dR(x) Exp(J_theta d) to first order. A factor
// evaluated at x re-integrates there (no first-order bias correction, the report's remedy for the
// local minimum of a fixed intrinsics linearization); the same struct also serves first-order
// correction about a fixed x0 (correct()), which is what preintegration with fixed linearization
// does.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

#include "mvis/inertial/imu_preintegration.h"
#include "mvis/rig/rig.h"

namespace mvis {

constexpr int kImuIntrinsicsSize = 24;
constexpr int kDeltaVariables = 6 + kImuIntrinsicsSize;

// Offsets inside the intrinsics block.
struct ImuIntrinsicsLayout {
  static constexpr int kDw = 0, kDa = 6, kTg = 12, kAccRotation = 21;
};

// Position of the upper-triangular element (r, c), r <= c, among the 6 column-wise entries.
constexpr int upperIndex(int r, int c) { return c * (c + 1) / 2 + r; }

// Writes `in` as a block relative to the rotation R0 = in.R_IMUtoACC^T (kalibr:
// in.R_IMUtoGYRO^T), theta = 0.
void intrinsicsToBlock(const ImuIntrinsics& in, double* block, bool kalibr = false);
// The rpng intrinsics of a block whose rotation is relative to R0 (R_ACCtoIMU at theta = 0).
ImuIntrinsics intrinsicsFromBlock(const double* block, const Eigen::Matrix3d& R0);
// The upper-triangular matrix of 6 column-wise entries.
Eigen::Matrix3d upperTriangular(const double* d);

// How a factor with an intrinsics block gets its deltas.
enum class IntrinsicsLinearization {
  kReintegrate,  // re-integrated at every evaluation (report Sec. 2.2; the default)
  kFixed,        // first order about a fixed point, the configured intrinsics (Xiao et al.'s
                 // preintegration; the report finds it drifts into a local minimum; kept for
                 // comparison)
};

// What a sensor's readings are corrected with, besides the block: R0 and whether it is a
// gyroscope.
struct ImuIntrinsicsFrame {
  Eigen::Matrix3d R0 = Eigen::Matrix3d::Identity();  // R_ACCtoIMU (kalibr: R_GYROtoIMU) at 0
  bool gyro_only = false;
  bool kalibr = false;  // the kalibr model's parametrization (see above)
};

// The intrinsics of a block in its frame's model (rpng or kalibr).
ImuIntrinsics intrinsicsFromBlock(const double* block, const ImuIntrinsicsFrame& frame);

struct ImuDeltas {
  using Vector30d = Eigen::Matrix<double, kDeltaVariables, 1>;
  Vector30d x0 = Vector30d::Zero();  // where they were integrated
  Eigen::Matrix3d dR = Eigen::Matrix3d::Identity();
  Eigen::Vector3d dp = Eigen::Vector3d::Zero(), dv = Eigen::Vector3d::Zero();
  Eigen::Matrix<double, 9, kDeltaVariables> J = Eigen::Matrix<double, 9, kDeltaVariables>::Zero();
  double duration = 0.0;  // [s]
};

// x = [b_g b_a intrinsics] from its parts (intrinsics null: identity).
ImuDeltas::Vector30d deltaVariables(const double* bias_gyro, const double* bias_accel,
                                    const double* intrinsics);

// Integrates the readings at x; with `jacobians`, J holds the exact derivatives (else zero).
ImuDeltas reintegrate(const std::vector<ImuMeasurement>& samples, const ImuDeltas::Vector30d& x,
                      const ImuIntrinsicsFrame& frame, bool jacobians);

// A preintegration's deltas and first-order bias Jacobians at its bias linearization point (the
// intrinsics columns zero: its readings are taken as calibrated).
ImuDeltas deltasOf(const ImuPreintegration& pre);

// The deltas an inertial factor evaluates with at x (imu_factor.h): without an intrinsics block
// the preintegration's, with one re-integrated at x (kReintegrate; Jacobians only when
// `jacobians`) or `fixed` (kFixed). `local` holds what is computed here.
const ImuDeltas& factorDeltas(const ImuPreintegration& pre, bool intrinsics,
                              IntrinsicsLinearization mode, const ImuDeltas& fixed,
                              const ImuDeltas::Vector30d& x, const ImuIntrinsicsFrame& frame,
                              bool jacobians, ImuDeltas* local);

// The inverses of the maps that carry a reading's noise into its corrected value (w = G (w_m -
// ...), a = M (a_m - ...): G^-1, M^-1; a gyroscope's M^-1 = I) at `intrinsics`, applied to the
// rotation, position and velocity parts of `r` (rows 0-2 by G^-1, 3-5 and 6-8 by M^-1), and the
// result's derivative in the intrinsics at fixed r (if `jacobian`), and G^-1, M^-1 themselves
// (imu_factor.h: the whitening by the current intrinsics).
void noiseMapInverses(const double* intrinsics, const ImuIntrinsicsFrame& frame,
                      const Eigen::Matrix<double, 9, 1>& r, Eigen::Matrix<double, 9, 1>* out,
                      Eigen::Matrix<double, 9, kImuIntrinsicsSize>* jacobian,
                      Eigen::Matrix3d* G_inv, Eigen::Matrix3d* M_inv);

}  // namespace mvis
