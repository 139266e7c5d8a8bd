// Rejection of tag observations that cannot be right. Detections from the image detector and
// detections that arrive as messages both pass through here, so the estimator sees one kind of
// input whatever its source.
#pragma once

#include <string>
#include <vector>

#include "mvis/frontend/tag_observation.h"

namespace mvis {

struct TagCheckOptions {
  int num_board_tags = -1;        // ids must be in [0, num_board_tags); -1: no board, any id >= 0
  int max_hamming = 1;            // bits the decoder may have corrected
  double min_side_px = 6.0;       // shortest side of the quad [px]
  double min_angle_deg = 20.0;    // every interior angle in [min, 180 - min] [deg]
  bool reject_duplicates = true;  // the same id twice in one image: drop every copy

  std::string validate() const;  // empty when usable
};

// Why observations were dropped, counted.
struct TagRejections {
  int non_finite = 0;  // NaN or inf corner
  int outside = 0;     // corner outside the image
  int unknown_id = 0;  // id not on the configured board
  int hamming = 0;     // too many corrected bits
  int degenerate = 0;  // non-convex, too small or too thin quad
  int duplicate = 0;   // the same id more than once in one image (all copies are dropped)

  int total() const { return non_finite + outside + unknown_id + hamming + degenerate + duplicate; }
  // e.g. "2 outside the image, 1 unknown id"; empty when nothing was rejected.
  std::string describe() const;
};

// Keeps the observations of `frame` that pass every check; adds the others to `rejections`.
void checkTagFrame(TagFrame* frame, const TagCheckOptions& options, TagRejections* rejections);

}  // namespace mvis
