// Sub-pixel corners of a decoded tag from its edges, knowing its printed pattern.
//
// Each side of the tag's detected square is an edge between the white ring outside and the
// black border inside. Beyond the border, one cell in, lie the data cells: where one is white,
// the border is a black stripe one cell wide and blur (the lens, the sensor's pixel area) lets
// that stripe's inner edge pull on the outer one. Every method that locates the edge from its
// own profile alone (a gradient peak, a halfway crossing, a first moment with levels taken
// from the profile's ends) is pulled outwards there; that was mvis's old refinement's outward
// bias of ~0.04 px on images rendered by others. Knowing the code, this refinement measures
// each side only across data cells that are black (the black then reaches two cells in and the
// edge is a plain step), plus the border's corner cells where the ring is white around them,
// and falls back to the white ones, with a narrower window, only for a side without any.
//
// Across such a cell the edge's offset e along the inward normal t comes from the image's
// black area in a window t in [-r, r] (r = 1.25 cells where the neighbouring columns are black
// two cells deep too, else 0.75; at most 10 px and short of the white known outside), its
// lateral sides sheared with the cells: with the white and black levels W, B measured in the
// window's outer halves,
//   sum_p w_p (W - I_p) / (W - B) = sum_p w_p S(t_p - e)
// over the pixels p in the window, w_p the part of a pixel's footprint inside it and S the
// part of the pixel's square beyond the edge (exact for any edge direction). Area is what
// pixels preserve, so this holds whatever the edge's phase within a pixel, and blur only moves
// area across t = e symmetrically; blur also dims both levels alike, which cancels in a window
// centred on the edge (each pass re-centres it). A line is fitted to each side's offsets and the
// corners are the neighbouring lines' intersections.
//
// With `junctions` (Kalibr's AprilGrid), a corner where a black square touches the tag is
// instead the centre of the X-junction they make (junction_refinement.h), which no symmetric
// blur and no camera gamma moves: tried first from the given corners, the edges only where a
// corner has no junction.
//
// Lens distortion bends long edges; the straight-line model holds for tags that span a small
// part of the image.
#pragma once

#include <functional>
#include <opencv2/core/mat.hpp>

#include "mvis/frontend/tag_observation.h"

namespace mvis {

struct CornerRefinementOptions {
  double min_contrast = 20.0;  // white - black below this [grey levels]: the side is not used
  double max_shift_px = 1.5;   // a corner that would move further is left as it was
  double min_cell_px = 2.0;    // narrower cells (across the edge) are not measured [px]
  int passes = 3;
  // Cells known white outside the square: 1 for libapriltag's ring; Kalibr's gaps are wider.
  double white_outside_cells = 1.0;
  // Also measure across the border's corner cells (the half away from the corner): right for
  // tags with a white ring, wrong next to Kalibr's black squares.
  bool corner_cells = true;
  // Corners where a black square touches the tag (Kalibr's AprilGrid) taken as the X-junction's
  // centre instead (junction_refinement.h): immune to the camera's gamma, which moves edges.
  bool junctions = false;
};

// Cell (row, col) of the upright tag's detected square, width x width cells, row 0 at the top;
// rows and columns -1 and width are the white ring: true for black.
using TagCells = std::function<bool(int row, int col)>;

// How far the edges of plain tags lie from where the camera's response puts them (see
// measureEdgeShift): per tag, the sum and count of its stripes' measurements [px, inwards].
struct EdgeShift {
  double sum = 0.0;
  int count = 0;
};

// Refines `tag` in place from `gray` (CV_8UC1). Returns false, leaving the tag unchanged, when
// neither all four junctions (with `junctions`) nor the edges can be measured: a side without a
// usable cell, a corner that would move more than max_shift_px.
bool refineTagCorners(const cv::Mat& gray, TagObservation* tag, int width, const TagCells& black,
                      const CornerRefinementOptions& options);

// Plain tags (a one-cell border, white ring): a camera's response that is not linear (gamma)
// moves every edge the area measure above finds into the black, by the same amount on every
// tag of an image (it depends on the blur and the response, not on the tag): the tags read
// smaller. What it does not move is the centre of a black stripe between two white regions,
// the border where the data cell behind it is white: a monotone response and a symmetric blur
// move its two edges into it alike. Where a refined tag's side has such stripes whose
// neighbouring columns are white behind too (so that nothing dark within a cell of the stripe's
// inner side makes it asymmetric), each stripe's centre (its two edges' midpoint, each edge
// measured as above in a window half a cell wide) less half a cell is where the side is; its
// offset from the refined side is added to `shift` (positive: the side lies inside the true
// edge). The half cell is the refined square's, itself short by the shift: the measured offset
// is (1 - 1 / width) of the true one, corrected here.
void measureEdgeShift(const cv::Mat& gray, const TagObservation& tag, int width,
                      const TagCells& black, const CornerRefinementOptions& options,
                      EdgeShift* shift);

// Moves a refined tag's four sides outwards by `px` [px] (corners at the moved sides'
// intersections).
void moveTagSides(TagObservation* tag, double px);

}  // namespace mvis
