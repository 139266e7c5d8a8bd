#include "mvis/frontend/corner_refinement.h"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

namespace mvis {
namespace {

constexpr double kProfileStepPx = 0.25;

// Bilinear intensity at (u, v) in mvis's pixel convention; nullopt outside the image.
std::optional<double> sample(const cv::Mat& gray, double u, double v) {
  const int c = static_cast<int>(std::floor(u));
  const int r = static_cast<int>(std::floor(v));
  if (c < 0 || r < 0 || c + 1 >= gray.cols || r + 1 >= gray.rows) return std::nullopt;
  const double a = u - c, b = v - r;
  const auto* row0 = gray.ptr<std::uint8_t>(r);
  const auto* row1 = gray.ptr<std::uint8_t>(r + 1);
  return (1 - b) * ((1 - a) * row0[c] + a * row0[c + 1]) +
         b * ((1 - a) * row1[c] + a * row1[c + 1]);
}

// Offset along `normal` from `point` of the edge between the tag's side (negative offsets)
// and the outside. The profile is normalized between its two end levels; its area is the
// length of the outer part of the window, so offset = reach - area. Box filtering by pixels
// preserves area, which makes this exact for a straight step edge whatever its phase within a
// pixel (a halfway crossing of the interpolated profile is not). nullopt if the profile is
// flat, leaves the image, or puts the edge outside the window.
std::optional<double> edgeOffset(const cv::Mat& gray, const Eigen::Vector2d& point,
                                 const Eigen::Vector2d& normal, double reach_px,
                                 double min_contrast) {
  const int half = static_cast<int>(std::floor(reach_px / kProfileStepPx));
  const double reach = half * kProfileStepPx;
  std::vector<double> profile(2 * half + 1);
  for (int k = -half; k <= half; ++k) {
    const Eigen::Vector2d p = point + (k * kProfileStepPx) * normal;
    const auto value = sample(gray, p.x(), p.y());
    if (!value) return std::nullopt;
    profile[k + half] = *value;
  }
  // Levels from the last quarter of the window on either side.
  const int quarter = std::max(1, half / 4);
  double inner = 0.0, outer = 0.0;
  for (int k = 0; k < quarter; ++k) {
    inner += profile[k];
    outer += profile[2 * half - k];
  }
  inner /= quarter;
  outer /= quarter;
  if (std::abs(outer - inner) < min_contrast) return std::nullopt;
  double area = 0.0;  // trapezoidal rule over the normalized profile
  for (int k = 0; k < 2 * half; ++k) {
    const double f0 = (profile[k] - inner) / (outer - inner);
    const double f1 = (profile[k + 1] - inner) / (outer - inner);
    area += 0.5 * (f0 + f1) * kProfileStepPx;
  }
  const double offset = reach - area;
  if (std::abs(offset) > 0.75 * reach) return std::nullopt;
  return offset;
}

struct Line {
  Eigen::Vector2d point;
  Eigen::Vector2d direction;  // unit
};

std::optional<Line> fitLine(const std::vector<Eigen::Vector2d>& points) {
  if (points.size() < 3) return std::nullopt;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
  for (const auto& p : points) scatter += (p - mean) * (p - mean).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> solver(scatter);
  return Line{mean, solver.eigenvectors().col(1)};  // largest eigenvalue: along the line
}

std::optional<Eigen::Vector2d> intersect(const Line& a, const Line& b) {
  Eigen::Matrix2d A;
  A << a.direction, -b.direction;
  if (std::abs(A.determinant()) < 1e-6) return std::nullopt;
  const Eigen::Vector2d t = A.inverse() * (b.point - a.point);
  return a.point + t[0] * a.direction;
}

}  // namespace

bool refineTagCorners(const cv::Mat& gray, TagObservation* tag,
                      const CornerRefinementOptions& options) {
  if (gray.empty() || gray.type() != CV_8UC1) return false;
  const auto& corners = tag->corners_px;
  const Eigen::Vector2d centre = 0.25 * (corners[0] + corners[1] + corners[2] + corners[3]);
  for (int i = 0; i < 4; ++i) {
    if ((corners[(i + 1) % 4] - corners[i]).norm() / options.width_at_border <
        options.min_cell_px) {
      return false;
    }
  }
  std::array<Line, 4> sides;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d& a = corners[i];
    const Eigen::Vector2d& b = corners[(i + 1) % 4];
    const double length = (b - a).norm();
    if (length < 4.0) return false;
    const Eigen::Vector2d along = (b - a) / length;
    Eigen::Vector2d normal(-along.y(), along.x());
    if (normal.dot(0.5 * (a + b) - centre) < 0.0) normal = -normal;  // pointing out of the tag
    // Stay within the single cell of border on either side of the edge.
    const double cell_px = length / options.width_at_border;
    const double reach = std::clamp(0.7 * cell_px, 1.0, 4.0);
    const int count = std::max(5, static_cast<int>(length * (1.0 - 2.0 * options.edge_margin)));
    std::vector<Eigen::Vector2d> points;
    points.reserve(count);
    for (int k = 0; k < count; ++k) {
      const double s = options.edge_margin + (1.0 - 2.0 * options.edge_margin) * (k + 0.5) / count;
      const Eigen::Vector2d p = a + s * (b - a);
      const auto offset = edgeOffset(gray, p, normal, reach, options.min_contrast);
      if (offset) points.push_back(p + *offset * normal);
    }
    const auto line = fitLine(points);
    if (!line) return false;
    sides[i] = *line;
  }
  std::array<Eigen::Vector2d, 4> refined;
  for (int i = 0; i < 4; ++i) {
    // Corner i joins side i - 1 (ending at it) and side i (starting at it).
    const auto corner = intersect(sides[(i + 3) % 4], sides[i]);
    if (!corner || (*corner - corners[i]).norm() > options.max_shift_px) return false;
    refined[i] = *corner;
  }
  tag->corners_px = refined;
  return true;
}

}  // namespace mvis
