// What the front end hands the estimator: tag corners seen by one camera in one image.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <vector>

#include "mvis/common/time.h"

namespace mvis {

// One tag in one image. Corners are raw (distorted) pixel coordinates with (0, 0) at the centre
// of the top-left pixel, in the contract's order: 0 bottom-left, 1 bottom-right, 2 top-right,
// 3 top-left of the upright tag.
struct TagObservation {
  int tag_id = -1;
  std::array<Eigen::Vector2d, 4> corners_px;
  int hamming = 0;  // bits corrected by the decoder (0 for detections made elsewhere)
};

// Every tag one camera saw in one image.
struct TagFrame {
  std::size_t camera = 0;  // index into Rig::cameras
  TimeNs stamp_ns = 0;     // mid-exposure, in the camera's own clock
  int width = 0;           // image size [px]
  int height = 0;
  std::vector<TagObservation> tags;
};

// Feature id of corner `corner` (0..3) of tag `tag_id`: stable across images and cameras.
inline long featureId(int tag_id, int corner) { return 4L * tag_id + corner; }

}  // namespace mvis
