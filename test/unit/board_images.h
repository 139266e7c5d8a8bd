// Rendered views of a 6x6 tag board with exactly known corners, by two independent renderers,
// for the detector's accuracy tests.
//
// - mvis's own (TagBoardRenderer): the board's reflectance at stratified jittered sample points
//   of every pixel (a box filter over the pixel area), then a Gaussian blur, noise and 8 bits.
// - a texture renderer built here from OpenCV only, as other simulators make images: the board
//   drawn as a texture of 8 texels per cell, sampled bilinearly through the homography at 3 x 3
//   points per pixel (cv::warpPerspective), box-filtered down (cv::resize INTER_AREA), then the
//   same blur, noise and quantization. Its pixel-centre conventions are worked out from
//   OpenCV's own (integer coordinates at texel and pixel centres), not shared with mvis's.
#pragma once

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>
#include <string>

#include "mvis/common/lie.h"
#include "mvis/rig/rig.h"
#include "mvis/sim/tag_renderer.h"

namespace mvis::test {

enum class Renderer { kMvis, kTexture };

struct BoardView {
  AprilGrid grid;  // 6x6 tag36h11, 88 mm tags, spacing 0.3
  BoardKind kind = BoardKind::kPlain;
  Eigen::Vector4d intrinsics{450.0, 450.0, 375.5, 239.5};  // 752x480 pinhole
  SE3 T_cam_board;
  cv::Mat image;

  // Where corner c of tag id truly is in the image [px, mvis convention].
  Eigen::Vector2d truth(int id, int c) const;
};

struct ViewOptions {
  Renderer renderer = Renderer::kMvis;
  BoardKind kind = BoardKind::kPlain;
  double blur_sigma = 0.0;   // [px]
  double noise_sigma = 2.0;  // [grey levels]
  double black = 40.0, white = 230.0;
  double gamma = 1.0;  // texture renderer: response out = 255 (in / 255)^(1 / gamma)
  std::uint32_t seed = 1;
};

// The camera about `distance` [m] in front of the board's centre, tilted by (tilt_x, tilt_y)
// [rad] about the board's x and y axes, upright.
SE3 viewOfBoard(double tilt_x, double tilt_y, double distance);

BoardView renderBoard(const SE3& T_cam_board, const ViewOptions& options);

}  // namespace mvis::test
