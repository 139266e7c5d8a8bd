#include "mvis/sim/coverage_renderer.h"

#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>

#include <algorithm>
#include <cmath>
#include <random>

namespace mvis {
namespace {

using Polygon = std::vector<Eigen::Vector2d>;

// Sutherland-Hodgman: the part of `in` on the side a x + b y <= c (the clip region is convex,
// the polygon need not be: pieces it splits into are joined along the line, at no area).
Polygon clip(const Polygon& in, double a, double b, double c) {
  Polygon out;
  const std::size_t n = in.size();
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d& p = in[i];
    const Eigen::Vector2d& q = in[(i + 1) % n];
    const double fp = a * p.x() + b * p.y() - c, fq = a * q.x() + b * q.y() - c;
    if (fp <= 0.0) out.push_back(p);
    if ((fp < 0.0 && fq > 0.0) || (fp > 0.0 && fq < 0.0))
      out.push_back(p + (fp / (fp - fq)) * (q - p));
  }
  return out;
}

double area(const Polygon& p) {
  double twice = 0.0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const Eigen::Vector2d& a = p[i];
    const Eigen::Vector2d& b = p[(i + 1) % p.size()];
    twice += a.x() * b.y() - a.y() * b.x();
  }
  return 0.5 * std::abs(twice);
}

struct Rect {
  double x0, y0, x1, y1;  // [m] on the board
};

// The board's black rectangles: per tag, runs of black cells per row of libapriltag's pattern.
StatusOr<std::vector<Rect>> blackRegions(const AprilGrid& grid, bool kalibr_squares) {
  if (grid.tag_family != "tag36h11") {
    return Status::Error("the coverage renderer draws tag36h11 only, not " + grid.tag_family);
  }
  std::vector<Rect> rects;
  apriltag_family_t* family = tag36h11_create();
  const int total = family->total_width;  // 10: a white ring around the black border
  // Plain tags: the detected square is the black border's outline (8 cells), the white ring
  // outside it. Kalibr's: the ring is black too, a border two cells wide, and the square is all
  // 10 cells.
  const int border = kalibr_squares ? total : family->width_at_border;
  const double cell = grid.tag_size / border;
  const double ring = 0.5 * (total - border) * cell;
  const double pitch = (1.0 + grid.tag_spacing) * grid.tag_size;
  for (int id = 0; id < grid.numTags(); ++id) {
    image_u8_t* image = apriltag_to_image(family, id);
    // Tag id's detected square spans [x, x + size] x [y, y + size]; its top (image row 0) at
    // the largest board y.
    const double x = pitch * (id % grid.tag_cols) - ring;
    const double y = pitch * (id / grid.tag_cols) - ring;
    for (int r = 0; r < image->height; ++r) {
      const double top = y + (total - r) * cell, bottom = top - cell;
      const auto black = [&](int col) {
        const bool ring_cell = r == 0 || col == 0 || r == total - 1 || col == total - 1;
        return (kalibr_squares && ring_cell) || image->buf[r * image->stride + col] < 128;
      };
      for (int c = 0; c < image->width;) {
        if (!black(c)) {
          ++c;
          continue;
        }
        int end = c;
        while (end < image->width && black(end)) ++end;
        rects.push_back({x + c * cell, bottom, x + end * cell, top});
        c = end;
      }
    }
    image_u8_destroy(image);
  }
  tag36h11_destroy(family);
  if (kalibr_squares) {
    const double gap = grid.tag_spacing * grid.tag_size;
    for (int i = 0; i <= grid.tag_cols; ++i) {
      for (int j = 0; j <= grid.tag_rows; ++j) {
        rects.push_back({i * pitch - gap, j * pitch - gap, i * pitch, j * pitch});
      }
    }
  }
  return rects;
}

// A kernel sampled at integer offsets, normalized; rows, then columns; edge pixels repeated.
cv::Mat blur(const cv::Mat& in, double sigma) {
  const int radius = static_cast<int>(std::ceil(4.0 * sigma));
  std::vector<double> k(2 * radius + 1);
  double sum = 0.0;
  for (int i = -radius; i <= radius; ++i) {
    sum += k[i + radius] = std::exp(-0.5 * i * i / (sigma * sigma));
  }
  for (double& v : k) v /= sum;
  const auto pass = [&](const cv::Mat& src, bool down) {
    cv::Mat dst(src.size(), CV_64FC1);
    for (int r = 0; r < src.rows; ++r) {
      for (int c = 0; c < src.cols; ++c) {
        double v = 0.0;
        for (int i = -radius; i <= radius; ++i) {
          const int rr = down ? std::clamp(r + i, 0, src.rows - 1) : r;
          const int cc = down ? c : std::clamp(c + i, 0, src.cols - 1);
          v += k[i + radius] * src.at<double>(rr, cc);
        }
        dst.at<double>(r, c) = v;
      }
    }
    return dst;
  };
  return pass(pass(in, false), true);
}

}  // namespace

double pixelCoverage(const std::vector<Eigen::Vector2d>& polygon, double cx, double cy) {
  Polygon p = clip(polygon, 1.0, 0.0, cx + 0.5);
  p = clip(p, -1.0, 0.0, -(cx - 0.5));
  p = clip(p, 0.0, 1.0, cy + 0.5);
  p = clip(p, 0.0, -1.0, -(cy - 0.5));
  return p.size() < 3 ? 0.0 : area(p);
}

StatusOr<cv::Mat> renderByCoverage(const AprilGrid& grid, const BoardToPixel& project,
                                   const CoverageOptions& o) {
  auto regions = blackRegions(grid, o.kalibr_squares);
  if (!regions.ok()) return regions.status();
  cv::Mat covered = cv::Mat::zeros(o.height, o.width, CV_64FC1);
  const int n = std::max(1, o.subdivisions);
  Polygon outline;
  for (const Rect& rect : regions.value()) {
    const Eigen::Vector2d corners[4] = {
        {rect.x0, rect.y0}, {rect.x1, rect.y0}, {rect.x1, rect.y1}, {rect.x0, rect.y1}};
    outline.clear();
    bool visible = true;
    for (int side = 0; side < 4 && visible; ++side) {
      for (int k = 0; k < n && visible; ++k) {
        const double s = static_cast<double>(k) / n;
        Eigen::Vector2d pixel;
        visible = project((1.0 - s) * corners[side] + s * corners[(side + 1) % 4], &pixel);
        outline.push_back(pixel);
      }
    }
    if (!visible) continue;  // partly behind the camera: not drawn (not in view anyway)
    double lo_x = outline[0].x(), hi_x = lo_x, lo_y = outline[0].y(), hi_y = lo_y;
    for (const auto& v : outline) {
      lo_x = std::min(lo_x, v.x()), hi_x = std::max(hi_x, v.x());
      lo_y = std::min(lo_y, v.y()), hi_y = std::max(hi_y, v.y());
    }
    if (hi_x < -1.0 || hi_y < -1.0 || lo_x > o.width || lo_y > o.height) continue;
    const int c0 = std::max(0, static_cast<int>(std::floor(lo_x + 0.5)));
    const int c1 = std::min(o.width - 1, static_cast<int>(std::ceil(hi_x - 0.5)));
    const int r0 = std::max(0, static_cast<int>(std::floor(lo_y + 0.5)));
    const int r1 = std::min(o.height - 1, static_cast<int>(std::ceil(hi_y - 0.5)));
    for (int r = r0; r <= r1; ++r) {
      for (int c = c0; c <= c1; ++c) covered.at<double>(r, c) += pixelCoverage(outline, c, r);
    }
  }
  cv::Mat irradiance(o.height, o.width, CV_64FC1);
  const double cx = 0.5 * (o.width - 1), cy = 0.5 * (o.height - 1);
  const double corner_sq = cx * cx + cy * cy;
  for (int r = 0; r < o.height; ++r) {
    for (int c = 0; c < o.width; ++c) {
      const double d_sq = (c - cx) * (c - cx) + (r - cy) * (r - cy);
      const double k = std::min(1.0, covered.at<double>(r, c));
      irradiance.at<double>(r, c) =
          (o.white - k * (o.white - o.black)) * (1.0 - o.vignetting * d_sq / corner_sq);
    }
  }
  if (o.blur_sigma > 0.0) irradiance = blur(irradiance, o.blur_sigma);
  std::mt19937 rng(o.seed);
  std::normal_distribution<double> noise(0.0, o.noise_sigma);
  cv::Mat image(o.height, o.width, CV_8UC1);
  for (int r = 0; r < o.height; ++r) {
    for (int c = 0; c < o.width; ++c) {
      const double linear = std::max(0.0, irradiance.at<double>(r, c)) / 255.0;
      double v = 255.0 * std::pow(linear, 1.0 / o.gamma);
      if (o.noise_sigma > 0.0) v += noise(rng);
      image.at<std::uint8_t>(r, c) =
          static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
    }
  }
  return image;
}

}  // namespace mvis
