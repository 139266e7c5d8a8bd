// The inertial sensors' intrinsics (report Eq. 1-4, Sec. 2.2): per sensor either a correction of
// its readings by the configured intrinsics (applied on arrival), or, while they are estimated,
// a parameter block (imu_reintegration.h) with its prior and latest covariance, the readings
// left raw for the factors to re-integrate. Private to src/core/estimator.
//
// Owns: the blocks, the configured corrections and the base IMU's current estimate as a
// correction (for IMU-rate propagation). Asks nothing of the other parts.
#pragma once

#include <ceres/ceres.h>

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "calibration_blocks.h"
#include "mvis/inertial/imu_correction.h"
#include "mvis/inertial/imu_reintegration.h"

namespace mvis {
namespace estimator_internal {

// An inertial sensor's intrinsics block while they are estimated.
struct ImuIntrinsicsBlock {
  double x[kImuIntrinsicsSize];
  double initial[kImuIntrinsicsSize];  // the configured values (IntrinsicsLinearization::kFixed)
  ImuIntrinsicsFrame frame;
  Eigen::Matrix<double, kImuIntrinsicsSize, 1> prior_std;
  // Holds the entries that are not estimated (a gyroscope's all but Dw and Tg; Tg unless
  // gravity sensitivity is estimated); null when every entry is.
  std::unique_ptr<ceres::Manifold> manifold;
  std::vector<int> free;  // the entries that are estimated: the tangent's directions, in order
  // Latest covariance of the block (ambient; zero rows for the held entries), if computed.
  std::optional<Eigen::Matrix<double, kImuIntrinsicsSize, kImuIntrinsicsSize>> covariance;
};

class ImuIntrinsicsBlocks {
 public:
  ImuIntrinsicsBlocks(const Rig& rig, const EstimatorOptions& options);

  // Adds the estimated sensors' blocks with their priors.
  void addTo(ceres::Problem* problem, const TrustedCalibration& trusted);
  // Every estimated block with its name, for the trusted calibration (as
  // CalibrationBlocks::trustedBlocks).
  std::vector<TrustedCalibration::Block> trustedBlocks(const ceres::Problem* problem);
  std::size_t sensors() const { return blocks_.size(); }
  // Sensor i's block, or null when its intrinsics are not estimated.
  ImuIntrinsicsBlock* block(std::size_t i) { return blocks_[i].get(); }
  const ImuIntrinsicsBlock* block(std::size_t i) const { return blocks_[i].get(); }
  double* values(std::size_t i) { return blocks_[i] ? blocks_[i]->x : nullptr; }
  bool isBlock(const double* x) const;
  // What sensor i's readings are corrected with on arrival: the configured intrinsics, or
  // identity while they are estimated.
  const ImuCorrection& arrivalCorrection(std::size_t i) const { return arrival_[i]; }
  // The base IMU's current estimate as a correction (identity when not estimated), for readings
  // used as they are (IMU-rate propagation, frame anchors): refreshed by refreshBase().
  const ImuCorrection& baseCorrection() const { return base_; }
  void refreshBase();
  // Sensor i's current estimate as a correction of its readings as they arrived, when its
  // intrinsics are estimated (arrival leaves them as they are then); nullopt when not.
  std::optional<ImuCorrection> estimatedCorrection(std::size_t i) const;
  // The biases to subtract from readings corrected by baseCorrection() for raw biases bg, ba.
  void baseBiases(const Eigen::Vector3d& bg, const Eigen::Vector3d& ba, Eigen::Vector3d* bg_out,
                  Eigen::Vector3d* ba_out) const {
    base_.biases(bg, ba, bg_out, ba_out);
  }
  void covarianceBlocks(const ceres::Problem& problem,
                        std::vector<std::pair<const double*, const double*>>* blocks) const;
  // Every estimated block's covariance from a computed covariance (held whole: kept).
  void updateCovariance(const ceres::Problem& problem, const TangentCovariance& tangent);
  // Latest standard deviations / covariance of a block in its own tangent (the prior's before
  // any covariance); empty / unset for another block.
  Eigen::VectorXd latestStd(const double* x) const;
  std::optional<Eigen::MatrixXd> latestCovariance(const double* x) const;
  // The current intrinsics (and standard deviations) into `out`.
  void write(Rig* out) const;
  // The estimated blocks to `start`'s intrinsics (the priors and the frame, R0, unchanged).
  void setValues(const Rig& start);

 private:
  std::vector<std::unique_ptr<ImuIntrinsicsBlock>> blocks_;
  std::vector<std::string> names_;  // the sensors'
  std::vector<ImuCorrection> arrival_;
  ImuCorrection base_;
};

}  // namespace estimator_internal
}  // namespace mvis
