// Degenerate-motion awareness (report Sec. 5.1, Tables 2-3; observability.h): what the base
// IMU's recent motion and the inertial sensors' recent readings tell each estimated calibration
// quantity, which directions they leave unobservable, and holding those directions (a subspace
// manifold, or constant when held whole) at the standard deviation they had until the motion
// tells them again. Private to src/core/estimator.
//
// Owns: the motion's and readings' information over the horizon, the latest findings
// (unobservable(), uninformative()) and the holds. Reads the calibration and IMU-intrinsics
// blocks (their values, priors and latest standard deviations); changes only the manifolds and
// constancy of the blocks it holds, in the problem it is handed.
#pragma once

#include <ceres/ceres.h>

#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "block_covariance.h"
#include "calibration_blocks.h"
#include "imu_intrinsics.h"

namespace mvis {
namespace estimator_internal {

// The intrinsics element a weak direction mostly moves (its tangent entries' ambient indices
// `elements`), as the report writes them: dw12 (Dw row 1, column 2), da33, tg21, and "theta_y"
// for the accelerometer rotation about y (kalibr model: "theta_g_y" for the gyroscope's).
std::string intrinsicsElementName(const std::vector<int>& elements,
                                  const Eigen::VectorXd& direction, bool kalibr);

class ObservabilityMonitor {
 public:
  ObservabilityMonitor(const Rig& rig, const EstimatorOptions& options,
                       const CalibrationBlocks& calibration, const ImuIntrinsicsBlocks& intrinsics);

  // Adds the base motion between window states at a and b (its readings over [a, b] and the gyro
  // bias there; with `R_a` the base IMU's orientation at a (R_W_I) and `gravity` the gravity
  // vector, also how gravity and the kinematic acceleration go in its frame (parallelViews,
  // accelerationAlong; kept only while the cameras' intrinsics are estimated, which is when they
  // are asked; a zero gravity leaves them out).
  void addMotion(TimeNs a, TimeNs b, const std::vector<ImuMeasurement>& readings,
                 const Eigen::Vector3d& bias_gyro,
                 const Eigen::Quaterniond& R_a = Eigen::Quaterniond::Identity(),
                 const Eigen::Vector3d& gravity = Eigen::Vector3d::Zero());
  // Adds inertial sensor i's readings between window states (the later at t), for its
  // intrinsics (ignored unless they are estimated). For the base IMU also gravity in its frame
  // along them, g_I = R^T g, from `R_start` (its orientation at the first reading, R = R_W_I) and
  // the rates less `bias_gyro`: what tells a scale of the kinematic acceleration from the
  // accelerometer's own (intrinsicsQuantities).
  void addReadingMoments(std::size_t i, TimeNs t, const std::vector<ImuMeasurement>& readings,
                         const Eigen::Quaterniond& R_start = Eigen::Quaterniond::Identity(),
                         const Eigen::Vector3d& gravity = Eigen::Vector3d::Zero(),
                         const Eigen::Vector3d& bias_gyro = Eigen::Vector3d::Zero());
  // Finds what the recent motion leaves unobservable, holds it and releases what it no longer
  // does.
  void check(ceres::Problem* problem);
  // The latest findings, and per block the tangent directions (orthonormal columns) that what
  // leaves the window must not inform.
  const std::vector<UnobservableCalibration>& unobservable() const { return unobservable_; }
  const std::map<const double*, Eigen::MatrixXd>& uninformative() const { return uninformative_; }
  // What the marginalization must not learn along: per block the held directions (orthonormal
  // tangent columns), marginalized as unknown. Held extrinsic and time offset directions are not
  // in it unless the cameras' intrinsics are estimated, the IMU intrinsics' (considered) and
  // the gauge's anchor (anchors()) never (see the definition).
  std::map<const double*, Eigen::MatrixXd> heldDirections() const;

  // The block's own manifold, also while it is held.
  const ceres::Manifold* baseManifold(const ceres::Problem& problem, const double* block) const;
  // Whether a block is estimated (not constant, or constant only while held).
  bool estimated(const ceres::Problem& problem, const double* block) const;
  // Covariance of a block in its own manifold's tangent (held directions with the variance they
  // keep); NaN where the block was not in the computation.
  Eigen::MatrixXd tangentCovariance(const ceres::Problem& problem, const BlockCovariance& cov,
                                    const double* block) const;
  // The same for several blocks jointly (stacked in the order given, cross-covariances too);
  // empty if one was not in the computation. With `considered_lifted` the considered blocks (see
  // below) were computed lifted, in their own tangents, and get no kept variance here; `offsets`
  // gets each block's first row and size.
  Eigen::MatrixXd jointTangentCovariance(
      const ceres::Problem& problem, const BlockCovariance& cov,
      const std::vector<const double*>& blocks, bool considered_lifted = false,
      std::map<const double*, std::pair<int, int>>* offsets = nullptr) const;
  // The pose blocks' covariances with the held directions released at the uncertainty they
  // kept: with them constant it would be as if they were known.
  Status poseCovarianceWithHeld(ceres::Problem* problem, const std::vector<double*>& poses,
                                std::vector<Eigen::Matrix<double, 6, 6>>* out);
  bool holding() const { return !holds_.empty(); }
  bool holds(const double* block) const { return holds_.count(block) > 0; }

  // The IMU intrinsics' held directions as consider parameters (Schmidt's consider analysis;
  // held_covariance.cpp): what leaves the window is marginalized with them as with any kept
  // block, so the prior holds what every leaving measurement told about them and across them
  // (heldDirections leaves them out), the solves hold them at their value, and the covariance
  // releases them to add what their held value's own uncertainty V makes of everything else:
  //   Sigma' = Sigma + Sigma_.u Sigma_uu^-1 (V - Sigma_uu) Sigma_uu^-1 Sigma_u.
  // (Sigma with them free: the information they have). Whether any such direction is held now.
  bool considering() const;
  // Those blocks freed (their own manifolds, variable) for a covariance, and held again.
  void liftConsidered(ceres::Problem* problem) { liftHolds(problem, true); }
  void restoreConsidered(ceres::Problem* problem) { restoreHolds(problem, true); }
  // With the considered blocks lifted: the joint tangent covariance of `blocks` (each in its own
  // manifold's tangent, other holds as jointTangentCovariance has them) with the correction
  // above; `offsets` gets each block's first row and size. Empty if a block was not in the
  // computation.
  Eigen::MatrixXd considerCovariance(const ceres::Problem& problem, const BlockCovariance& cov,
                                     const std::vector<const double*>& blocks,
                                     std::map<const double*, std::pair<int, int>>* offsets) const;
  // The joint check's cost: seconds in total and how many times it ran.
  double windowCheckSeconds() const { return window_check_s_; }
  long windowChecks() const { return window_checks_; }
  // Forgets everything (the problem the holds were in is gone).
  void clear();

 private:
  // What the base IMU's motion between consecutive states tells the calibration (per unit
  // noise density).
  struct MotionInformation {
    TimeNs t = 0;                                           // the later state's time
    Eigen::Matrix3d translation = Eigen::Matrix3d::Zero();  // int (hat(a) + hat(w)^2)^T (...) dt
    double translation_var = 0.0;  // its noise's variance along any direction (at most)
    Eigen::Matrix3d rotation = Eigen::Matrix3d::Zero();  // int hat(w)^T hat(w) dt
    double time_offset = 0.0;      // int |alpha|^2 dt, less the noise's share (may be < 0)
    double time_offset_var = 0.0;  // that estimate's variance from the gyroscope's noise
    // Over the readings, in the base IMU's frame: gravity g_I = R^T g and the kinematic
    // acceleration k = a + g_I (a the specific force): T = int dt, int g dt, int g g^T dt,
    // int k dt, int k k^T dt (all zero without the orientation).
    double T = 0.0, span = 0.0;  // span: the readings' whole time, with or without it
    Eigen::Vector3d g = Eigen::Vector3d::Zero(), k = Eigen::Vector3d::Zero();
    Eigen::Matrix3d gg = Eigen::Matrix3d::Zero(), kk = Eigen::Matrix3d::Zero();
  };
  // Whether the recent views of the board are parallel (Sturm and Maybank 1999): gravity's
  // direction in the base IMU turned by less than 5 deg (RMS about its mean, widest axis) over
  // the horizon (hand-held motion: 8-11 deg per 5 s; translation-only and yaw-only over a flat
  // board: 0). False without the orientations over at least 2 s and most of the horizon's
  // motion (right after the start the few states in it looked parallel on hand-held motion).
  bool parallelViews() const;
  // The RMS kinematic acceleration along the unit direction n (base frame) over the horizon
  // [m/s^2] (yaw-only motion along the VI-Rig cameras' axis: 0.01; translation-only and
  // hand-held: 0.6); -1 when unknown (as parallelViews).
  double accelerationAlong(const Eigen::Vector3d& n) const;
  // Time-weighted moments of one sensor's readings between two window states.
  struct ReadingMoments {
    TimeNs t = 0;    // the later state's time
    double T = 0.0;  // [s] covered
    int n = 0;       // readings
    Eigen::Vector3d w = Eigen::Vector3d::Zero(), a = Eigen::Vector3d::Zero();    // int x dt
    Eigen::Matrix3d ww = Eigen::Matrix3d::Zero(), aa = Eigen::Matrix3d::Zero();  // int x x^T dt
    Eigen::Matrix3d wa = Eigen::Matrix3d::Zero();                                // int w a^T dt
    // Gravity in the sensor's frame g_I (base IMU only, else zero): int g dt, int g g^T dt,
    // int w g^T dt, int a g^T dt.
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    Eigen::Matrix3d gg = Eigen::Matrix3d::Zero(), wg = Eigen::Matrix3d::Zero(),
                    ag = Eigen::Matrix3d::Zero();
  };
  // A block held along its unobservable directions: its own manifold, the subspace manifold in
  // use (null: held whole, constant), the held directions and the variance each keeps.
  struct Hold {
    ceres::Manifold* base = nullptr;
    std::unique_ptr<SubspaceManifold> subspace;
    Eigen::MatrixXd directions;
    Eigen::VectorXd variance;
    std::uint64_t sequence = 0;  // when first held: an order that is not the block's address
  };
  // One calibrated quantity: rows [offset, offset + size) of its block's tangent, and the
  // information the recent motion gives it (tangent coordinates).
  struct Quantity {
    std::string sensor, name;
    const double* block;
    int offset, size;
    Eigen::VectorXd prior_std;
    Eigen::Matrix3d to_I;  // tangent coordinates to the base IMU frame
    Eigen::MatrixXd information;
    // IMU intrinsics only: the channel ("gyro", "gravity", "accel"), the block's tangent rows
    // (instead of offset..offset+size) and their ambient entries in the intrinsics block.
    std::string symbol = {};
    std::vector<int> rows = {};
    std::vector<int> elements = {};
    bool kalibr = false;      // the block's parametrization (imu_reintegration.h)
    std::string advice = {};  // what motion would tell it, where the generic words are wrong
  };

  // The window's information about every estimated calibration block jointly
  // (window_information.h), whitened by the blocks' priors and restricted to what the checks
  // above left free: its directions with less than `window_observability_ratio` are held too,
  // each block's share of them (observability_window.cpp).
  void windowCheck(ceres::Problem* problem);
  // Adds the joint check's parts to uninformative_ and its findings to unobservable_.
  void holdWindowParts();
  // The holds (or only the considered ones) lifted (own manifolds, variable) and put back.
  // With `keep_anchor` the gauge's anchor (below) stays held.
  void liftHolds(ceres::Problem* problem, bool considered_only = false, bool keep_anchor = false) {
    setHolds(problem, false, considered_only, keep_anchor);
  }
  void restoreHolds(ceres::Problem* problem, bool considered_only = false,
                    bool keep_anchor = false) {
    setHolds(problem, true, considered_only, keep_anchor);
  }
  void setHolds(ceres::Problem* problem, bool held, bool considered_only, bool keep_anchor);
  void spatialQuantities(const ceres::Problem& problem, std::vector<Quantity>* out) const;
  void intrinsicsQuantities(const ceres::Problem& problem, std::vector<Quantity>* out) const;
  void applyHolds(ceres::Problem* problem);
  // The considered holds' directions as the columns U of a stacked tangent vector of `rows`
  // (each block's at its first row, `at`: (row, block)) and the variances v they kept.
  void consideredColumns(const std::vector<std::pair<int, const double*>>& at, int rows,
                         Eigen::MatrixXd* U, Eigen::VectorXd* v) const;
  // An IMU intrinsics block whose held directions are considered (above).
  bool considered(const double* block) const;
  // The cameras' common position on the base IMU as a gauge (online, the cameras' intrinsics
  // estimated; spatialQuantities): the first camera's translation held, the others not held
  // (`followers_`, found by check()) and placed by the images relative to it. Nothing tells
  // their common shift d on the motion that held it (with imu0's positions shifted by -R_W_I
  // d, every residual is the same), so the solves and the marginalization take the anchor as
  // known (kept, not forgotten: the prior conditioned on it, as the solves are), and every
  // covariance adds what the anchor's kept variance V moves along that shift, G V G^T, with
  // G = d(block's tangent) / d(anchor's held coordinates) (gaugeMap).
  bool anchors(const double* block) const;
  // G for a block (its tangent rows x the anchor's held directions); empty if the gauge does
  // not move it. `pose`: a window state's pose block (its position moves by -R_W_I d).
  Eigen::MatrixXd gaugeMap(const double* block, bool pose = false) const;
  // The gauge's variances along the anchor's held directions (empty without a gauge).
  Eigen::VectorXd gaugeVariance() const;
  void findFollowers(const ceres::Problem& problem);
  // The latest tangent covariance of a calibration block: the full one for IMU intrinsics once
  // computed, else diag(latest std^2).
  Eigen::MatrixXd latestCovariance(const double* block) const;

  const Rig& rig_;
  const EstimatorOptions& options_;
  const CalibrationBlocks& calibration_;
  const ImuIntrinsicsBlocks& intrinsics_;
  std::deque<MotionInformation> motion_;
  std::vector<std::deque<ReadingMoments>> moments_;  // per inertial sensor
  std::vector<UnobservableCalibration> unobservable_;
  std::map<const double*, Eigen::MatrixXd> uninformative_;
  std::map<const double*, Hold> holds_;
  std::uint64_t holds_made_ = 0;
  std::set<const double*> window_blocks_;  // blocks holding a part of a joint weak direction
  std::vector<const double*> followers_;   // the cameras' extrinsics following the anchor
  std::vector<std::pair<const double*, Eigen::VectorXd>> window_parts_;  // (block, direction)
  std::vector<UnobservableCalibration> window_found_;
  long solves_since_window_check_ = 0;
  bool window_weak_ = false;  // the last joint check found weak directions (release at 4x)
  double window_check_s_ = 0.0;
  long window_checks_ = 0;
  bool consider_ = false;  // the IMU intrinsics' holds as consider parameters (online only)
};

}  // namespace estimator_internal
}  // namespace mvis
