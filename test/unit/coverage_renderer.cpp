#include "coverage_renderer.h"

#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace mvis::test {
namespace {

using Polygon = std::vector<Eigen::Vector2d>;

// Sutherland-Hodgman: the part of `in` on the side a * x + b * y <= c.
Polygon clip(const Polygon& in, double a, double b, double c) {
  Polygon out;
  const std::size_t n = in.size();
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d& p = in[i];
    const Eigen::Vector2d& q = in[(i + 1) % n];
    const double fp = a * p.x() + b * p.y() - c, fq = a * q.x() + b * q.y() - c;
    if (fp <= 0.0) out.push_back(p);
    if ((fp < 0.0 && fq > 0.0) || (fp > 0.0 && fq < 0.0)) {
      out.push_back(p + (fp / (fp - fq)) * (q - p));
    }
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

// A black rectangle [x0, x1] x [y0, y1] on the board.
struct Rect {
  double x0, y0, x1, y1;
};

std::vector<Rect> blackRegions(const AprilGrid& grid, bool kalibr_squares) {
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
      for (int c = 0; c < image->width;) {
        const auto black = [&](int col) {
          const bool ring_cell = r == 0 || col == 0 || r == total - 1 || col == total - 1;
          return (kalibr_squares && ring_cell) || image->buf[r * image->stride + col] < 128;
        };
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

// A kernel sampled at integer offsets, normalized; then rows and columns.
cv::Mat blur(const cv::Mat& in, double sigma) {
  const int radius = static_cast<int>(std::ceil(4.0 * sigma));
  std::vector<double> k(2 * radius + 1);
  double sum = 0.0;
  for (int i = -radius; i <= radius; ++i)
    sum += k[i + radius] = std::exp(-0.5 * i * i / (sigma * sigma));
  for (double& v : k) v /= sum;
  const auto pass = [&](const cv::Mat& src, bool rows) {
    cv::Mat dst(src.size(), CV_64FC1);
    for (int r = 0; r < src.rows; ++r) {
      for (int c = 0; c < src.cols; ++c) {
        double v = 0.0;
        for (int i = -radius; i <= radius; ++i) {
          // Edge pixels repeated beyond the image.
          const int rr = rows ? std::clamp(r + i, 0, src.rows - 1) : r;
          const int cc = rows ? c : std::clamp(c + i, 0, src.cols - 1);
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

double pixelCoverage(const Eigen::Vector2d q[4], double cx, double cy) {
  Polygon p(q, q + 4);
  p = clip(p, 1.0, 0.0, cx + 0.5);
  p = clip(p, -1.0, 0.0, -(cx - 0.5));
  p = clip(p, 0.0, 1.0, cy + 0.5);
  p = clip(p, 0.0, -1.0, -(cy - 0.5));
  return p.size() < 3 ? 0.0 : area(p);
}

cv::Mat renderByCoverage(const AprilGrid& grid, const SE3& T_cam_board, const CoverageOptions& o) {
  cv::Mat covered = cv::Mat::zeros(o.height, o.width, CV_64FC1);
  const auto project = [&](double x, double y) {
    const Eigen::Vector3d X = T_cam_board * Eigen::Vector3d(x, y, 0.0);
    return Eigen::Vector2d(o.intrinsics[0] * X.x() / X.z() + o.intrinsics[2],
                           o.intrinsics[1] * X.y() / X.z() + o.intrinsics[3]);
  };
  for (const Rect& rect : blackRegions(grid, o.kalibr_squares)) {
    const Eigen::Vector2d q[4] = {project(rect.x0, rect.y0), project(rect.x1, rect.y0),
                                  project(rect.x1, rect.y1), project(rect.x0, rect.y1)};
    double lo_x = q[0].x(), hi_x = lo_x, lo_y = q[0].y(), hi_y = lo_y;
    for (const auto& v : q) {
      lo_x = std::min(lo_x, v.x()), hi_x = std::max(hi_x, v.x());
      lo_y = std::min(lo_y, v.y()), hi_y = std::max(hi_y, v.y());
    }
    const int c0 = std::max(0, static_cast<int>(std::floor(lo_x + 0.5)));
    const int c1 = std::min(o.width - 1, static_cast<int>(std::ceil(hi_x - 0.5)));
    const int r0 = std::max(0, static_cast<int>(std::floor(lo_y + 0.5)));
    const int r1 = std::min(o.height - 1, static_cast<int>(std::ceil(hi_y - 0.5)));
    for (int r = r0; r <= r1; ++r) {
      for (int c = c0; c <= c1; ++c) covered.at<double>(r, c) += pixelCoverage(q, c, r);
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

}  // namespace mvis::test
