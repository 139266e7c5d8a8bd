#include "board_images.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <random>

namespace mvis::test {

Eigen::Vector2d BoardView::truth(int id, int c) const {
  return projectPinhole(intrinsics, T_cam_board, grid.corner(id, c));
}

SE3 viewOfBoard(double tilt_x, double tilt_y, double distance) {
  const Eigen::Vector3d board_centre(0.3212, 0.3212, 0.0);  // middle of the 6x6 grid
  // Camera z towards the board, camera x along board x, camera y along board -y.
  Eigen::Matrix3d R_board_cam;
  R_board_cam << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  R_board_cam = lie::expSO3(Eigen::Vector3d(tilt_x, tilt_y, 0.0)) * R_board_cam;
  const Eigen::Vector3d p_board_cam = board_centre - distance * R_board_cam.col(2);
  return SE3(R_board_cam, p_board_cam).inverse();
}

namespace {

cv::Mat textureRender(const BoardView& view, const TagBoardRenderer& board,
                      const ViewOptions& options) {
  const double kalibr_cell = view.grid.tag_size / 10.0;  // both kinds' cells are multiples of
  const double texel = kalibr_cell / 8.0;                // 1/40 of a tag: 8 texels per 1/10
  const double pitch = (1.0 + view.grid.tag_spacing) * view.grid.tag_size;
  const double lo = -pitch;  // board margin of one pitch
  const double hi = view.grid.tag_cols * pitch - view.grid.tag_spacing * view.grid.tag_size + pitch;
  const int texels = static_cast<int>(std::lround((hi - lo) / texel));
  cv::Mat texture(texels, texels, CV_32FC1);
  for (int i = 0; i < texels; ++i) {
    for (int j = 0; j < texels; ++j) {
      // Texel (i, j) covers board [lo + j t, lo + (j + 1) t] x [lo + i t, lo + (i + 1) t].
      const double r = board.reflectance(lo + (j + 0.5) * texel, lo + (i + 0.5) * texel, 1.0);
      texture.at<float>(i, j) =
          static_cast<float>(r < 0.0 ? 110.0 : options.black + r * (options.white - options.black));
    }
  }
  // Board point (x, y) -> texel coordinates (centres at integers).
  Eigen::Matrix3d A;
  A << 1.0 / texel, 0, -lo / texel - 0.5, 0, 1.0 / texel, -lo / texel - 0.5, 0, 0, 1;
  // Board plane -> image [px, centres at integers].
  const Eigen::Matrix3d R = view.T_cam_board.rotation();
  Eigen::Matrix3d Rt;
  Rt << R.col(0), R.col(1), view.T_cam_board.p;
  Eigen::Matrix3d K;
  K << view.intrinsics[0], 0, view.intrinsics[2], 0, view.intrinsics[1], view.intrinsics[3], 0, 0,
      1;
  // Supersampled pixel (X, Y) has its centre at image position (X + 0.5) / 3 - 0.5.
  constexpr int kSuper = 3;
  Eigen::Matrix3d S;
  S << 1.0 / kSuper, 0, 0.5 / kSuper - 0.5, 0, 1.0 / kSuper, 0.5 / kSuper - 0.5, 0, 0, 1;
  const Eigen::Matrix3d dst_to_src = A * (K * Rt).inverse() * S;
  cv::Mat M(3, 3, CV_64FC1);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) M.at<double>(r, c) = dst_to_src(r, c);
  }
  cv::Mat super, image;
  cv::warpPerspective(texture, super, M, cv::Size(752 * kSuper, 480 * kSuper),
                      cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT,
                      cv::Scalar(110.0));
  cv::resize(super, image, cv::Size(752, 480), 0, 0, cv::INTER_AREA);
  return image;
}

}  // namespace

BoardView renderBoard(const SE3& T_cam_board, const ViewOptions& options) {
  BoardView view;
  view.grid.tag_cols = 6;
  view.grid.tag_rows = 6;
  view.grid.tag_size = 0.088;
  view.grid.tag_spacing = 0.3;
  view.kind = options.kind;
  view.T_cam_board = T_cam_board;
  auto board = TagBoardRenderer::create(view.grid, options.kind);
  EXPECT_TRUE(board.ok());
  if (options.renderer == Renderer::kMvis) {
    RenderOptions render;
    render.black = options.black;
    render.white = options.white;
    render.blur_sigma = options.blur_sigma;
    render.noise_sigma = options.noise_sigma;
    render.seed = options.seed;
    view.image =
        board.value()->render(752, 480, pinholeToBoard(view.intrinsics, T_cam_board), render);
    return view;
  }
  cv::Mat clean = textureRender(view, *board.value(), options);
  if (options.blur_sigma > 0.0) {
    cv::GaussianBlur(clean, clean, cv::Size(), options.blur_sigma, options.blur_sigma,
                     cv::BORDER_REPLICATE);
  }
  std::mt19937 rng(options.seed);
  std::normal_distribution<double> noise(0.0, options.noise_sigma);
  view.image.create(clean.size(), CV_8UC1);
  for (int r = 0; r < clean.rows; ++r) {
    for (int c = 0; c < clean.cols; ++c) {
      const double linear = std::max(0.0, static_cast<double>(clean.at<float>(r, c))) / 255.0;
      const double v = 255.0 * std::pow(linear, 1.0 / options.gamma) +
                       (options.noise_sigma > 0 ? noise(rng) : 0.0);
      view.image.at<std::uint8_t>(r, c) =
          static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
    }
  }
  return view;
}

}  // namespace mvis::test
