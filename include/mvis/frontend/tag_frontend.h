// The tag front end of a rig: one detector per camera, one set of checks, one track store.
// Images and detections made elsewhere take the same path after detection:
//   image ------> TagDetector --+
//                                +--> checkTagFrame --> TagTracks --> the checked frame
//   detections (messages) ------+
// Thread safety: different cameras may be processed concurrently; one camera's frames must
// come one at a time (as ROS subscription callbacks do).
#pragma once

#include <memory>
#include <mutex>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "mvis/common/status.h"
#include "mvis/frontend/tag_checks.h"
#include "mvis/frontend/tag_detector.h"
#include "mvis/frontend/tag_tracks.h"
#include "mvis/rig/rig.h"

namespace mvis {

struct TagFrontendOptions {
  TagDetectorOptions detector;  // family and tag_spacing are taken from the rig's board if any
  TagCheckOptions checks;       // checks.num_board_tags likewise
};

// What one image or detection message gave.
struct TagFrontendResult {
  TagFrame frame;            // the observations that passed the checks
  TagRejections rejections;  // and what was dropped, why
};

class TagFrontend {
 public:
  static StatusOr<std::unique_ptr<TagFrontend>> create(const Rig& rig, TagFrontendOptions options);

  // Detects, checks and records the tags in `gray` (CV_8UC1) of camera `camera`, stamped
  // `stamp_ns` in the camera's clock. Fails, recording nothing, on a bad camera index or an
  // unusable image (empty, wrong type, size not the camera's resolution).
  StatusOr<TagFrontendResult> processImage(std::size_t camera, TimeNs stamp_ns,
                                           const cv::Mat& gray);

  // Checks and records detections made elsewhere (frame.width/height are set from the rig).
  StatusOr<TagFrontendResult> processDetections(TagFrame frame);

  // A copy of the current tracks (taken under the lock).
  TagTracks tracks() const;
  void dropBefore(std::size_t camera, TimeNs stamp_ns);

 private:
  TagFrontend(const Rig& rig, TagFrontendOptions options);
  TagFrontendResult record(TagFrame frame);

  std::vector<std::array<int, 2>> resolutions_;
  TagFrontendOptions options_;
  std::vector<std::unique_ptr<TagDetector>> detectors_;  // one per camera
  mutable std::mutex mutex_;                             // guards tracks_
  TagTracks tracks_;
};

}  // namespace mvis
