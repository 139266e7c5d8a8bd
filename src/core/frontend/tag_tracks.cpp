#include "mvis/frontend/tag_tracks.h"

#include <algorithm>

namespace mvis {

bool TagTracks::add(const TagFrame& frame) {
  if (frame.camera >= cameras_.size()) return false;
  Tracks& tracks = cameras_[frame.camera];
  for (const auto& tag : frame.tags) {
    for (int c = 0; c < 4; ++c) {
      auto& track = tracks[featureId(tag.tag_id, c)];
      const TrackedCorner observation{frame.stamp_ns, tag.corners_px[c]};
      const auto at =
          std::lower_bound(track.begin(), track.end(), frame.stamp_ns,
                           [](const TrackedCorner& o, TimeNs stamp) { return o.stamp_ns < stamp; });
      if (at != track.end() && at->stamp_ns == frame.stamp_ns) {
        *at = observation;
      } else {
        track.insert(at, observation);
      }
    }
  }
  return true;
}

void TagTracks::dropBefore(std::size_t camera, TimeNs stamp_ns) {
  Tracks& tracks = cameras_.at(camera);
  for (auto it = tracks.begin(); it != tracks.end();) {
    auto& track = it->second;
    track.erase(track.begin(), std::lower_bound(track.begin(), track.end(), stamp_ns,
                                                [](const TrackedCorner& o, TimeNs stamp) {
                                                  return o.stamp_ns < stamp;
                                                }));
    it = track.empty() ? tracks.erase(it) : std::next(it);
  }
}

std::size_t TagTracks::numObservations() const {
  std::size_t count = 0;
  for (const auto& tracks : cameras_) {
    for (const auto& [feature, track] : tracks) count += track.size();
  }
  return count;
}

}  // namespace mvis
