// Per-camera bookkeeping of tag-corner observations: for every camera, every feature
// (tag id, corner) maps to its observations in time order, stamped in that camera's clock.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <map>
#include <vector>

#include "mvis/frontend/tag_observation.h"

namespace mvis {

// One corner of a tag in one frame (not the factors' CornerObservation, which is on a board).
struct TrackedCorner {
  TimeNs stamp_ns = 0;  // camera clock
  Eigen::Vector2d uv_px = Eigen::Vector2d::Zero();
};

class TagTracks {
 public:
  using Tracks = std::map<long, std::vector<TrackedCorner>>;  // feature id -> observations

  explicit TagTracks(std::size_t num_cameras) : cameras_(num_cameras) {}

  // Adds every corner of `frame`. Frames may arrive out of order; a frame with a stamp already
  // present for a feature replaces that observation (a duplicate message). Returns false, adding
  // nothing, if frame.camera is not a camera of this rig.
  bool add(const TagFrame& frame);

  // Forgets the observations of `camera` older than `stamp_ns` (camera clock), and features
  // left with none.
  void dropBefore(std::size_t camera, TimeNs stamp_ns);

  const Tracks& camera(std::size_t camera) const { return cameras_.at(camera); }
  std::size_t numCameras() const { return cameras_.size(); }
  std::size_t numObservations() const;

 private:
  std::vector<Tracks> cameras_;
};

}  // namespace mvis
