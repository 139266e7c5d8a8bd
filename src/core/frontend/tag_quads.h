// Candidate tag squares in a grayscale image: the first stage of mvis's own tag detector.
//
// Pixels are classified black against the midpoint of their neighbourhood's darkest and
// brightest values (tiles of 4-8 px, a 5x5-tile neighbourhood), with a margin: a pixel is black
// only if it lies below the midpoint by `margin` of the local contrast. Black pixels are joined
// into 4-connected components. The margin is what makes Kalibr AprilGrids detectable: there a
// tag's black border touches the little black squares between the tags only at its corners,
// in X-junctions whose centre is mid-grey; without a margin one noisy pixel joins every tag and
// square of the board into one component (libapriltag's failure on these boards). With it the
// junction's centre is never black and each tag's border is a component of its own.
//
// Each component of plausible size gives its outer contour; four corners are chosen on its
// convex hull (the largest inscribed quadrilateral, found greedily), the contour must stay close
// to the quadrilateral's sides (a small bump, such as a square still attached at a corner, is
// tolerated), solid components (the squares themselves) are refused, and the corners are
// sharpened by intersecting lines fitted to the middle of each side. A component that is no quad
// but big enough to hold several (tags joined where a junction's centre came out dark) is
// thresholded again with a larger margin (0.2, then 0.3), its own pixels only (not the other
// components its box overlaps). They are good to a fraction of a cell, enough to read the code;
// the sub-pixel corners come later (corner_refinement.h).
#pragma once

#include <Eigen/Core>
#include <array>
#include <opencv2/core/mat.hpp>
#include <vector>

namespace mvis {

struct QuadFinderOptions {
  double min_contrast = 20.0;  // darkest to brightest of a neighbourhood below this: no black
  double margin = 0.1;         // black: below the midpoint by this part of the local contrast
  int min_side_px = 8;         // smallest quad side considered [px]
};

// Corners in mvis's pixel convention ((0, 0) at the centre of the top-left pixel), clockwise
// as seen in the image (x right, y down): positive shoelace area.
using Quad = std::array<Eigen::Vector2d, 4>;

// Every quad-shaped black component's outline in `gray` (CV_8UC1).
std::vector<Quad> findQuads(const cv::Mat& gray, const QuadFinderOptions& options);

// The same, of the components inside `region` (clipped to the image) that do not touch its
// border: for those the quads are the whole image's, bit for bit (the levels are computed with
// the neighbourhood's reach around the region), in the same order.
std::vector<Quad> findQuads(const cv::Mat& gray, const cv::Rect& region,
                            const QuadFinderOptions& options);

}  // namespace mvis
