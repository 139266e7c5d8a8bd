#include "mvis/sim/tag_renderer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <random>
#include <thread>

#include "mvis/camera/camera_model.h"
#include "mvis/frontend/tag_detector.h"

namespace mvis {
namespace {

// Optics after the pixel-area average: Gaussian blur, then noise (seeded per row) and 8 bits.
void blurAndQuantize(const cv::Mat& clean, const RenderOptions& options, cv::Mat* image) {
  cv::Mat blurred;
  cv::GaussianBlur(clean, blurred, cv::Size(), options.blur_sigma, options.blur_sigma,
                   cv::BORDER_REPLICATE);
  std::normal_distribution<double> noise(0.0, options.noise_sigma);
  for (int r = 0; r < blurred.rows; ++r) {
    std::mt19937 rng(options.seed * 7919u + static_cast<std::uint32_t>(r));
    const float* in = blurred.ptr<float>(r);
    auto* out = image->ptr<std::uint8_t>(r);
    for (int c = 0; c < blurred.cols; ++c) {
      double value = in[c];
      if (options.noise_sigma > 0.0) value += noise(rng);
      out[c] = static_cast<std::uint8_t>(std::clamp(std::lround(value), 0L, 255L));
    }
  }
}

}  // namespace

StatusOr<std::unique_ptr<TagBoardRenderer>> TagBoardRenderer::create(const AprilGrid& grid,
                                                                     BoardKind kind) {
  std::unique_ptr<TagBoardRenderer> renderer(new TagBoardRenderer());
  renderer->grid_ = grid;
  renderer->kind_ = kind;
  auto patterns = tagFamilyPatterns(grid.tag_family, grid.numTags());
  if (!patterns.ok()) return patterns.status();
  int total = patterns.value().total_width;
  int at_border = patterns.value().width_at_border;
  auto cells = std::move(patterns.value().cells);
  if (kind == BoardKind::kKalibrGrid) {
    if (total != at_border + 2) {
      return Status::Error("tag family " + grid.tag_family + " has no plain border to widen");
    }
    // One more black ring inside the white one: the data keeps its cells, the square grows.
    const int wide = total + 2;
    for (auto& pattern : cells) {
      std::vector<std::uint8_t> widened(wide * wide, 255);
      for (int r = 1; r < wide - 1; ++r) {
        for (int c = 1; c < wide - 1; ++c) {
          const bool inner = r >= 2 && c >= 2 && r < wide - 2 && c < wide - 2;
          widened[r * wide + c] = inner ? pattern[(r - 1) * total + (c - 1)] : 0;
        }
      }
      pattern = std::move(widened);
    }
    total = wide;
    at_border += 2;
  }
  renderer->total_width_ = total;
  renderer->width_at_border_ = at_border;
  renderer->patterns_ = std::move(cells);
  return renderer;
}

double TagBoardRenderer::reflectance(double x, double y, double margin_tags) const {
  const double size = grid_.tag_size;
  const double pitch = (1.0 + grid_.tag_spacing) * size;
  const double margin = margin_tags * pitch;
  if (x < -margin || y < -margin ||
      x > grid_.tag_cols * pitch - grid_.tag_spacing * size + margin ||
      y > grid_.tag_rows * pitch - grid_.tag_spacing * size + margin) {
    return -1.0;
  }
  // Tag cell under (x, y): the pattern's outer ring reaches (total - at_border) / 2 cells past
  // the detected square on each side.
  const double cell = size / width_at_border_;
  const double ring = 0.5 * (total_width_ - width_at_border_) * cell;
  if (kind_ == BoardKind::kKalibrGrid) {
    // The squares fill every crossing of the gaps, [k * pitch - gap, k * pitch] on both axes.
    const double gap = grid_.tag_spacing * size;
    const double kx = std::floor((x + gap) / pitch), ky = std::floor((y + gap) / pitch);
    const bool in_x = x >= kx * pitch - gap && x < kx * pitch && kx >= 0 && kx <= grid_.tag_cols;
    const bool in_y = y >= ky * pitch - gap && y < ky * pitch && ky >= 0 && ky <= grid_.tag_rows;
    if (in_x && in_y) return 0.0;
  }
  const int col = static_cast<int>(std::floor((x + ring) / pitch));
  const int row = static_cast<int>(std::floor((y + ring) / pitch));
  if (col < 0 || row < 0 || col >= grid_.tag_cols || row >= grid_.tag_rows) return 1.0;
  const double lx = x - col * pitch + ring;  // from the pattern's left edge
  const double ly = y - row * pitch + ring;  // from the pattern's bottom edge
  const int cx = static_cast<int>(std::floor(lx / cell));
  const int cy = static_cast<int>(std::floor(ly / cell));
  if (cx < 0 || cy < 0 || cx >= total_width_ || cy >= total_width_) return 1.0;
  // Board y grows towards the tag's top; pattern rows grow downwards from its top.
  const int pattern_row = total_width_ - 1 - cy;
  const auto& pattern = patterns_[row * grid_.tag_cols + col];
  return pattern[pattern_row * total_width_ + cx] > 127 ? 1.0 : 0.0;
}

cv::Mat TagBoardRenderer::render(int width, int height, const PixelToBoard& pixel_to_board,
                                 const RenderOptions& options) const {
  cv::Mat image(height, width, CV_8UC1);
  cv::Mat clean;  // area averages before blur, with blur only
  if (options.blur_sigma > 0.0) clean.create(height, width, CV_32FC1);
  const int n = std::max(1, options.supersample);
  std::mt19937 rng(options.seed);
  std::normal_distribution<double> noise(0.0, options.noise_sigma);
  std::uniform_real_distribution<double> jitter(0.0, 1.0);
  Eigen::Vector2d board;
  for (int r = 0; r < height; ++r) {
    auto* row = image.ptr<std::uint8_t>(r);
    for (int c = 0; c < width; ++c) {
      double sum = 0.0;
      for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) {
          // Stratified jittered samples over the pixel [c - 0.5, c + 0.5]: their mean is the
          // exact area average in expectation, where a regular grid would snap straight edges
          // to multiples of 1 / n pixel.
          const Eigen::Vector2d pixel(c - 0.5 + (j + jitter(rng)) / n,
                                      r - 0.5 + (i + jitter(rng)) / n);
          double value = options.background;
          if (pixel_to_board(pixel, &board)) {
            const double reflect = reflectance(board.x(), board.y(), options.margin_tags);
            if (reflect >= 0.0) value = options.black + reflect * (options.white - options.black);
          }
          sum += value;
        }
      }
      double value = sum / (n * n);
      if (!clean.empty()) {
        clean.at<float>(r, c) = static_cast<float>(value);
        continue;
      }
      if (options.noise_sigma > 0.0) value += noise(rng);
      row[c] = static_cast<std::uint8_t>(std::clamp(std::lround(value), 0L, 255L));
    }
  }
  if (!clean.empty()) blurAndQuantize(clean, options, &image);
  return image;
}

CameraRays::CameraRays(const Camera& camera, int supersample, std::uint32_t seed)
    : width_(camera.resolution[0]),
      height_(camera.resolution[1]),
      samples_(std::max(1, supersample) * std::max(1, supersample)) {
  const int n = std::max(1, supersample);
  rays_.resize(2 * static_cast<std::size_t>(samples_) * width_ * height_);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> jitter(0.0, 1.0);
  Eigen::Vector2d previous(0.0, 0.0);
  bool have_previous = false;
  float* out = rays_.data();
  for (int r = 0; r < height_; ++r) {
    for (int c = 0; c < width_; ++c) {
      for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) {
          const Eigen::Vector2d pixel(c - 0.5 + (j + jitter(rng)) / n,
                                      r - 0.5 + (i + jitter(rng)) / n);
          Eigen::Vector2d m;
          if (unprojectPixel(camera, pixel, &m, have_previous ? &previous : nullptr)) {
            previous = m;
            have_previous = true;
            *out++ = static_cast<float>(m.x());
            *out++ = static_cast<float>(m.y());
          } else {
            have_previous = false;
            *out++ = std::numeric_limits<float>::quiet_NaN();
            *out++ = std::numeric_limits<float>::quiet_NaN();
          }
        }
      }
    }
  }
}

cv::Mat TagBoardRenderer::render(const CameraRays& rays, const SE3& T_G_C,
                                 const RenderOptions& options, int threads) const {
  cv::Mat image(rays.height(), rays.width(), CV_8UC1);
  cv::Mat clean;  // area averages before blur, with blur only
  if (options.blur_sigma > 0.0) clean.create(rays.height(), rays.width(), CV_32FC1);
  const Eigen::Matrix3d R = T_G_C.rotation();
  const Eigen::Vector3d o = T_G_C.p;
  const int samples = rays.samplesPerPixel();
  const auto renderRows = [&](int first, int last) {
    std::normal_distribution<double> noise(0.0, options.noise_sigma);
    for (int r = first; r < last; ++r) {
      // Noise seeded per row: the same image whatever the number of threads.
      std::mt19937 rng(options.seed * 7919u + static_cast<std::uint32_t>(r));
      auto* row = image.ptr<std::uint8_t>(r);
      for (int c = 0; c < rays.width(); ++c) {
        const float* m = rays.pixel(r, c);
        double sum = 0.0;
        for (int k = 0; k < samples; ++k) {
          double value = options.background;
          const double mx = m[2 * k], my = m[2 * k + 1];
          if (!std::isnan(mx)) {
            // Ray in the world; the board is the plane z = 0.
            const double dz = R(2, 0) * mx + R(2, 1) * my + R(2, 2);
            const double t = std::abs(dz) > 1e-12 ? -o.z() / dz : -1.0;
            if (t > 0.0) {
              const double x = o.x() + t * (R(0, 0) * mx + R(0, 1) * my + R(0, 2));
              const double y = o.y() + t * (R(1, 0) * mx + R(1, 1) * my + R(1, 2));
              const double reflect = reflectance(x, y, options.margin_tags);
              if (reflect >= 0.0) value = options.black + reflect * (options.white - options.black);
            }
          }
          sum += value;
        }
        double value = sum / samples;
        if (!clean.empty()) {
          clean.at<float>(r, c) = static_cast<float>(value);
          continue;
        }
        if (options.noise_sigma > 0.0) value += noise(rng);
        row[c] = static_cast<std::uint8_t>(std::clamp(std::lround(value), 0L, 255L));
      }
    }
  };
  const int parts = std::max(1, std::min(threads, rays.height()));
  std::vector<std::thread> workers;
  const int rows_per_part = (rays.height() + parts - 1) / parts;
  for (int p = 1; p < parts; ++p) {
    workers.emplace_back(renderRows, std::min(rays.height(), p * rows_per_part),
                         std::min(rays.height(), (p + 1) * rows_per_part));
  }
  renderRows(0, std::min(rays.height(), rows_per_part));
  for (auto& worker : workers) worker.join();
  if (!clean.empty()) blurAndQuantize(clean, options, &image);
  return image;
}

PixelToBoard pinholeToBoard(const Eigen::Vector4d& intrinsics, const SE3& T_cam_board) {
  const SE3 T_board_cam = T_cam_board.inverse();
  const Eigen::Matrix3d R = T_board_cam.rotation();
  const Eigen::Vector3d origin = T_board_cam.p;
  return [=](const Eigen::Vector2d& pixel, Eigen::Vector2d* board) {
    const Eigen::Vector3d ray_cam((pixel.x() - intrinsics[2]) / intrinsics[0],
                                  (pixel.y() - intrinsics[3]) / intrinsics[1], 1.0);
    const Eigen::Vector3d ray = R * ray_cam;
    if (std::abs(ray.z()) < 1e-12) return false;
    const double t = -origin.z() / ray.z();
    if (t <= 0.0) return false;
    *board = (origin + t * ray).head<2>();
    return true;
  };
}

Eigen::Vector2d projectPinhole(const Eigen::Vector4d& intrinsics, const SE3& T_cam_board,
                               const Eigen::Vector3d& X_board) {
  const Eigen::Vector3d X = T_cam_board * X_board;
  return Eigen::Vector2d(intrinsics[0] * X.x() / X.z() + intrinsics[2],
                         intrinsics[1] * X.y() / X.z() + intrinsics[3]);
}

}  // namespace mvis
