// A third renderer of tag boards for the detector's accuracy tests, sharing nothing with mvis's
// renderer or its tag patterns: every black region of the board (the tags' cells as libapriltag
// draws them, apriltag_to_image; Kalibr's squares) is a rectangle on the board, projected
// through a pinhole camera to a convex quadrilateral, and a pixel's value is the exact area of
// its square [c - 1/2, c + 1/2] x [r - 1/2, r + 1/2] (pixel centres at integers) that the
// quadrilaterals cover (polygon clipping, no sampling). Then, in this order: vignetting (the
// irradiance times 1 - v (d / d_corner)^2, d the distance from the image centre), a Gaussian
// blur of the irradiance (a kernel sampled at the pixel offsets out to 4 sigma, normalized),
// the camera's response (gamma encoding, out = 255 (in / 255)^(1 / gamma)), Gaussian noise,
// rounding to 8 bits.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core/mat.hpp>

#include "mvis/common/lie.h"
#include "mvis/rig/rig.h"

namespace mvis::test {

struct CoverageOptions {
  int width = 752, height = 480;
  Eigen::Vector4d intrinsics{450.0, 450.0, 375.5, 239.5};  // fu, fv, cu, cv [px]
  bool kalibr_squares =
      false;  // Kalibr's AprilGrid: two-cell borders, squares at the gaps' crossings
  double black = 40.0, white = 230.0;  // linear irradiance [grey levels]
  double vignetting = 0.0;             // v above: irradiance lost at the image's corners
  double blur_sigma = 0.0;             // [px]
  double gamma = 1.0;                  // 1: linear response
  double noise_sigma = 2.0;            // [grey levels], after the response
  std::uint32_t seed = 1;
};

// The board `grid` (tag36h11) seen from T_cam_board; the rest of the plane is white.
cv::Mat renderByCoverage(const AprilGrid& grid, const SE3& T_cam_board,
                         const CoverageOptions& options);

// Area of the intersection of the convex quadrilateral q (either orientation) with the unit
// pixel square centred at (cx, cy).
double pixelCoverage(const Eigen::Vector2d q[4], double cx, double cy);

}  // namespace mvis::test
