#include "tag_quads.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <optional>

namespace mvis {
namespace {

// The darkest and brightest values around every tile of the image.
struct LocalLevels {
  int tile = 8;
  cv::Mat lo, hi;  // per tile, over its 5 x 5 tile neighbourhood
};

LocalLevels localLevels(const cv::Mat& gray) {
  LocalLevels levels;
  const int tile = levels.tile = std::min(gray.cols, gray.rows) >= 400 ? 8 : 4;
  const int tiles_y = (gray.rows + tile - 1) / tile;
  const int tiles_x = (gray.cols + tile - 1) / tile;
  cv::Mat lo(tiles_y, tiles_x, CV_8UC1), hi(tiles_y, tiles_x, CV_8UC1);
  for (int ty = 0; ty < tiles_y; ++ty) {
    auto* lo_row = lo.ptr<std::uint8_t>(ty);
    auto* hi_row = hi.ptr<std::uint8_t>(ty);
    std::fill(lo_row, lo_row + tiles_x, 255);
    std::fill(hi_row, hi_row + tiles_x, 0);
    for (int r = ty * tile; r < std::min(gray.rows, (ty + 1) * tile); ++r) {
      const auto* row = gray.ptr<std::uint8_t>(r);
      for (int tx = 0; tx < tiles_x; ++tx) {
        std::uint8_t lo_value = lo_row[tx], hi_value = hi_row[tx];
        for (int c = tx * tile; c < std::min(gray.cols, (tx + 1) * tile); ++c) {
          lo_value = std::min(lo_value, row[c]);
          hi_value = std::max(hi_value, row[c]);
        }
        lo_row[tx] = lo_value;
        hi_row[tx] = hi_value;
      }
    }
  }
  const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(5, 5));
  cv::erode(lo, levels.lo, kernel, cv::Point(-1, -1), 1, cv::BORDER_REPLICATE);
  cv::dilate(hi, levels.hi, kernel, cv::Point(-1, -1), 1, cv::BORDER_REPLICATE);
  return levels;
}

// 255 where a pixel of `roi` is black by the rule in the header with `margin`, 0 elsewhere.
cv::Mat blackMask(const cv::Mat& gray, const LocalLevels& levels, const cv::Rect& roi,
                  double margin, double min_contrast) {
  const int tile = levels.tile;
  const int tiles_x = levels.lo.cols;
  // Per tile: the level below which a pixel is black (-1: none, too little contrast).
  std::vector<int> below(static_cast<std::size_t>(tiles_x) * levels.lo.rows);
  for (int ty = roi.y / tile; ty <= (roi.y + roi.height - 1) / tile; ++ty) {
    for (int tx = roi.x / tile; tx <= (roi.x + roi.width - 1) / tile; ++tx) {
      const double a = levels.lo.at<std::uint8_t>(ty, tx), b = levels.hi.at<std::uint8_t>(ty, tx);
      below[ty * tiles_x + tx] =
          b - a < min_contrast ? -1 : static_cast<int>(std::ceil(0.5 * (a + b) - margin * (b - a)));
    }
  }
  cv::Mat mask(roi.size(), CV_8UC1);
  for (int r = 0; r < roi.height; ++r) {
    const auto* row = gray.ptr<std::uint8_t>(roi.y + r);
    auto* out = mask.ptr<std::uint8_t>(r) - roi.x;
    const int* level = &below[((roi.y + r) / tile) * tiles_x];
    for (int tx = roi.x / tile; tx <= (roi.x + roi.width - 1) / tile; ++tx) {
      const int threshold = level[tx];
      const int end = std::min(roi.x + roi.width, (tx + 1) * tile);
      for (int c = std::max(roi.x, tx * tile); c < end; ++c) out[c] = row[c] < threshold ? 255 : 0;
    }
  }
  return mask;
}

double cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

// Total-least-squares line through points: (point on it, unit direction).
std::optional<std::pair<Eigen::Vector2d, Eigen::Vector2d>> fitLine(
    const std::vector<cv::Point>& contour, int first, int count) {
  const int n = static_cast<int>(contour.size());
  if (count < 2) return std::nullopt;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (int k = 0; k < count; ++k) {
    const cv::Point& p = contour[(first + k) % n];
    mean += Eigen::Vector2d(p.x, p.y);
  }
  mean /= count;
  Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
  for (int k = 0; k < count; ++k) {
    const cv::Point& p = contour[(first + k) % n];
    const Eigen::Vector2d d = Eigen::Vector2d(p.x, p.y) - mean;
    scatter += d * d.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> solver(scatter);
  return std::make_pair(mean, Eigen::Vector2d(solver.eigenvectors().col(1)));
}

// The quad of one component's outer contour (pixel coordinates of the black boundary pixels).
std::optional<Quad> quadOfContour(const std::vector<cv::Point>& contour, int area_px,
                                  int min_side_px) {
  const int n = static_cast<int>(contour.size());
  if (n < 4 * min_side_px / 2) return std::nullopt;
  std::vector<int> hull;
  cv::convexHull(contour, hull, false, false);
  if (hull.size() < 4) return std::nullopt;
  const auto at = [&](int i) { return Eigen::Vector2d(contour[i].x, contour[i].y); };
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  for (int i : hull) centre += at(i);
  centre /= static_cast<double>(hull.size());
  // Greedy largest quadrilateral on the hull: the point farthest from the centre, the point
  // farthest from it, and the farthest on either side of the diagonal they make.
  int i0 = hull[0], i2 = hull[0], i1 = -1, i3 = -1;
  for (int i : hull) {
    if ((at(i) - centre).squaredNorm() > (at(i0) - centre).squaredNorm()) i0 = i;
  }
  for (int i : hull) {
    if ((at(i) - at(i0)).squaredNorm() > (at(i2) - at(i0)).squaredNorm()) i2 = i;
  }
  double most = 0.0, least = 0.0;
  for (int i : hull) {
    const double side = cross(at(i2) - at(i0), at(i) - at(i0));
    if (side > most) most = side, i1 = i;
    if (side < least) least = side, i3 = i;
  }
  if (i1 < 0 || i3 < 0) return std::nullopt;
  // Corners in contour order.
  std::array<int, 4> idx{i0, i1, i2, i3};
  std::sort(idx.begin(), idx.end());
  Quad rough;
  for (int k = 0; k < 4; ++k) rough[k] = at(idx[k]);
  double area = 0.0;
  for (int k = 0; k < 4; ++k) area += cross(rough[k], rough[(k + 1) % 4]);
  if (std::abs(area) < 2.0 * min_side_px * min_side_px) return std::nullopt;
  // Solid (Kalibr's squares, dark blobs): a tag's component is its border and the black data
  // cells touching it, never more than ~90% of its square. The contour runs through pixel
  // centres: the square the pixels cover is half a pixel wider all round.
  double perimeter = 0.0;
  for (int k = 0; k < 4; ++k) perimeter += (rough[(k + 1) % 4] - rough[k]).norm();
  if (area_px > 0.93 * (0.5 * std::abs(area) + 0.5 * perimeter + 1.0)) return std::nullopt;
  // The whole contour must follow the four sides.
  double shortest = 1e9;
  for (int k = 0; k < 4; ++k) shortest = std::min(shortest, (rough[(k + 1) % 4] - rough[k]).norm());
  if (shortest < min_side_px) return std::nullopt;
  // Loose: lens distortion bends sides, blur rounds corners; reading the code is the real test.
  const double tolerance = std::max(2.0, 0.12 * shortest);
  std::array<std::pair<Eigen::Vector2d, Eigen::Vector2d>, 4> lines;
  int astray = 0;  // contour points off the sides: a bump (a square still attached at a
                   // corner, a blob of noise) may be tolerated, a different shape not
  for (int k = 0; k < 4; ++k) {
    const int first = idx[k];
    const int count = (idx[(k + 1) % 4] - first + n) % n;
    const Eigen::Vector2d a = rough[k], b = rough[(k + 1) % 4];
    const Eigen::Vector2d along = (b - a).normalized();
    for (int j = 0; j <= count; ++j) {
      const double off = std::abs(cross(along, at((first + j) % n) - a));
      if (off > 3.0 * tolerance) return std::nullopt;
      astray += off > tolerance;
    }
    // The middle 70% of the side: corners are rounded by blur and thresholding.
    const int skip = count * 15 / 100;
    const auto line = fitLine(contour, first + skip, count + 1 - 2 * skip);
    if (!line) return std::nullopt;
    lines[k] = *line;
  }
  if (astray > n / 8) return std::nullopt;
  Quad quad;
  for (int k = 0; k < 4; ++k) {
    // Corner k joins side k - 1 and side k.
    const auto& [pa, da] = lines[(k + 3) % 4];
    const auto& [pb, db] = lines[k];
    const double det = cross(da, db);
    if (std::abs(det) < 0.2) return std::nullopt;  // sides within ~12 degrees of parallel
    const double t = cross(pb - pa, db) / det;
    quad[k] = pa + t * da;
    if ((quad[k] - rough[k]).norm() > tolerance + 2.0) return std::nullopt;
  }
  // Clockwise in the image (y down), and the lines half a pixel outwards: the contour runs
  // through the centres of the outermost black pixels.
  area = 0.0;
  for (int k = 0; k < 4; ++k) area += cross(quad[k], quad[(k + 1) % 4]);
  if (area < 0.0) std::swap(quad[1], quad[3]);
  const Eigen::Vector2d mid = 0.25 * (quad[0] + quad[1] + quad[2] + quad[3]);
  for (auto& q : quad) q += 0.5 * std::sqrt(2.0) * (q - mid).normalized();
  return quad;
}

// Quads of the black components in `roi`; a component too big and shaped too badly to be one
// tag (tags joined through a junction pixel, e.g. where an edge and noise meet) is looked at
// again with a larger margin, up to twice.
void quadsIn(const cv::Mat& gray, const LocalLevels& levels, const cv::Rect& roi, double margin,
             int retries, const QuadFinderOptions& options, std::vector<Quad>* quads) {
  const cv::Mat mask = blackMask(gray, levels, roi, margin, options.min_contrast);
  cv::Mat labels, stats, centroids;
  const int count = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 4, CV_32S);
  cv::Mat component;
  std::vector<std::vector<cv::Point>> contours;
  for (int k = 1; k < count; ++k) {
    const int x = stats.at<int>(k, cv::CC_STAT_LEFT), y = stats.at<int>(k, cv::CC_STAT_TOP);
    const int w = stats.at<int>(k, cv::CC_STAT_WIDTH), h = stats.at<int>(k, cv::CC_STAT_HEIGHT);
    const int area = stats.at<int>(k, cv::CC_STAT_AREA);
    if (w < options.min_side_px || h < options.min_side_px) continue;
    // Touching the border of the image or of the region: the tag may be cut off.
    if (x == 0 || y == 0 || x + w == roi.width || y + h == roi.height) continue;
    if (area < 2 * options.min_side_px * 2) continue;
    const cv::Rect box(x - 1, y - 1, w + 2, h + 2);
    cv::compare(labels(box), k, component, cv::CMP_EQ);
    contours.clear();
    cv::findContours(component, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE,
                     cv::Point(roi.x + box.x, roi.y + box.y));
    if (contours.empty()) continue;
    const auto largest =
        std::max_element(contours.begin(), contours.end(),
                         [](const auto& a, const auto& b) { return a.size() < b.size(); });
    if (auto quad = quadOfContour(*largest, area, options.min_side_px)) {
      quads->push_back(*quad);
    } else if (retries > 0 && w >= 2 * options.min_side_px && h >= 2 * options.min_side_px) {
      const cv::Rect again = cv::Rect(roi.x + x - 2, roi.y + y - 2, w + 4, h + 4) &
                             cv::Rect(0, 0, gray.cols, gray.rows);
      quadsIn(gray, levels, again, margin + 0.1, retries - 1, options, quads);
    }
  }
}

}  // namespace

std::vector<Quad> findQuads(const cv::Mat& gray, const QuadFinderOptions& options) {
  std::vector<Quad> quads;
  if (gray.empty() || gray.type() != CV_8UC1) return quads;
  const LocalLevels levels = localLevels(gray);
  quadsIn(gray, levels, cv::Rect(0, 0, gray.cols, gray.rows), options.margin, 2, options, &quads);
  return quads;
}

}  // namespace mvis
