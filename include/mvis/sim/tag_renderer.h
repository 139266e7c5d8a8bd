// Renders images of a planar AprilTag board (the aprilgrid.yaml layout) with anti-aliasing, for
// the simulator and for tests with known corners. Two kinds of board: plain (libapriltag's tags,
// a one-cell black border, white between the tags) and Kalibr's AprilGrid (two-cell borders, a
// black square of the gap's size at every crossing of the gaps, the outer ones included); in
// both, tag_size is the edge of a tag's black square.
//
// The camera model enters only through `pixel_to_board`: for a pixel position (u, v) in mvis's
// convention ((0, 0) at the centre of the top-left pixel) it returns the board point (x, y) [m]
// seen there, or false if the ray misses the board plane. Any projection with any distortion
// fits; pinholeToBoard() gives the undistorted pinhole case.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <memory>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "mvis/common/lie.h"
#include "mvis/common/status.h"
#include "mvis/rig/rig.h"

namespace mvis {

using PixelToBoard = std::function<bool(const Eigen::Vector2d& pixel, Eigen::Vector2d* board)>;

struct RenderOptions {
  int supersample = 4;        // stratified jittered samples per pixel along each axis (box filter)
  double black = 25.0;        // intensity of black tag cells [0, 255]
  double white = 230.0;       // intensity of the white board
  double background = 110.0;  // where the ray misses the board
  double margin_tags = 1.0;   // white board beyond the outer tags, in tag pitches
  double blur_sigma = 0.0;    // Gaussian blur after pixel-area averaging [px] (optics)
  double noise_sigma = 0.0;   // Gaussian pixel noise [intensity]
  std::uint32_t seed = 1;     // for the sample jitter and the noise
};

// The viewing rays of one camera's anti-aliasing samples, computed once (inverting the
// distortion per sample is the expensive part of rendering): for every pixel, supersample^2
// stratified jittered sample positions (a fixed pattern from `seed`) and their normalized rays
// m (p_C = z [m; 1]); NaN where the distortion cannot be inverted.
class CameraRays {
 public:
  CameraRays(const Camera& camera, int supersample, std::uint32_t seed);
  int width() const { return width_; }
  int height() const { return height_; }
  int samplesPerPixel() const { return samples_; }
  // Rays of pixel (row, col): samplesPerPixel() consecutive (x, y) pairs.
  const float* pixel(int row, int col) const {
    return rays_.data() + 2 * static_cast<std::size_t>(samples_) * (row * width_ + col);
  }

 private:
  int width_ = 0, height_ = 0, samples_ = 0;
  std::vector<float> rays_;
};

enum class BoardKind {
  kPlain,       // libapriltag's tags, one-cell border
  kKalibrGrid,  // Kalibr's AprilGrid: two-cell borders, black squares between the tags
};

class TagBoardRenderer {
 public:
  // Fails if the grid's family is unknown or has no plain border (Kalibr kind).
  static StatusOr<std::unique_ptr<TagBoardRenderer>> create(const AprilGrid& grid,
                                                            BoardKind kind = BoardKind::kPlain);

  cv::Mat render(int width, int height, const PixelToBoard& pixel_to_board,
                 const RenderOptions& options) const;

  // The same with precomputed rays, for camera pose T_G_C over the board (world = board frame);
  // options.supersample is the rays' own. Rows are shared between `threads` threads; the image
  // is the same for any number of threads.
  cv::Mat render(const CameraRays& rays, const SE3& T_G_C, const RenderOptions& options,
                 int threads = 1) const;

  // Board intensity in [0, 1] (0 black, 1 white) at board point (x, y) [m]; -1 off the board.
  double reflectance(double x, double y, double margin_tags) const;

 private:
  TagBoardRenderer() = default;
  AprilGrid grid_;
  BoardKind kind_ = BoardKind::kPlain;
  int total_width_ = 0;      // pattern cells across, including the outer ring
  int width_at_border_ = 0;  // cells across the tag's detected square
  std::vector<std::vector<std::uint8_t>> patterns_;  // per tag id, row-major, row 0 = top
};

// The pinhole camera with intrinsics [fu fv pu pv] and no distortion, looking at the board
// from pose T_cam_board.
PixelToBoard pinholeToBoard(const Eigen::Vector4d& intrinsics, const SE3& T_cam_board);

// Pixel position of board point X (z = 0) in that camera.
Eigen::Vector2d projectPinhole(const Eigen::Vector4d& intrinsics, const SE3& T_cam_board,
                               const Eigen::Vector3d& X_board);

}  // namespace mvis
