#include "tag_reading.h"

#include <Eigen/Dense>
#include <array>
#include <cmath>

#include "image_sampling.h"
#include "tag_homography.h"

namespace mvis {
namespace {

constexpr double kSharpening = 0.25;

// Least-squares plane v = c0 + c1 x + c2 y through samples (x, y, v), accumulated.
struct PlaneFit {
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  void add(double x, double y, double v) {
    const Eigen::Vector3d row(1.0, x, y);
    A += row * row.transpose();
    b += row * v;
  }
  Eigen::Vector3d solve() const { return A.ldlt().solve(b); }
};

}  // namespace

std::optional<TagObservation> readTag(const cv::Mat& gray, const Quad& quad,
                                      const TagCodebook& codebook, int border,
                                      const TagReadingOptions& options) {
  const int d = codebook.dataWidth();
  const int w = d + 2 * border;
  const TagHomography H(quad, w);
  if (!H.valid()) return std::nullopt;
  // The mean of four samples around a cell's centre (x, y in cells); false outside the image.
  const auto cellValue = [&](double x, double y, double* value) {
    double sum = 0.0;
    for (const double dy : {-0.2, 0.2}) {
      for (const double dx : {-0.2, 0.2}) {
        const Eigen::Vector2d p = H(x + dx, y + dy);
        double v;
        if (!bilinear(gray, p.x(), p.y(), &v)) return false;
        sum += v;
      }
    }
    *value = 0.25 * sum;
    return true;
  };
  // The square and the ring around it, (W + 2) x (W + 2) cells; cell (r, c) of the square is
  // grid[(r + 1) * (W + 2) + c + 1].
  constexpr int kMaxGrid = 16;  // W <= 14: data of at most 8 cells, border at most 2
  const int g = w + 2;
  if (g > kMaxGrid) return std::nullopt;
  std::array<double, kMaxGrid * kMaxGrid> grid;
  for (int r = -1; r <= w; ++r) {
    for (int c = -1; c <= w; ++c) {
      if (!cellValue(c + 0.5, r + 0.5, &grid[(r + 1) * g + c + 1])) return std::nullopt;
    }
  }
  // Blur makes a lone white cell among black ones grey (and the reverse): sharpened by a
  // Laplacian over the four neighbouring cells, as libapriltag does.
  std::array<double, kMaxGrid * kMaxGrid> cells;
  for (int r = 0; r < w; ++r) {
    for (int c = 0; c < w; ++c) {
      const double* v = &grid[(r + 1) * g + c + 1];
      cells[r * w + c] = v[0] + kSharpening * (4.0 * v[0] - v[-1] - v[1] - v[-g] - v[g]);
    }
  }
  PlaneFit dark, light;
  for (int r = 0; r < w; ++r) {
    for (int c = 0; c < w; ++c) {
      if (r < border || c < border || r >= w - border || c >= w - border) {
        dark.add(c + 0.5, r + 0.5, grid[(r + 1) * g + c + 1]);
      }
    }
  }
  // The ring's samples, as (x, y, value), for the plane and for the count of dark ones.
  std::array<Eigen::Vector3d, 4 * kMaxGrid> ring;
  int ring_size = 0;
  for (int k = 1; k < w - 1; ++k) {
    ring[ring_size++] = Eigen::Vector3d(k + 0.5, -0.5, grid[k + 1]);
    ring[ring_size++] = Eigen::Vector3d(k + 0.5, w + 0.5, grid[(w + 1) * g + k + 1]);
    ring[ring_size++] = Eigen::Vector3d(-0.5, k + 0.5, grid[(k + 1) * g]);
    ring[ring_size++] = Eigen::Vector3d(w + 0.5, k + 0.5, grid[(k + 1) * g + w + 1]);
  }
  for (int k = 0; k < ring_size; ++k) light.add(ring[k].x(), ring[k].y(), ring[k].z());
  const Eigen::Vector3d black = dark.solve(), white = light.solve();
  const auto threshold = [&](double x, double y) {
    return 0.5 * (black.dot(Eigen::Vector3d(1, x, y)) + white.dot(Eigen::Vector3d(1, x, y)));
  };
  const double contrast =
      (white - black).dot(Eigen::Vector3d(1.0, 0.5 * w, 0.5 * w));  // at the centre
  if (!(contrast >= options.min_contrast)) return std::nullopt;
  int dark_ring = 0;
  for (int k = 0; k < ring_size; ++k) {
    dark_ring += ring[k].z() < threshold(ring[k].x(), ring[k].y());
  }
  if (4 * dark_ring > ring_size) return std::nullopt;
  int white_border = 0;
  for (int r = 0; r < w; ++r) {
    for (int c = 0; c < w; ++c) {
      if (r < border || c < border || r >= w - border || c >= w - border) {
        white_border += cells[r * w + c] >= threshold(c + 0.5, r + 0.5);
      }
    }
  }
  if (white_border > options.max_hamming) return std::nullopt;
  std::uint64_t word = 0;
  for (int r = 0; r < d; ++r) {
    for (int c = 0; c < d; ++c) {
      const int row = r + border, col = c + border;
      if (cells[row * w + col] < threshold(col + 0.5, row + 0.5)) {
        word |= std::uint64_t{1} << (r * d + c);
      }
    }
  }
  const auto decoded = codebook.decode(word, options.max_hamming - white_border);
  if (!decoded) return std::nullopt;
  TagObservation tag;
  tag.tag_id = decoded->id;
  tag.hamming = decoded->hamming + white_border;
  // The upright top-left is quad corner `rotation`; mvis's order starts at the bottom-left.
  const int s = decoded->rotation;
  for (int k = 0; k < 4; ++k) tag.corners_px[k] = quad[(s + 3 - k) % 4];
  return tag;
}

}  // namespace mvis
