// A second renderer of tag boards, by a method that shares nothing with TagBoardRenderer (which
// averages the board's reflectance over sample points): every black region of the board (the
// tags' cells as libapriltag draws them, apriltag_to_image; Kalibr's squares) is a rectangle on
// the board, its outline projected into the image (each side split into `subdivisions`
// segments, so that lens distortion bends it), and a pixel's value is the exact area of its
// square [c - 1/2, c + 1/2] x [r - 1/2, r + 1/2] (pixel centres at integers) that these
// polygons cover (polygon clipping, no sampling). Then, in this order: vignetting (the
// irradiance times 1 - v (d / d_corner)^2, d the distance from the image centre), a Gaussian
// blur of the irradiance (a kernel sampled at the pixel offsets out to 4 sigma, normalized),
// the camera's response (gamma encoding, out = 255 (in / 255)^(1 / gamma)), Gaussian noise,
// rounding to 8 bits. The plane beyond the tags is white. tag36h11 only.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "mvis/common/status.h"
#include "mvis/rig/rig.h"

namespace mvis {

struct CoverageOptions {
  int width = 752, height = 480;
  bool kalibr_squares = false;  // Kalibr's AprilGrid: two-cell borders, squares at the crossings
  double black = 40.0, white = 230.0;  // linear irradiance [grey levels]
  double vignetting = 0.0;             // v above: irradiance lost at the image's corners
  double blur_sigma = 0.0;             // [px]
  double gamma = 1.0;                  // 1: linear response
  double noise_sigma = 2.0;            // [grey levels], after the response
  int subdivisions = 1;                // segments per side of a projected rectangle
  std::uint32_t seed = 1;
};

// Board point (x, y, 0) [m] to its pixel; false where it does not project (behind the camera).
using BoardToPixel = std::function<bool(const Eigen::Vector2d& board, Eigen::Vector2d* pixel)>;

// The board seen through `project`; an error for a family other than tag36h11.
StatusOr<cv::Mat> renderByCoverage(const AprilGrid& grid, const BoardToPixel& project,
                                   const CoverageOptions& options);

// Area of the intersection of a simple polygon (either orientation; convex or not) with the unit
// pixel square centred at (cx, cy).
double pixelCoverage(const std::vector<Eigen::Vector2d>& polygon, double cx, double cy);

}  // namespace mvis
