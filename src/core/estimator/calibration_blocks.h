// The spatial and temporal calibration as parameter blocks: every camera's extrinsic T_C_I, time
// offset and intrinsics, every auxiliary sensor's extrinsic T_i_b (a gyroscope's rotation) and
// time offset, and gravity in the world frame; with their priors and their latest standard
// deviations. Private to src/core/estimator.
//
// Owns: those blocks (they always exist; options and holds only make them constant), their
// priors and standard deviations. Asks nothing of the other parts: the window's problem and the
// covariance are handed in by whoever solves.
#pragma once

#include <ceres/ceres.h>
#include <ceres/sphere_manifold.h>

#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "block_covariance.h"
#include "mvis/estimator/estimator.h"
#include "mvis/factors/state_blocks.h"
#include "mvis/rig/rig.h"
#include "trusted_calibration.h"

namespace mvis {
namespace estimator_internal {

// Whether options.hold holds `quantity` of `sensor` at its configured value.
bool heldByOption(const EstimatorOptions& options, const std::string& sensor, const char* quantity);

// Prior standard deviations of an extrinsic and time offset: the configuration's *_std values
// where positive, the defaults elsewhere.
struct CalibrationPrior {
  Eigen::Vector3d rotation, translation;
  double time_offset;
};

struct CameraBlocks {
  double extrinsic[kPoseSize];  // T_C_I
  double time_offset[1];        // [s]
  double intrinsics[kIntrinsicsSize];
  CalibrationPrior prior;  // of the extrinsic and time offset
  // The camera moved during the run (ChangeDetector): its priors are the options' defaults.
  bool moved = false;
  // Of [fu fv pu pv k1 k2 k3 k4] (used when the intrinsics are estimated).
  Eigen::Matrix<double, kIntrinsicsSize, 1> intrinsics_prior =
      Eigen::Matrix<double, kIntrinsicsSize, 1>::Zero();
};

// An auxiliary IMU's or gyroscope's calibration (rig.inertial[sensor], sensor >= 1).
struct AuxCalibration {
  std::size_t sensor = 0;
  bool gyro = false;
  double extrinsic[kPoseSize];     // T_i_b (IMUs)
  double rotation[kRotationSize];  // the rotation of T_i_b (gyroscopes)
  double time_offset[1];           // [s], t_imu0 = t_i + time_offset
  CalibrationPrior prior;          // of the extrinsic (or rotation) and time offset
  std::optional<InertialCalibrationStd> std;
  bool moved = false;  // moved during the run (as CameraBlocks::moved)

  double* extrinsicBlock() { return gyro ? rotation : extrinsic; }
  // The extrinsic rotation R_AI and translation p_AI of T_i_b (p_A = R_AI p_I + p_AI).
  void extrinsicParts(Eigen::Matrix3d* R_AI, Eigen::Vector3d* p_AI) const;
};

// A block's covariance in its own tangent (held directions with the variance they keep).
using TangentCovariance = std::function<Eigen::MatrixXd(const double* block)>;

class CalibrationBlocks {
 public:
  CalibrationBlocks(const Rig& rig, const EstimatorOptions& options);

  // Adds gravity and every camera's and auxiliary sensor's blocks with their priors, constant
  // where the options or holds say so. The priors are the configured ones, or where `trusted`
  // has a covariance of a block (after a restart) that.
  void addTo(ceres::Problem* problem, const TrustedCalibration& trusted);
  // Every block with its name and values, for the trusted calibration; estimated where it is
  // variable in `problem` (none when null).
  std::vector<TrustedCalibration::Block> trustedBlocks(const ceres::Problem* problem);
  // The blocks addTo made constant for the whole run (held by the options).
  const std::set<const double*>& fixedBlocks() const { return fixed_; }

  std::size_t cameras() const { return cameras_.size(); }
  CameraBlocks& camera(std::size_t c) { return *cameras_[c]; }
  const CameraBlocks& camera(std::size_t c) const { return *cameras_[c]; }
  // Index sensor - 1.
  std::size_t auxiliaries() const { return aux_.size(); }
  AuxCalibration& aux(std::size_t i) { return *aux_[i]; }
  const AuxCalibration& aux(std::size_t i) const { return *aux_[i]; }
  double* gravity() { return gravity_; }

  // Camera c moved (change_detector.h): its extrinsic's and time offset's priors in `problem`
  // become the options' defaults centred on their current values, for the rest of the run, and
  // their standard deviations the prior's until the next covariance (null `problem`: for the
  // next problem only).
  void reopenCamera(std::size_t c, ceres::Problem* problem);
  // The same for auxiliary sensor `sensor` - 1 = i (its extrinsic or rotation, time offset).
  void reopenAux(std::size_t i, ceres::Problem* problem);
  // Camera c's time offset [ns].
  TimeNs timeOffsetNs(std::size_t c) const { return fromSeconds(cameras_[c]->time_offset[0]); }
  // Camera c with its current intrinsics.
  Camera currentCamera(std::size_t c) const;
  // The blocks the first batch holds: the auxiliary sensors' and the cameras' intrinsics, and
  // with `trusted` (a restart from a trusted calibration) the cameras' extrinsics and time
  // offsets too.
  std::vector<double*> batchHeldBlocks(bool trusted);
  // The estimated (non-constant) blocks whose covariance is wanted.
  void covarianceBlocks(const ceres::Problem& problem,
                        std::vector<std::pair<const double*, const double*>>* blocks) const;
  // Standard deviations from a computed covariance. Blocks held whole keep theirs: held by the
  // options 0 (not estimated), held by the motion the last computed one, or before any its
  // prior's (the uncertainty it is held at, as the held directions of a partly held block).
  void updateStd(const ceres::Problem& problem, const TangentCovariance& tangent);
  // Latest standard deviations of a camera or auxiliary calibration block in its own tangent
  // (the prior's before any covariance); empty for another block.
  Eigen::VectorXd latestStd(const double* block) const;
  // The current calibration into `out` (a copy of the configured rig).
  void write(Rig* out) const;
  // The blocks to `start`'s values (a rig of the same sensors; the priors are unchanged).
  void setValues(const Rig& start);

 private:
  const Rig& rig_;
  const EstimatorOptions& options_;
  std::vector<std::unique_ptr<CameraBlocks>> cameras_;
  std::vector<std::unique_ptr<AuxCalibration>> aux_;  // index sensor - 1
  std::set<const double*> fixed_;                     // fixedBlocks()
  // The cameras' extrinsic and time offset priors in the problem (null: the trusted calibration's
  // joint prior stands instead).
  std::map<const double*, ceres::ResidualBlockId> prior_ids_;
  // In the problem, constant, and not held by the options (held whole by the motion, or by the
  // first batch).
  bool heldWholeByMotion(const ceres::Problem& problem, const double* block) const;
  // An auxiliary sensor's extrinsic (a gyroscope's rotation) prior at its current value.
  static ceres::CostFunction* auxExtrinsicPrior(const AuxCalibration& a);
  // The priors of a re-opened extrinsic and time offset in `problem` replaced by these (owned;
  // deleted when `problem` is null).
  void replacePriors(ceres::Problem* problem, double* extrinsic,
                     ceres::CostFunction* extrinsic_prior, double* time_offset,
                     ceres::CostFunction* time_offset_prior);
  double gravity_[kGravitySize] = {0.0, 0.0, -9.81};
  std::optional<std::vector<CameraCalibrationStd>> camera_std_;
  PoseManifold pose_manifold_;
  RotationManifold rotation_manifold_;
  ceres::SphereManifold<3> sphere_manifold_;
};

}  // namespace estimator_internal
}  // namespace mvis
