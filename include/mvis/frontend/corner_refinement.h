// Sub-pixel refinement of a tag's corners from its edges.
//
// libapriltag fits its quad to thresholded contours and (with refine_edges) nudges edges along
// gradients; its corners still stray by about 0.2 px on clean rendered images. Here each side
// of the quad is re-measured: across the side, at many points along its middle 70%, the
// intensity profile is sampled (bilinear, 0.25 px steps) and the edge located from the
// profile's area between its dark and bright levels (the first moment of the step: exact for a
// straight edge under pixel-area filtering, whatever its phase within a pixel, where a halfway
// crossing of the interpolated profile errs by up to ~0.15 px). A line is fitted to each side's
// edge points (total least squares) and the corners are the intersections of neighbouring
// lines.
//
// Lens distortion bends long edges; the straight-line model holds for tags that span a small
// part of the image.
#pragma once

#include <opencv2/core/mat.hpp>

#include "mvis/frontend/tag_observation.h"

namespace mvis {

struct CornerRefinementOptions {
  double edge_margin = 0.15;   // part of each side left out at either end
  double min_contrast = 20.0;  // bright - dark below this: the sample is not used
  double max_shift_px = 1.5;   // a corner that would move further is left as it was
  int width_at_border = 8;     // cells across the detected square (family dependent)
  // Smaller tags are left alone: the profile must fit inside one border cell on each side of
  // the edge; measured on rendered boards, cells of 3 px refine worse than libapriltag.
  double min_cell_px = 4.0;
};

// Refines `tag` in place from `gray` (CV_8UC1). Returns false, leaving the tag unchanged, when a
// side has too few usable edge points or a corner would move more than max_shift_px.
bool refineTagCorners(const cv::Mat& gray, TagObservation* tag,
                      const CornerRefinementOptions& options);

}  // namespace mvis
