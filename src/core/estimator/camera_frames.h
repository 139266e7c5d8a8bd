// Camera frames into the window: each camera's frames waiting for the IMU (cam0's make the
// window states, the others are attached between them), and a frame's reprojection factors
// (TagReprojectionFactor: one over its board corners, or without a board one per tag with the
// tag's landmark block), its pose propagated from the state before it with the base readings.
// Private to src/core/estimator.
//
// Owns: the waiting frames, each camera's last frame stamp, the per-frame robust losses.
// Asks of the others: the window (states, factors), the base IMU's readings, the cameras'
// calibration blocks and gravity, the base IMU's intrinsics block and current correction, and
// the landmarks (without a board).
#pragma once

#include <deque>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "calibration_blocks.h"
#include "change_detector.h"
#include "imu_buffer.h"
#include "imu_intrinsics.h"
#include "landmarks.h"
#include "window.h"

namespace mvis {
namespace estimator_internal {

class CameraFrames {
 public:
  CameraFrames(const Rig& rig, const EstimatorOptions& options, Window& window,
               const ImuBuffer& imu, CalibrationBlocks& calibration,
               ImuIntrinsicsBlocks& intrinsics, Landmarks& landmarks, EstimatorCounters& counters);

  // Without a board one tag is a frame's worth: four corners of a landmark (a rig among
  // scattered tags often sees only one); with one, options.min_tags.
  int minTags() const;
  // Whether the frame is newer than its camera's last one (then it becomes the last).
  bool markNewer(const TagFrame& frame);
  // Queues a frame (at most 300 per camera wait: the oldest are dropped as too old).
  void enqueue(TagFrame frame);

  bool hasBaseFrame() const { return !base_.empty(); }
  const TagFrame& nextBaseFrame() const { return base_.front(); }
  TagFrame takeBaseFrame();

  // Adds the frame's factors to the window, owned by window state k (or its successor).
  // `initialized`: the window runs (the first batch has the loss per frame).
  void add(const TagFrame& frame, std::size_t k, bool initialized);
  // Places every waiting frame of the other cameras that falls inside the window.
  void attachWaiting(bool initialized);
  void clear();
  // With a board and options.frame_gate_sigma > 0, frames whose corners' median whitened
  // residual at the current estimate is 3 times the camera's recent frames' (and over 2 sigma)
  // are dropped before they enter, and so are frames over `sigma` and, in the frames kept,
  // single corners over `sigma` (0: no such bound; the estimator sets options.frame_gate_sigma
  // once a calibration is trusted).
  void setGate(double sigma) { gate_sigma_ = sigma; }
  // With a board, every frame the gate looks at (kept or dropped) is also evidence for `changes`
  // (its residuals and their Jacobian in the camera's extrinsic and time offset); null: none.
  void setChangeDetector(ChangeDetector* changes) { changes_ = changes; }
  // Camera c moved and was re-opened: its recent residuals (the gate's baseline) are forgotten.
  void forgetCamera(std::size_t c) { recent_.at(c).clear(); }
  // Camera c's frames stay out of the next first batch (the window starts over because it
  // moved: its new calibration is a guess until its frames inform it in the running window).
  void holdOutOfFirstBatch(std::size_t c) { held_out_.at(c) = true; }
  // Without a board: frames owned by a state before `k` enter with the carried tags only (the
  // first batch's states that are cut to the window; 0: every tag, the default).
  void carriedTagsOnlyBefore(std::size_t k) { carried_only_before_ = k; }
  // The cameras' recent residuals and the bound are forgotten (the calibration starts over from
  // the configured one: its residuals are not the cameras').
  void forgetResiduals();
  // The newest base time at which a frame entered the window (lowest TimeNs: none yet).
  TimeNs lastEntered() const { return last_entered_; }
  // The latest rejection's message (then empty).
  std::string takeWarning() { return std::move(warning_); }
  // After the first batch's solve without a board, with RobustLoss::kCorner: each of its tags'
  // factors whose corners are clean at the solution (RMS whitened corner residual within 2
  // sigma) takes the loss per corner that every later frame has, in place of its loss per
  // frame. That one is needed while the rough starting calibration makes the residuals, but it
  // counts a clean frame of N corners like about 3 sqrt(N/2) of them, and the prior the batch
  // leaves keeps that: without a board every later pose stands on it (the world is the first
  // state), and the pose covariance of a whole run was too large. A factor still off (a fault
  // going on while the batch restarts) keeps its loss per frame. With a board the poses are seen
  // against it again and the batch keeps its loss per frame (settled there, it left imu0's and
  // imu1's Tg 1.7-2.7x further off in test CalibratesImuIntrinsicsByReintegration). Returns the
  // number of factors changed (the batch is then solved again before it is marginalized).
  int settleFirstBatch();
  // Forgets the batch's losses: the problem their factors were in has been dropped.
  void dropBatchLosses();

 private:
  struct Piece {
    ceres::CostFunction* cost;
    ceres::LossFunction* loss;
    std::vector<double*> blocks;
  };
  // The frame's factors (and, with options.propagation_noise, the prior of its propagation-noise
  // block, owned by the state); empty when the frame cannot be used.
  std::vector<Piece> factors(const TagFrame& frame, std::size_t k, bool initialized);
  // The loss of each of a frame's T tag factors without a board: Huber at huber_sigma /
  // sqrt(T), so that the frame weighs as it would as one factor with the board (the Huber on
  // its whole norm counts a frame of N corners like about 3 sqrt(N/2) of them, see
  // RobustLoss::kFrame). Used with RobustLoss::kFrame (the first batch's with kCorner are
  // batch_losses_).
  ceres::LossFunction* tagLoss(int tags);
  // The frame's residuals and their Jacobian in its camera's [extrinsic tangent, time offset],
  // to the change detector; returns each corner's whitened residual norm (empty if the factor
  // could not be evaluated).
  std::vector<double> addEvidence(const ceres::CostFunction& factor,
                                  const std::vector<double*>& blocks, const TagFrame& frame);
  // The camera's pose at the frame: state k's carried there with the readings.
  SE3 cameraPoseAt(const TagFrame& frame, std::size_t k) const;

  const Rig& rig_;
  const EstimatorOptions& options_;
  Window& window_;
  const ImuBuffer& imu_;
  CalibrationBlocks& calibration_;
  ImuIntrinsicsBlocks& intrinsics_;
  Landmarks& landmarks_;
  EstimatorCounters& counters_;
  std::deque<TagFrame> base_;                  // cam0's, waiting for the IMU
  std::vector<std::deque<TagFrame>> waiting_;  // the other cameras', waiting for the window
  std::vector<TimeNs> last_;
  // The loss per frame (options.huber_sigma), null for plain squares; without a board per number
  // of tags in the frame. The loss per corner lives in the factor (useCornerLoss).
  std::unique_ptr<ceres::LossFunction> huber_;
  std::map<int, std::unique_ptr<ceres::LossFunction>> tag_losses_;
  // Without a board and with RobustLoss::kCorner the first batch's factors have a loss per frame
  // each, in a wrapper that settleFirstBatch() may empty (plain squares, the loss per corner then
  // in the factor); they stay as long as the problem (dropBatchLosses()).
  std::vector<std::unique_ptr<ceres::LossFunctionWrapper>> batch_losses_;
  bool batch_settled_ = false;
  double gate_sigma_ = 0.0;
  ChangeDetector* changes_ = nullptr;
  std::size_t carried_only_before_ = 0;
  std::vector<std::deque<double>> recent_;  // per camera, its entered frames' median residuals
  std::vector<bool> held_out_;              // holdOutOfFirstBatch()
  std::string warning_;
  TimeNs last_entered_ = std::numeric_limits<TimeNs>::min();
};

}  // namespace estimator_internal
}  // namespace mvis
