#include "mvis/frontend/corner_refinement.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "junction_refinement.h"
#include "tag_homography.h"

namespace mvis {
namespace {

constexpr double kMaxWindowPx = 10.0;

double cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

// One pixel of a window across an edge.
struct EdgePixel {
  double t;       // offset along the inward normal from the current edge [px]
  double value;   // intensity
  double weight;  // part of its footprint inside the window
};

// A side of the detected square in pattern coordinates: from `start`, `width` cells along
// `along`, with `inward` pointing into the tag.
struct PatternSide {
  Eigen::Vector2d start, along, inward;
};

std::array<PatternSide, 4> patternSides(double w) {
  return {PatternSide{{0, 0}, {1, 0}, {0, 1}},    // top
          PatternSide{{w, 0}, {0, 1}, {-1, 0}},   // right
          PatternSide{{w, w}, {-1, 0}, {0, -1}},  // bottom
          PatternSide{{0, w}, {0, -1}, {1, 0}}};  // left
}

// The pixels of the window t in [-reach, reach] across the edge segment e0 -> e1, with
// inward normal n. Its lateral sides run along `across`, the image of the pattern's inward
// direction: under perspective the cells are sheared, and a window cut square to the edge would
// reach into the neighbouring cells.
void collectWindow(const cv::Mat& gray, const Eigen::Vector2d& e0, const Eigen::Vector2d& e1,
                   const Eigen::Vector2d& n, const Eigen::Vector2d& across, double reach,
                   std::vector<EdgePixel>* out) {
  out->clear();
  const Eigen::Vector2d d = e1 - e0;
  // p - e0 = lateral * d + m * across; lateral = cross(p - e0, across) / cross(d, across).
  const double det = d.x() * across.y() - d.y() * across.x();
  if (std::abs(det) < 1e-6) return;
  // Half the pixel's footprint along n.
  const double half = 0.5 * (std::abs(n.x()) + std::abs(n.y()));
  double lo_x = std::min({e0.x(), e1.x()}) - reach - 1.0;
  double hi_x = std::max({e0.x(), e1.x()}) + reach + 1.0;
  double lo_y = std::min({e0.y(), e1.y()}) - reach - 1.0;
  double hi_y = std::max({e0.y(), e1.y()}) + reach + 1.0;
  // The window is the parallelogram lateral in [0, 1], t in [-reach - half, reach + half]: its
  // box (a pixel wider all round) bounds the pixels to test.
  const double across_n = across.dot(n);
  if (std::abs(across_n) > 0.1) {
    double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
    for (const double lateral : {0.0, 1.0}) {
      for (const double t : {-reach - half, reach + half}) {
        const Eigen::Vector2d q = e0 + lateral * d + (t - lateral * d.dot(n)) / across_n * across;
        x0 = std::min(x0, q.x()), x1 = std::max(x1, q.x());
        y0 = std::min(y0, q.y()), y1 = std::max(y1, q.y());
      }
    }
    lo_x = std::max(lo_x, x0 - 1.0), hi_x = std::min(hi_x, x1 + 1.0);
    lo_y = std::max(lo_y, y0 - 1.0), hi_y = std::min(hi_y, y1 + 1.0);
  }
  const int c0 = std::max(0, static_cast<int>(std::ceil(lo_x)));
  const int c1 = std::min(gray.cols - 1, static_cast<int>(std::floor(hi_x)));
  const int r0 = std::max(0, static_cast<int>(std::ceil(lo_y)));
  const int r1 = std::min(gray.rows - 1, static_cast<int>(std::floor(hi_y)));
  for (int r = r0; r <= r1; ++r) {
    const auto* row = gray.ptr<std::uint8_t>(r);
    for (int c = c0; c <= c1; ++c) {
      const Eigen::Vector2d p(c - e0.x(), r - e0.y());
      // lateral = num / det in [0, 1], without the division.
      const double num = p.x() * across.y() - p.y() * across.x();
      if (det > 0.0 ? (num < 0.0 || num > det) : (num > 0.0 || num < det)) continue;
      const double t = p.dot(n);
      const double inside = std::min(t + half, reach) - std::max(t - half, -reach);
      if (inside <= 0.0) continue;
      out->push_back({t, static_cast<double>(row[c]), inside / (2.0 * half)});
    }
  }
}

// The step as one pixel sees it: the part of the pixel's square (centre at offset t along the
// unit normal n) beyond the edge at offset e. The square's area projects onto n as a trapezoid,
// a box of |n.x| convolved with a box of |n.y|; this is its cumulative distribution.
// hi, lo: the larger and smaller of |n.x|, |n.y|.
double stepSeen(double t, double e, double hi, double lo) {
  const double x = e - t;  // the edge's offset from the pixel's centre
  double below;            // part of the square before the edge
  if (lo < 1e-6) {
    below = std::clamp(x / hi + 0.5, 0.0, 1.0);
  } else if (x <= -0.5 * (hi + lo)) {
    below = 0.0;
  } else if (x < -0.5 * (hi - lo)) {
    below = (x + 0.5 * (hi + lo)) * (x + 0.5 * (hi + lo)) / (2.0 * hi * lo);
  } else if (x <= 0.5 * (hi - lo)) {
    below = lo / (2.0 * hi) + (x + 0.5 * (hi - lo)) / hi;
  } else if (x < 0.5 * (hi + lo)) {
    below = 1.0 - (0.5 * (hi + lo) - x) * (0.5 * (hi + lo) - x) / (2.0 * hi * lo);
  } else {
    below = 1.0;
  }
  return 1.0 - below;
}

// Its derivative with respect to e (negative: the step moves inwards, less of the pixel is past
// it), by the trapezoid's density.
double stepSeenSlope(double t, double e, double hi, double lo) {
  const double x = std::abs(e - t);
  if (x >= 0.5 * (hi + lo)) return 0.0;
  if (x <= 0.5 * (hi - lo) || lo < 1e-6) return -1.0 / hi;
  return -(0.5 * (hi + lo) - x) / (hi * lo);
}

// The edge offset in one window (see the header), given the levels; nullopt if not found.
std::optional<double> edgeOffset(const std::vector<EdgePixel>& pixels, double white, double black,
                                 double reach, const Eigen::Vector2d& n) {
  double area = 0.0, total = 0.0;
  for (const auto& p : pixels) {
    area += p.weight * (white - p.value) / (white - black);
    total += p.weight;
  }
  if (total <= 0.0) return std::nullopt;
  // Continuous guess, then Newton on the piecewise-linear pixel sum.
  double e = reach - area * (2.0 * reach) / total;
  const double hi = std::max(std::abs(n.x()), std::abs(n.y()));
  const double lo = std::min(std::abs(n.x()), std::abs(n.y()));
  for (int iteration = 0; iteration < 8; ++iteration) {
    double g = -area, slope = 0.0;
    for (const auto& p : pixels) {
      g += p.weight * stepSeen(p.t, e, hi, lo);
      slope += p.weight * stepSeenSlope(p.t, e, hi, lo);
    }
    if (slope >= -1e-9) break;
    const double step = -g / slope;
    e += std::clamp(step, -0.5, 0.5);
    if (std::abs(step) < 1e-4) break;
  }
  if (!(std::abs(e) < 0.9 * reach)) return std::nullopt;
  return e;
}

struct SideFit {
  Eigen::Vector2d point;      // on the edge
  Eigen::Vector2d direction;  // unit
};

// One window across a side: its pixels, where it lies along the side, and its reach.
struct Window {
  std::vector<EdgePixel> pixels;
  double lateral = 0.0;  // centre's distance along the side from its start [px]
  double reach = 0.0;    // half its extent across the edge [px]
};

// The refined edge line of one side, from the current square (homography H).
std::optional<SideFit> fitSide(const cv::Mat& gray, const TagHomography& H, const PatternSide& side,
                               int width, const TagCells& black, const Eigen::Vector2d& centre,
                               const CornerRefinementOptions& options) {
  const Eigen::Vector2d a = H(side.start), b = H(side.start + width * side.along);
  const Eigen::Vector2d along = (b - a).normalized();
  Eigen::Vector2d n(-along.y(), along.x());
  if (n.dot(centre - 0.5 * (a + b)) < 0.0) n = -n;  // inward
  // Black cells from the edge inwards in the pattern's column c along this side (at most 3).
  const auto depth = [&](int c) {
    int k = 0;
    while (k < 3) {
      const Eigen::Vector2d cell = side.start + (c + 0.5) * side.along + (k + 0.5) * side.inward;
      if (!black(static_cast<int>(std::floor(cell.y())), static_cast<int>(std::floor(cell.x())))) {
        break;
      }
      ++k;
    }
    return k;
  };
  // Cells whose data cell behind the border is black first (and the corner cells, whose
  // border column is black all along, where allowed); the others if there are none.
  for (const bool behind_black : {true, false}) {
    std::vector<Window> windows;
    double white_sum = 0.0, white_weight = 0.0, black_sum = 0.0, black_weight = 0.0;
    for (int j = 0; j < width; ++j) {
      const bool corner = j == 0 || j == width - 1;
      if (corner && !(behind_black && options.corner_cells)) continue;
      if ((depth(j) >= 2) != behind_black) continue;
      // Blur reaches across from the neighbouring columns too: the window goes deep only where
      // they are as black.
      int deep = depth(j);
      if (j > 0) deep = std::min(deep, depth(j - 1));
      if (j < width - 1) deep = std::min(deep, depth(j + 1));
      const Eigen::Vector2d mid = side.start + (j + 0.5) * side.along;
      const double cell_px = (H(mid + side.inward) - H(mid)).dot(n);
      if (!(cell_px >= options.min_cell_px)) continue;  // foreshortened here
      Window window;
      // Inside: black for two cells (one if the data cell is white); outside: white for
      // white_outside_cells. The window stops well short of either (3/4 of a cell inside, a
      // quarter outside), at most kMaxWindowPx from the edge.
      // Symmetric about the edge, so that the levels' blur cancels (see the header).
      const double reach =
          std::min({kMaxWindowPx, (deep >= 2 ? 1.25 : 0.75) * cell_px,
                    std::clamp(options.white_outside_cells - 0.25, 0.5, 1.5) * cell_px});
      window.reach = reach;
      // Corner cells: the half away from the corner (the ring's corner may be near).
      const double from = corner ? (j == 0 ? 0.45 : 0.05) : 0.25;
      const Eigen::Vector2d e0 = H(side.start + (j + from) * side.along);
      const Eigen::Vector2d e1 = H(side.start + (j + from + 0.5) * side.along);
      const Eigen::Vector2d across = (H(mid + side.inward) - H(mid)).normalized();
      collectWindow(gray, e0, e1, n, across, reach, &window.pixels);
      if (window.pixels.size() < 4) continue;
      // Levels from the outer halves of the window.
      for (const auto& p : window.pixels) {
        if (p.t <= -0.5 * reach) white_sum += p.weight * p.value, white_weight += p.weight;
        if (p.t >= 0.5 * reach) black_sum += p.weight * p.value, black_weight += p.weight;
      }
      window.lateral = (0.5 * (e0 + e1) - a).dot(along);
      windows.push_back(std::move(window));
    }
    if (windows.size() < 2 || white_weight <= 0.0 || black_weight <= 0.0) continue;
    const double white = white_sum / white_weight, dark = black_sum / black_weight;
    if (white - dark < options.min_contrast) return std::nullopt;
    // Offsets per window, then a line e(s) = alpha + beta s along the side.
    double s0 = 0, s1 = 0, s2 = 0, e_sum = 0, se_sum = 0;
    for (const auto& window : windows) {
      const auto e = edgeOffset(window.pixels, white, dark, window.reach, n);
      if (!e) continue;
      const double s = window.lateral;
      s0 += 1.0, s1 += s, s2 += s * s, e_sum += *e, se_sum += s * *e;
    }
    if (s0 < 1.0) continue;
    double alpha = e_sum / s0, beta = 0.0;
    const double det = s0 * s2 - s1 * s1;
    if (s0 >= 2.0 && det > 1e-6 * s0 * s0) {
      beta = (s0 * se_sum - s1 * e_sum) / det;
      alpha = (e_sum - beta * s1) / s0;
    }
    const double length = (b - a).norm();
    const Eigen::Vector2d p0 = a + alpha * n;
    const Eigen::Vector2d p1 = a + length * along + (alpha + beta * length) * n;
    return SideFit{p0, (p1 - p0).normalized()};
  }
  return std::nullopt;
}

// The corners from the four sides' edges, `passes` times; false if a side cannot be measured
// or a corner moves more than max_shift_px.
bool refineByEdges(const cv::Mat& gray, int width, const TagCells& black,
                   const CornerRefinementOptions& options, std::array<Eigen::Vector2d, 4>* square) {
  const std::array<Eigen::Vector2d, 4> initial = *square;
  const auto sides = patternSides(width);
  for (int pass = 0; pass < options.passes; ++pass) {
    const TagHomography H(*square, width);
    if (!H.valid()) return false;
    const Eigen::Vector2d centre = H(0.5 * width, 0.5 * width);
    std::array<SideFit, 4> lines;
    for (int k = 0; k < 4; ++k) {
      const auto line = fitSide(gray, H, sides[k], width, black, centre, options);
      if (!line) return false;
      lines[k] = *line;
    }
    for (int k = 0; k < 4; ++k) {
      // Corner k of the square joins side k - 1 (ending at it) and side k (starting at it).
      const SideFit& p = lines[(k + 3) % 4];
      const SideFit& q = lines[k];
      const double det = cross(p.direction, q.direction);
      if (std::abs(det) < 1e-3) return false;
      (*square)[k] = p.point + cross(q.point - p.point, q.direction) / det * p.direction;
      if (!(((*square)[k] - initial[k]).norm() <= options.max_shift_px)) return false;
    }
  }
  return true;
}

// Where a black square touches a corner of `square` (Kalibr's AprilGrid), that corner becomes
// the centre of the X-junction they make: found from the junction's symmetry, which gamma and
// blur keep (junction_refinement.h), where edges are moved by gamma. Returns which corners.
std::array<bool, 4> refineJunctions(const cv::Mat& gray, int width,
                                    const CornerRefinementOptions& options,
                                    std::array<Eigen::Vector2d, 4>* square) {
  std::array<bool, 4> done{false, false, false, false};
  const TagHomography H(*square, width);
  if (!H.valid()) return done;
  const double w = width;
  const std::array<Eigen::Vector2d, 4> pattern{Eigen::Vector2d(0, 0), Eigen::Vector2d(w, 0),
                                               Eigen::Vector2d(w, w), Eigen::Vector2d(0, w)};
  const auto level = [&](const Eigen::Vector2d& p) {
    const Eigen::Vector2d px = H(p);
    const int r = std::clamp(static_cast<int>(std::lround(px.y())), 0, gray.rows - 1);
    const int c = std::clamp(static_cast<int>(std::lround(px.x())), 0, gray.cols - 1);
    return static_cast<double>(gray.at<std::uint8_t>(r, c));
  };
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2d next = (pattern[(k + 1) % 4] - pattern[k]) / w;  // unit, in cells
    const Eigen::Vector2d prev = (pattern[(k + 3) % 4] - pattern[k]) / w;
    // The four sectors one cell out along the diagonals: the tag's border and the square dark,
    // the gaps light.
    const double dark = std::max(level(pattern[k] + next + prev), level(pattern[k] - next - prev));
    const double light = std::min(level(pattern[k] + next - prev), level(pattern[k] - next + prev));
    if (light - dark < options.min_contrast) continue;  // no square here
    const double cell_px = std::min((H(pattern[k] + next) - (*square)[k]).norm(),
                                    (H(pattern[k] + prev) - (*square)[k]).norm());
    const auto centre = refineJunction(gray, (*square)[k], std::clamp(1.25 * cell_px, 2.0, 8.0),
                                       options.max_shift_px);
    if (centre) (*square)[k] = *centre, done[k] = true;
  }
  return done;
}

// Whether the pattern's column c along the side is black in the border and white for `cells`
// cells behind it.
bool whiteBehind(const PatternSide& side, const TagCells& black, int c, int cells) {
  for (int k = 0; k <= cells; ++k) {
    const Eigen::Vector2d cell = side.start + (c + 0.5) * side.along + (k + 0.5) * side.inward;
    const bool dark =
        black(static_cast<int>(std::floor(cell.y())), static_cast<int>(std::floor(cell.x())));
    if (dark != (k == 0)) return false;
  }
  return true;
}

// The white and black levels of windows across edges: from their outer halves.
bool windowLevels(const std::vector<Window>& windows, double* white, double* dark) {
  double white_sum = 0.0, white_weight = 0.0, black_sum = 0.0, black_weight = 0.0;
  for (const auto& window : windows) {
    for (const auto& p : window.pixels) {
      if (p.t <= -0.5 * window.reach) white_sum += p.weight * p.value, white_weight += p.weight;
      if (p.t >= 0.5 * window.reach) black_sum += p.weight * p.value, black_weight += p.weight;
    }
  }
  if (white_weight <= 0.0 || black_weight <= 0.0) return false;
  *white = white_sum / white_weight;
  *dark = black_sum / black_weight;
  return true;
}

}  // namespace

void measureEdgeShift(const cv::Mat& gray, const TagObservation& tag, int width,
                      const TagCells& black, const CornerRefinementOptions& options,
                      EdgeShift* shift) {
  if (gray.empty() || gray.type() != CV_8UC1 || width < 4) return;
  const auto& c = tag.corners_px;
  const TagHomography H(std::array<Eigen::Vector2d, 4>{c[3], c[2], c[1], c[0]}, width);
  if (!H.valid()) return;
  const Eigen::Vector2d centre = H(0.5 * width, 0.5 * width);
  for (const PatternSide& side : patternSides(width)) {
    const Eigen::Vector2d a = H(side.start), b = H(side.start + width * side.along);
    Eigen::Vector2d n(-(b - a).normalized().y(), (b - a).normalized().x());
    if (n.dot(centre - 0.5 * (a + b)) < 0.0) n = -n;  // inward
    std::vector<Window> outer, inner;
    for (int j = 1; j < width - 1; ++j) {
      if (!whiteBehind(side, black, j, 2) || !whiteBehind(side, black, j - 1, 1) ||
          !whiteBehind(side, black, j + 1, 1)) {
        continue;
      }
      const Eigen::Vector2d mid = side.start + (j + 0.5) * side.along;
      const double cell_px = (H(mid + side.inward) - H(mid)).dot(n);
      if (!(cell_px >= options.min_cell_px)) continue;
      Window o, i;
      o.reach = i.reach = std::min(kMaxWindowPx, 0.5 * cell_px);
      const Eigen::Vector2d across = (H(mid + side.inward) - H(mid)).normalized();
      const Eigen::Vector2d p0 = side.start + (j + 0.25) * side.along;
      const Eigen::Vector2d p1 = side.start + (j + 0.75) * side.along;
      collectWindow(gray, H(p0), H(p1), n, across, o.reach, &o.pixels);
      collectWindow(gray, H(p0 + side.inward), H(p1 + side.inward), -n, across, i.reach, &i.pixels);
      if (o.pixels.size() < 4 || i.pixels.size() < 4) continue;
      outer.push_back(std::move(o));
      inner.push_back(std::move(i));
    }
    double white_o, dark_o, white_i, dark_i;
    if (outer.empty() || !windowLevels(outer, &white_o, &dark_o) ||
        !windowLevels(inner, &white_i, &dark_i) ||
        std::min(white_o - dark_o, white_i - dark_i) < options.min_contrast) {
      continue;
    }
    for (std::size_t k = 0; k < outer.size(); ++k) {
      const auto eo = edgeOffset(outer[k].pixels, white_o, dark_o, outer[k].reach, n);
      const auto ei = edgeOffset(inner[k].pixels, white_i, dark_i, inner[k].reach, -n);
      if (!eo || !ei) continue;
      // The stripe's outer edge from its centre, along n from the refined side: (eo - ei) / 2.
      shift->sum += -0.5 * (*eo - *ei) * width / (width - 1.0);
      ++shift->count;
    }
  }
}

void moveTagSides(TagObservation* tag, double px) {
  auto& c = tag->corners_px;
  const Eigen::Vector2d centre = 0.25 * (c[0] + c[1] + c[2] + c[3]);
  // Side k from corner k to k + 1, as a point and an outward normal.
  std::array<Eigen::Vector2d, 4> point, normal;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2d d = (c[(k + 1) % 4] - c[k]).normalized();
    normal[k] = Eigen::Vector2d(-d.y(), d.x());
    if (normal[k].dot(c[k] - centre) < 0.0) normal[k] = -normal[k];
    point[k] = c[k] + px * normal[k];
  }
  std::array<Eigen::Vector2d, 4> moved;
  for (int k = 0; k < 4; ++k) {
    // Corner k on sides k - 1 and k: n . x = n . point for both.
    const int p = (k + 3) % 4;
    Eigen::Matrix2d A;
    A << normal[p].transpose(), normal[k].transpose();
    const Eigen::Vector2d rhs(normal[p].dot(point[p]), normal[k].dot(point[k]));
    if (std::abs(A.determinant()) < 1e-9) return;
    moved[k] = A.lu().solve(rhs);
  }
  for (int k = 0; k < 4; ++k) c[k] = moved[k];
}

bool refineTagCorners(const cv::Mat& gray, TagObservation* tag, int width, const TagCells& black,
                      const CornerRefinementOptions& options) {
  if (gray.empty() || gray.type() != CV_8UC1 || width < 3) return false;
  // Upright top-left, top-right, bottom-right, bottom-left (mvis's order is bottom-left first).
  const auto& c = tag->corners_px;
  std::array<Eigen::Vector2d, 4> square{c[3], c[2], c[1], c[0]};
  const std::array<Eigen::Vector2d, 4> initial = square;
  // Junctions first: where all four corners have one, the edges are not needed.
  if (options.junctions) {
    const auto done = refineJunctions(gray, width, options, &square);
    if (done[0] && done[1] && done[2] && done[3]) {
      tag->corners_px = {square[3], square[2], square[1], square[0]};
      return true;
    }
    square = initial;
  }
  // Otherwise the edges, then the junctions there are from the edges' corners; without the
  // edges, only four junctions make a refined tag.
  const bool edges = refineByEdges(gray, width, black, options, &square);
  if (!edges) return false;
  if (options.junctions) refineJunctions(gray, width, options, &square);
  tag->corners_px = {square[3], square[2], square[1], square[0]};
  return true;
}

}  // namespace mvis
