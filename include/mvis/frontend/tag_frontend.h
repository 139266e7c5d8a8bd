// The tag front end of a rig: one detector per camera, one set of checks, one track store.
// Images and detections made elsewhere take the same path after detection:
//   image ------> TagDetector --+
//                                +--> checkTagFrame --> TagTracks --> the checked frame
//   detections (messages) ------+
// Thread safety: different cameras may be processed concurrently; one camera's frames must
// come one at a time and in time order (as ROS subscription callbacks do): the region searched
// in an image is predicted from the camera's previous images (the tags as found, before their
// corners are refined). locateTags()/finishImage() split that rule.
#pragma once

#include <memory>
#include <mutex>
#include <opencv2/core/mat.hpp>
#include <opencv2/core/types.hpp>
#include <string>
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
  // Predicted regions (mvis's engine): a camera's image is searched for tags only in the box
  // where the tags of its previous image go, moved on at the rate they moved between the two
  // images before, with a margin of a tag's side plus that motion. A tag found in the box has
  // the corners the whole image's search gives, bit for bit. The whole image is searched every
  // full_search_every-th image (a tag coming into view outside the box is found then), after a
  // gap of more than max_prediction_gap_s, when the previous image had no tag, and when the
  // prediction failed: half the tags predicted inside the image missed, or one missed while the
  // tags found are more than half the margin from where they were predicted (the missed one may
  // then be cut by the box's border; one missed well inside the box would be missed by the whole
  // search too: there the two searches see the same).
  // 1: every image searched whole.
  int full_search_every = 10;
  double max_prediction_gap_s = 0.25;

  std::string validate() const;  // empty when usable
};

// What one image or detection message gave.
struct TagFrontendResult {
  TagFrame frame;            // the observations that passed the checks
  TagRejections rejections;  // and what was dropped, why
  // Images: searched in a predicted region only, and that region's share of the image.
  bool predicted_region = false;
  double searched_fraction = 1.0;
  TagDetectionStages stages;  // quads and codes: both searches' when the region's failed
};

// An image's tags found and read in its predicted region (or the whole image), their corners not
// yet refined.
struct LocatedTags {
  TimeNs stamp_ns = 0;
  FoundTags found;
  bool predicted_region = false;
  double searched_fraction = 1.0;
};

// Where a camera's tags will be at `stamp_ns`, from its two previous images' tags (`last` at
// last_ns, `before` at before_ns; before may be empty) in a width x height image: the box to
// search (empty when there is nothing to predict from), its margin, and the tags predicted
// wholly inside the image with their corners.
struct TagPrediction {
  cv::Rect region;
  double margin_px = 0.0;
  std::vector<TagObservation> expected;
};
TagPrediction predictTags(const std::vector<TagObservation>& last, TimeNs last_ns,
                          const std::vector<TagObservation>& before, TimeNs before_ns,
                          TimeNs stamp_ns, int width, int height);

class TagFrontend {
 public:
  static StatusOr<std::unique_ptr<TagFrontend>> create(const Rig& rig, TagFrontendOptions options);

  // Detects, checks and records the tags in `gray` (CV_8UC1) of camera `camera`, stamped
  // `stamp_ns` in the camera's clock. Fails, recording nothing, on a bad camera index or an
  // unusable image (empty, wrong type, size not the camera's resolution).
  StatusOr<TagFrontendResult> processImage(std::size_t camera, TimeNs stamp_ns,
                                           const cv::Mat& gray);

  // processImage() in two steps, for callers that refine one camera's images in parallel:
  // locateTags() finds and reads the tags (one camera's images one at a time and in time order:
  // the region searched is predicted from the camera's previous images), finishImage() refines
  // their corners, checks and records them (any thread, any order).
  StatusOr<LocatedTags> locateTags(std::size_t camera, TimeNs stamp_ns, const cv::Mat& gray);
  StatusOr<TagFrontendResult> finishImage(std::size_t camera, const cv::Mat& gray,
                                          LocatedTags located);

  // Checks and records detections made elsewhere (frame.width/height are set from the rig).
  StatusOr<TagFrontendResult> processDetections(TagFrame frame);

  // A copy of the current tracks (taken under the lock).
  TagTracks tracks() const;
  void dropBefore(std::size_t camera, TimeNs stamp_ns);

 private:
  TagFrontend(const Rig& rig, TagFrontendOptions options);
  TagFrontendResult record(TagFrame frame);

  // A camera's two previous images' tags as found (before refinement and the checks), for the
  // predicted region; touched only by that camera's locateTags.
  struct SearchHistory {
    std::vector<TagObservation> last, before;
    TimeNs last_ns = 0, before_ns = 0;
    int since_full_search = 0;
  };

  std::vector<std::array<int, 2>> resolutions_;
  std::vector<SearchHistory> search_;
  TagFrontendOptions options_;
  std::vector<std::unique_ptr<TagDetector>> detectors_;  // one per camera
  mutable std::mutex mutex_;                             // guards tracks_
  TagTracks tracks_;
};

}  // namespace mvis
