// AprilTag detection in one grayscale image, wrapping libapriltag (which stays out of this
// header). Corners come out in mvis's pixel convention ((0, 0) at the centre of the top-left
// pixel), half a pixel from libapriltag's own.
#pragma once

#include <cstdint>
#include <memory>
#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

#include "mvis/common/status.h"
#include "mvis/frontend/tag_observation.h"

namespace mvis {

struct TagDetectorOptions {
  std::string family = "tag36h11";  // any of supportedTagFamilies()
  double decimate = 2.0;            // quad detection on an image this many times smaller (>= 1);
                                    // edges and corners are refined at full resolution
  double blur_sigma = 0.0;          // Gaussian blur [px] before quad detection; < 0 sharpens
  bool refine_edges = true;         // snap quad edges to strong gradients at full resolution
  double decode_sharpening = 0.25;
  int threads = 1;             // libapriltag worker threads
  int max_hamming = 1;         // bits the decoder may correct (0..2); more invites wrong ids
  bool refine_corners = true;  // mvis's edge-based sub-pixel refinement (corner_refinement.h)

  std::string validate() const;  // empty when usable
};

// The printed patterns of a family's first `count` tags: one byte per cell (0 black, 255 white),
// row-major, row 0 at the top of the upright tag. The detected square spans the middle
// width_at_border cells; the rest is the outer ring.
struct TagPatterns {
  int total_width = 0;
  int width_at_border = 0;
  std::vector<std::vector<std::uint8_t>> cells;  // per tag id
};
StatusOr<TagPatterns> tagFamilyPatterns(const std::string& family, int count);

class TagDetector {
 public:
  static StatusOr<std::unique_ptr<TagDetector>> create(const TagDetectorOptions& options);
  ~TagDetector();
  TagDetector(const TagDetector&) = delete;
  TagDetector& operator=(const TagDetector&) = delete;

  // Every tag found in `gray` (CV_8UC1, any stride). Nothing is filtered here beyond what the
  // decoder does; pass the result through checkTagFrame(). An empty or non-8-bit image gives an
  // error, never a crash.
  StatusOr<std::vector<TagObservation>> detect(const cv::Mat& gray) const;

  const TagDetectorOptions& options() const { return options_; }

 private:
  struct Impl;
  TagDetector(const TagDetectorOptions& options, std::unique_ptr<Impl> impl);
  TagDetectorOptions options_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mvis
