// Before the window runs: cam0's frames with a board pose (or, without a board, a pose on one
// tag of unknown side) collected for the initialization (initialization.h), and every camera's
// board rotations for the clock alignment: each camera's angular velocity from consecutive board
// poses, rotated into the IMU frame with the extrinsic guess, matched against the gyroscope over
// offsets within +-kAlignRange (a driver stamping on arrival, another clock); a clear best match
// replaces the configured offset. Private to src/core/estimator.
//
// Owns: the initialization frames, the board rotations, whether the clocks were aligned and what
// that changed. Asks of the others: the base IMU's readings, and the cameras' calibration blocks
// (it corrects their time offsets).
#pragma once

#include <deque>
#include <string>
#include <utility>
#include <vector>

#include "calibration_blocks.h"
#include "imu_buffer.h"

namespace mvis {
namespace estimator_internal {

struct InitFrame {
  TimeNs t = 0;  // base clock
  SE3 T_G_I;     // unused without a board (the initialization makes it)
  TagFrame frame;
  // Without a board: the pose tag's centre in cam0's frame [tag sides].
  Eigen::Vector3d scaled = Eigen::Vector3d::Zero();
};

class Startup {
 public:
  static constexpr TimeNs kAlignSpanNs = 1500000000;  // 1.5 s of board poses
  static constexpr double kAlignRange = 0.3;          // [s]
  // Without a board: the first batch's span (it places every tag from the motion).
  static constexpr TimeNs kLandmarkBatchNs = 4000000000;  // 4 s

  Startup(const Rig& rig, const EstimatorOptions& options, CalibrationBlocks& calibration,
          const ImuBuffer& imu, EstimatorCounters& counters);

  // A camera's board pose T_G_C (without a board: on its pose tag) at a frame stamp.
  void recordRotation(std::size_t c, TimeNs stamp, const SE3& T_G_C);
  // The camera's pose tag changed (no board): its rotations (and cam0's frames) start over.
  void restartCamera(std::size_t c);
  // A cam0 frame at base time t with its board pose T_G_C (or pose on tag `pose_tag`, >= 0
  // without a board). Whether the initialization can run now; *status says what it waits for.
  bool add(TagFrame frame, TimeNs t, const SE3& T_G_C, int pose_tag, std::string* status);
  // cam0 saw no pose: consecutive frames start over.
  void noPose() { frames_.clear(); }

  std::deque<InitFrame>& frames() { return frames_; }
  bool empty() const { return frames_.empty(); }
  TimeNs oldestTime() const { return frames_.front().t; }
  // The initialization failed: the older half of the frames is dropped.
  void dropOlderHalf() { frames_.erase(frames_.begin(), frames_.begin() + frames_.size() / 2); }
  // What the clock alignment changed ("" if nothing).
  const std::string& clockMessage() const { return clock_message_; }
  // Everything collected is dropped; `clocks_known` (a restart from a trusted calibration):
  // the clocks are not aligned again.
  void clear(bool clocks_known = false);

 private:
  // The offset correction of camera c [s], or 0 when the data do not decide it.
  double clockCorrection(std::size_t c) const;
  void alignClocks();

  const Rig& rig_;
  const EstimatorOptions& options_;
  CalibrationBlocks& calibration_;
  const ImuBuffer& imu_;
  EstimatorCounters& counters_;
  std::deque<InitFrame> frames_;
  std::vector<std::deque<std::pair<TimeNs, Eigen::Matrix3d>>> rotations_;  // per camera
  bool clocks_aligned_ = false;
  std::string clock_message_;
};

}  // namespace estimator_internal
}  // namespace mvis
