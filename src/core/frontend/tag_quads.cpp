#include "tag_quads.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <optional>

namespace mvis {
namespace {

// The darkest and brightest values around every tile of a region of the image.
struct LocalLevels {
  int tile = 8;
  int tx0 = 0, ty0 = 0;  // the first tile of lo and hi
  cv::Mat lo, hi;        // per tile, over its 5 x 5 tile neighbourhood
  int lo_at(int ty, int tx) const { return lo.at<std::uint8_t>(ty - ty0, tx - tx0); }
  int hi_at(int ty, int tx) const { return hi.at<std::uint8_t>(ty - ty0, tx - tx0); }
};

// The tile size depends on the whole image only, so that a region's levels are the whole
// image's there.
int tileSize(const cv::Mat& gray) { return std::min(gray.cols, gray.rows) >= 400 ? 8 : 4; }

// Levels for the tiles that `region` touches. They are computed over two more tiles all round
// (the neighbourhood's reach), so that they equal the whole image's.
LocalLevels localLevels(const cv::Mat& gray, const cv::Rect& region) {
  LocalLevels levels;
  const int tile = levels.tile = tileSize(gray);
  const int image_tiles_x = (gray.cols + tile - 1) / tile;
  const int image_tiles_y = (gray.rows + tile - 1) / tile;
  const int tx0 = std::max(0, region.x / tile - 2), ty0 = std::max(0, region.y / tile - 2);
  const int tx1 = std::min(image_tiles_x, (region.x + region.width - 1) / tile + 3);
  const int ty1 = std::min(image_tiles_y, (region.y + region.height - 1) / tile + 3);
  const int tiles_x = tx1 - tx0, tiles_y = ty1 - ty0;
  cv::Mat lo(tiles_y, tiles_x, CV_8UC1), hi(tiles_y, tiles_x, CV_8UC1);
  for (int ty = 0; ty < tiles_y; ++ty) {
    auto* lo_row = lo.ptr<std::uint8_t>(ty);
    auto* hi_row = hi.ptr<std::uint8_t>(ty);
    std::fill(lo_row, lo_row + tiles_x, 255);
    std::fill(hi_row, hi_row + tiles_x, 0);
    for (int r = (ty0 + ty) * tile; r < std::min(gray.rows, (ty0 + ty + 1) * tile); ++r) {
      const auto* row = gray.ptr<std::uint8_t>(r);
      for (int tx = 0; tx < tiles_x; ++tx) {
        std::uint8_t lo_value = lo_row[tx], hi_value = hi_row[tx];
        for (int c = (tx0 + tx) * tile; c < std::min(gray.cols, (tx0 + tx + 1) * tile); ++c) {
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
  levels.tx0 = tx0;
  levels.ty0 = ty0;
  return levels;
}

// A horizontal run of black pixels [c0, c1) in row `row` (image coordinates).
struct Run {
  int row, c0, c1;
};

// The runs of black pixels of `roi` by the rule in the header with `margin`, row by row, left to
// right; row_start[r] is the first run of the region's row r (row_start has height + 1 entries).
void blackRuns(const cv::Mat& gray, const LocalLevels& levels, const cv::Rect& roi, double margin,
               double min_contrast, std::vector<Run>* runs, std::vector<int>* row_start) {
  const int tile = levels.tile;
  const int tx0 = roi.x / tile, ty0 = roi.y / tile;
  const int tiles_x = (roi.x + roi.width - 1) / tile - tx0 + 1;
  const int tiles_y = (roi.y + roi.height - 1) / tile - ty0 + 1;
  // Per tile of the region: the level below which a pixel is black (-1: none, too little
  // contrast).
  std::vector<int> below(static_cast<std::size_t>(tiles_x) * tiles_y);
  for (int ty = 0; ty < tiles_y; ++ty) {
    for (int tx = 0; tx < tiles_x; ++tx) {
      const double a = levels.lo_at(ty0 + ty, tx0 + tx), b = levels.hi_at(ty0 + ty, tx0 + tx);
      below[ty * tiles_x + tx] =
          b - a < min_contrast ? -1 : static_cast<int>(std::ceil(0.5 * (a + b) - margin * (b - a)));
    }
  }
  runs->clear();
  row_start->assign(roi.height + 1, 0);
  for (int r = 0; r < roi.height; ++r) {
    (*row_start)[r] = static_cast<int>(runs->size());
    const auto* row = gray.ptr<std::uint8_t>(roi.y + r);
    const int* level = &below[((roi.y + r) / tile - ty0) * tiles_x];
    int open = -1;  // the start of the run being read
    for (int tx = tx0; tx < tx0 + tiles_x; ++tx) {
      const int threshold = level[tx - tx0];
      const int begin = std::max(roi.x, tx * tile);
      const int end = std::min(roi.x + roi.width, (tx + 1) * tile);
      if (threshold < 0) {  // nothing black in this tile
        if (open >= 0) runs->push_back({roi.y + r, open, begin}), open = -1;
        continue;
      }
      for (int c = begin; c < end; ++c) {
        const bool black = row[c] < threshold;
        if (black && open < 0) open = c;
        if (!black && open >= 0) runs->push_back({roi.y + r, open, c}), open = -1;
      }
    }
    if (open >= 0) runs->push_back({roi.y + r, open, roi.x + roi.width});
  }
  (*row_start)[roi.height] = static_cast<int>(runs->size());
}

// 4-connected components of runs (runs of adjacent rows that share a column), numbered in the
// order of their first pixel in a raster scan; per run, its component.
int runComponents(const std::vector<Run>& runs, const std::vector<int>& row_start,
                  std::vector<int>* component) {
  std::vector<int> parent(runs.size());
  for (std::size_t i = 0; i < runs.size(); ++i) parent[i] = static_cast<int>(i);
  const auto find = [&](int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  for (std::size_t r = 1; r + 1 < row_start.size(); ++r) {
    int j = row_start[r - 1];
    const int j_end = row_start[r];
    for (int i = row_start[r]; i < row_start[r + 1]; ++i) {
      while (j < j_end && runs[j].c1 <= runs[i].c0) ++j;
      for (int k = j; k < j_end && runs[k].c0 < runs[i].c1; ++k) {
        const int a = find(i), b = find(k);
        if (a != b) parent[std::max(a, b)] = std::min(a, b);  // the earlier run is the root
      }
    }
  }
  component->assign(runs.size(), -1);
  int count = 0;
  for (std::size_t i = 0; i < runs.size(); ++i) {
    const int root = find(static_cast<int>(i));
    (*component)[i] = root == static_cast<int>(i) ? count++ : (*component)[root];
  }
  return count;
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

// Keeps the runs (and the parts of runs) that lie inside `within` (row by row, left to right).
void keepWithin(const std::vector<Run>& within, std::vector<Run>* runs, std::vector<int>* row_start,
                int first_row) {
  std::vector<Run> kept;
  std::vector<int> starts(row_start->size(), 0);
  std::size_t w = 0;
  for (std::size_t r = 0; r + 1 < row_start->size(); ++r) {
    starts[r] = static_cast<int>(kept.size());
    const int row = first_row + static_cast<int>(r);
    while (w < within.size() && within[w].row < row) ++w;
    for (int i = (*row_start)[r]; i < (*row_start)[r + 1]; ++i) {
      for (std::size_t k = w; k < within.size() && within[k].row == row; ++k) {
        const int c0 = std::max((*runs)[i].c0, within[k].c0);
        const int c1 = std::min((*runs)[i].c1, within[k].c1);
        if (c0 < c1) kept.push_back({row, c0, c1});
      }
    }
  }
  starts.back() = static_cast<int>(kept.size());
  *runs = std::move(kept);
  *row_start = std::move(starts);
}

// Quads of the black components in `roi`; a component too big and shaped too badly to be one
// tag (tags joined through a junction pixel, e.g. where an edge and noise meet) is looked at
// again with a larger margin, up to twice: its own pixels only (`within`), so that what is found
// depends on the component alone, not on the others its box overlaps.
void quadsIn(const cv::Mat& gray, const LocalLevels& levels, const cv::Rect& roi, double margin,
             int retries, const QuadFinderOptions& options, std::vector<Quad>* quads,
             const std::vector<Run>* within = nullptr) {
  std::vector<Run> runs;
  std::vector<int> row_start, component;
  blackRuns(gray, levels, roi, margin, options.min_contrast, &runs, &row_start);
  if (within) keepWithin(*within, &runs, &row_start, roi.y);
  const int count = runComponents(runs, row_start, &component);
  // Per component: its box (image coordinates, inclusive), its area and its runs.
  struct Box {
    int x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1, area = 0;
    std::vector<int> runs;
  };
  std::vector<Box> boxes(count);
  for (std::size_t i = 0; i < runs.size(); ++i) {
    Box& box = boxes[component[i]];
    const Run& run = runs[i];
    box.x0 = std::min(box.x0, run.c0), box.x1 = std::max(box.x1, run.c1 - 1);
    box.y0 = std::min(box.y0, run.row), box.y1 = std::max(box.y1, run.row);
    box.area += run.c1 - run.c0;
    box.runs.push_back(static_cast<int>(i));
  }
  cv::Mat mask;
  std::vector<std::vector<cv::Point>> contours;
  for (const Box& b : boxes) {
    // In the region's coordinates, as the checks below were written.
    const int x = b.x0 - roi.x, y = b.y0 - roi.y, w = b.x1 - b.x0 + 1, h = b.y1 - b.y0 + 1;
    if (w < options.min_side_px || h < options.min_side_px) continue;
    // Touching the border of the image or of the region: the tag may be cut off.
    if (x == 0 || y == 0 || x + w == roi.width || y + h == roi.height) continue;
    if (b.area < 2 * options.min_side_px * 2) continue;
    // The component alone, with a row and column of background all round.
    mask.create(h + 2, w + 2, CV_8UC1);
    mask.setTo(0);
    for (const int i : b.runs) {
      const Run& run = runs[i];
      auto* row = mask.ptr<std::uint8_t>(run.row - b.y0 + 1);
      std::fill(row + run.c0 - b.x0 + 1, row + run.c1 - b.x0 + 1, 255);
    }
    contours.clear();
    cv::findContours(mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE,
                     cv::Point(b.x0 - 1, b.y0 - 1));
    if (contours.empty()) continue;
    const auto largest =
        std::max_element(contours.begin(), contours.end(),
                         [](const auto& a, const auto& b) { return a.size() < b.size(); });
    if (auto quad = quadOfContour(*largest, b.area, options.min_side_px)) {
      quads->push_back(*quad);
    } else if (retries > 0 && w >= 2 * options.min_side_px && h >= 2 * options.min_side_px) {
      const cv::Rect again = cv::Rect(roi.x + x - 2, roi.y + y - 2, w + 4, h + 4) &
                             cv::Rect(0, 0, gray.cols, gray.rows);
      std::vector<Run> own;
      own.reserve(b.runs.size());
      for (const int i : b.runs) own.push_back(runs[i]);
      quadsIn(gray, levels, again, margin + 0.1, retries - 1, options, quads, &own);
    }
  }
}

}  // namespace

std::vector<Quad> findQuads(const cv::Mat& gray, const QuadFinderOptions& options) {
  return findQuads(gray, cv::Rect(0, 0, gray.cols, gray.rows), options);
}

std::vector<Quad> findQuads(const cv::Mat& gray, const cv::Rect& region,
                            const QuadFinderOptions& options) {
  std::vector<Quad> quads;
  if (gray.empty() || gray.type() != CV_8UC1) return quads;
  const cv::Rect roi = region & cv::Rect(0, 0, gray.cols, gray.rows);
  if (roi.width < 3 || roi.height < 3) return quads;
  const LocalLevels levels = localLevels(gray, roi);
  quadsIn(gray, levels, roi, options.margin, 2, options, &quads);
  return quads;
}

}  // namespace mvis
