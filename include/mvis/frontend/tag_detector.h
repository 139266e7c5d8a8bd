// AprilTag detection in one grayscale image. Corners come out in mvis's pixel convention ((0, 0)
// at the centre of the top-left pixel) and order.
//
// Two engines. mvis's own (the default, for the families whose bits lie inside a black border:
// tag36h11, tag25h9, tag16h5) finds tags on plain boards and on Kalibr AprilGrids alike, where
// the black squares between the tags touch every tag's corners (tag_quads.h says how), reads
// their codes (tag_reading.h) and refines the corners knowing the code (corner_refinement.h).
// libapriltag's (use_libapriltag, and always for the other families) cannot see AprilGrids;
// its corners are refined the same way where the family allows. libapriltag stays out of this
// header.
#pragma once

#include <cstdint>
#include <memory>
#include <opencv2/core/mat.hpp>
#include <opencv2/core/types.hpp>
#include <string>
#include <vector>

#include "mvis/common/status.h"
#include "mvis/frontend/tag_observation.h"

namespace mvis {

struct TagDetectorOptions {
  std::string family = "tag36h11";  // any of supportedTagFamilies()
  bool use_libapriltag = false;     // libapriltag's detector instead of mvis's (no AprilGrids)
  double decimate = 1.0;            // quads searched in an image this many times smaller (>= 1);
                                    // codes and corners are read at full resolution
  int max_hamming = 1;              // bits the decoder may correct (0..2); more invites wrong ids
  bool refine_corners = true;       // sub-pixel corners from the edges (corner_refinement.h)
  // Plain tags: the sides moved by what the tags' stripes show of the camera's response (a
  // gamma moves edges into the black; measureEdgeShift), one shift per image.
  bool response_correction = true;
  double min_contrast = 20.0;  // mvis engine: black to white of a tag at least [grey levels]
  double tag_spacing = 0.0;    // the board's gap between tags / tag size (aprilgrid.yaml's
                               // tagSpacing); 0: a lone tag, white only in its ring
  // libapriltag engine only:
  double blur_sigma = 0.0;   // Gaussian blur [px] before quad detection; < 0 sharpens
  bool refine_edges = true;  // snap quad edges to strong gradients at full resolution
  double decode_sharpening = 0.25;
  int threads = 1;  // worker threads

  std::string validate() const;  // empty when usable
};

// The printed patterns of a family's first `count` tags (every tag for count < 0): one byte per
// cell (0 black, 255 white), row-major, row 0 at the top of the upright tag. The detected square
// spans the middle width_at_border cells; the rest is the outer ring.
struct TagPatterns {
  int total_width = 0;
  int width_at_border = 0;
  std::vector<std::vector<std::uint8_t>> cells;  // per tag id
};
StatusOr<TagPatterns> tagFamilyPatterns(const std::string& family, int count);

// An image as the detector takes it (CV_8UC1) from what cameras and files give: 8- or 16-bit,
// one, three (BGR) or four (BGRA) channels. 16-bit images are scaled so that their brightest
// pixel becomes 255 (cameras put 10 or 12 bits in 16). Other types: an error naming the type.
StatusOr<cv::Mat> grayForDetection(const cv::Mat& image);

// Where one image's detection spent its time [ms, wall clock].
struct TagDetectionStages {
  double quads_ms = 0.0;    // thresholding and quad finding (mvis's engine; all of libapriltag's)
  double reading_ms = 0.0;  // reading the codes, sharpening quads that did not read
  double corners_ms = 0.0;  // sub-pixel corners and the response correction
};

// The tags of an image found and read, before their corners are refined: detect()'s first two
// stages, for callers that run the last one elsewhere.
struct FoundTags {
  std::vector<TagObservation> tags;  // corners from the quads, good to a pixel or so
  std::vector<int> borders;          // per tag, its border width in cells
  TagDetectionStages stages;         // quads_ms and reading_ms
};

class TagDetector {
 public:
  static StatusOr<std::unique_ptr<TagDetector>> create(const TagDetectorOptions& options);
  ~TagDetector();
  TagDetector(const TagDetector&) = delete;
  TagDetector& operator=(const TagDetector&) = delete;

  // Every tag found in `gray` (CV_8UC1, any stride), each id at most once. Nothing is filtered
  // here beyond what the decoder does; pass the result through checkTagFrame(). An empty or
  // non-8-bit image gives an error, never a crash.
  StatusOr<std::vector<TagObservation>> detect(const cv::Mat& gray) const;

  // detect() in two steps: find() the tags (quads and codes), then refine() their corners
  // (sets stages->corners_ms); detect() is refine(find()) over the whole image. find() looks
  // for quads inside `region` only (a predicted region of interest): a tag whose square lies
  // inside it has the corners the whole image's search gives, bit for bit. libapriltag's engine
  // searches the whole image.
  StatusOr<FoundTags> find(const cv::Mat& gray, const cv::Rect& region) const;
  std::vector<TagObservation> refine(const cv::Mat& gray, FoundTags found,
                                     TagDetectionStages* stages = nullptr) const;

  const TagDetectorOptions& options() const { return options_; }

 private:
  struct Impl;
  TagDetector(const TagDetectorOptions& options, std::unique_ptr<Impl> impl);
  TagDetectorOptions options_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mvis
