#include "startup.h"

#include <sstream>

#include "mvis/estimator/initialization.h"

namespace mvis {
namespace estimator_internal {

Startup::Startup(const Rig& rig, const EstimatorOptions& options, CalibrationBlocks& calibration,
                 const ImuBuffer& imu, EstimatorCounters& counters)
    : rig_(rig),
      options_(options),
      calibration_(calibration),
      imu_(imu),
      counters_(counters),
      rotations_(rig.cameras.size()) {}

void Startup::recordRotation(std::size_t c, TimeNs stamp, const SE3& T_G_C) {
  auto& h = rotations_[c];
  if (!h.empty() && stamp <= h.back().first) return;
  h.emplace_back(stamp, T_G_C.rotation());
  while (h.size() > 2 && h.back().first - h.front().first > 2 * kAlignSpanNs) h.pop_front();
}

void Startup::restartCamera(std::size_t c) {
  rotations_[c].clear();
  if (c == 0) frames_.clear();
}

bool Startup::add(TagFrame frame, TimeNs t, const SE3& T_G_C, int pose_tag, std::string* status) {
  const bool landmarks = !rig_.target;
  recordRotation(0, frame.stamp_ns, T_G_C);
  // Consecutive frames only: a gap of more than 0.25 s starts over.
  if (!frames_.empty() && t - frames_.back().t > fromSeconds(0.25)) frames_.clear();
  if (landmarks) {
    // One tag's rotation is ambiguous (a mirrored pose fits about as well) but not its centre:
    // keep the centre in the camera frame, in tag sides; the initialization takes the rotations
    // from the gyroscope.
    frames_.push_back({t, SE3(), std::move(frame), T_G_C.inverse() * tagCorner(2, 0.5)});
  } else {
    frames_.push_back({t, T_G_C * poseToSE3(calibration_.camera(0).extrinsic), std::move(frame)});
  }
  std::ostringstream s;
  s << "initializing: " << frames_.size() << " of " << options_.init_frames << " "
    << rig_.cameras[0].name << " frames with a "
    << (landmarks ? "pose on tag " + std::to_string(pose_tag) : "board pose");
  *status = s.str();
  if (static_cast<int>(frames_.size()) < options_.init_frames) return false;
  if (!clocks_aligned_) {
    const auto& h = rotations_[0];
    if (h.size() < 2 || h.back().first - h.front().first < kAlignSpanNs) {
      *status += "; collecting 1.5 s of board poses to check the camera clocks";
      return false;
    }
    alignClocks();
    clocks_aligned_ = true;
  }
  // Without a board the first batch must also place every tag and tell the extrinsics'
  // translations from where the tags are: it waits for more motion.
  if (landmarks && !frames_.empty() && frames_.back().t - frames_.front().t < kLandmarkBatchNs) {
    std::ostringstream wait;
    wait << "; collecting " << toSeconds(kLandmarkBatchNs) << " s of motion to place the tags";
    *status += wait.str();
    return false;
  }
  // A corrected cam0 clock moves the states later than the readings may reach yet: the next
  // frame comes when they do.
  return !frames_.empty() && imu_.lastStamp() >= frames_.back().t;
}

double Startup::clockCorrection(std::size_t c) const {
  if (imu_.size() < 2) return 0.0;
  const Eigen::Matrix3d R_I_C = poseToSE3(calibration_.camera(c).extrinsic).rotation().transpose();
  return mvis::clockCorrection(
      rotations_[c], R_I_C, calibration_.timeOffsetNs(c), imu_.firstStamp(), imu_.lastStamp(),
      [this](TimeNs t) { return imu_.at(t).gyro; }, kAlignRange);
}

void Startup::alignClocks() {
  std::ostringstream said;
  for (std::size_t c = 0; c < calibration_.cameras(); ++c) {
    const double delta = clockCorrection(c);
    if (std::abs(delta) < 0.002) continue;  // within what the estimator refines anyway
    calibration_.camera(c).time_offset[0] += delta;
    said << " " << rig_.cameras[c].name << " " << (delta > 0 ? "+" : "") << delta * 1e3 << " ms";
    if (c == 0) {
      // The window states sit at cam0's frames: move them with its clock.
      for (auto& f : frames_) f.t = f.frame.stamp_ns + calibration_.timeOffsetNs(0);
      if (!imu_.empty() && frames_.front().t < imu_.firstStamp()) frames_.clear();
    }
  }
  if (!said.str().empty()) {
    ++counters_.clock_corrections;
    clock_message_ = "time offsets corrected from the gyroscope:" + said.str();
  }
}

void Startup::clear(bool clocks_known) {
  frames_.clear();
  for (auto& h : rotations_) h.clear();
  clocks_aligned_ = clocks_known;
}

}  // namespace estimator_internal
}  // namespace mvis
