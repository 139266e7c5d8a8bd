// Reading a tag's code inside a candidate quad: the second stage of mvis's own detector.
//
// The quad's square is divided into W x W cells (W = D + 2 * border, the border one or two cells
// wide, see tag_codebook.h) through the homography of its corners; each
// cell is sampled at its centre (the mean of four bilinear samples a fifth of a cell apart).
// Black and white levels are planes fitted to the border cells and to the white ring just
// outside the square (its middle cells only: in an AprilGrid the ring's corners are the black
// squares), so a gradient of light across the tag does not flip bits; each cell is black below
// the planes' mean. The data word is decoded against the family's codes in the four quarter
// turns; border cells that read white count as corrected bits too. A quad is refused when its
// contrast is below min_contrast, when more than a quarter of the ring reads black, or when no
// code is within max_hamming bits.
#pragma once

#include <opencv2/core/mat.hpp>
#include <optional>

#include "mvis/frontend/tag_observation.h"
#include "tag_codebook.h"
#include "tag_quads.h"

namespace mvis {

struct TagReadingOptions {
  int max_hamming = 1;
  double min_contrast = 20.0;  // white ring - black border [grey levels]
};

// The tag in `quad` (clockwise in the image) if its border is `border` cells wide, its
// corners in mvis's order; nullopt if none.
std::optional<TagObservation> readTag(const cv::Mat& gray, const Quad& quad,
                                      const TagCodebook& codebook, int border,
                                      const TagReadingOptions& options);

}  // namespace mvis
