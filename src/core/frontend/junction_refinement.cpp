#include "junction_refinement.h"

#include <Eigen/Dense>
#include <cmath>
#include <vector>

#include "image_sampling.h"

namespace mvis {

std::optional<Eigen::Vector2d> refineJunction(const cv::Mat& gray, const Eigen::Vector2d& start,
                                              double radius, double max_shift_px) {
  const int half = std::max(2, static_cast<int>(std::ceil(radius)));
  const int n = 2 * half + 3;  // one more sample on every side for the differences
  const double weight_sigma = 0.8 * radius;
  const int m = n + 2;  // samples before the binomial smoothing
  std::vector<double> raw(m * m), rows(m * n), values(n * n);
  Eigen::Vector2d q = start;
  for (int iteration = 0; iteration < 12; ++iteration) {
    for (int i = 0; i < m; ++i) {
      for (int j = 0; j < m; ++j) {
        if (!bilinear(gray, q.x() + j - half - 2, q.y() + i - half - 2, &raw[i * m + j])) {
          return std::nullopt;
        }
      }
    }
    // A [1 2 1] / 4 smoothing both ways: symmetric, so the junction stays where it is, and the
    // differences below no longer alias on sharp edges.
    for (int i = 0; i < m; ++i) {
      for (int j = 0; j < n; ++j) {
        rows[i * n + j] = 0.25 * (raw[i * m + j] + 2.0 * raw[i * m + j + 1] + raw[i * m + j + 2]);
      }
    }
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) {
        values[i * n + j] =
            0.25 * (rows[i * n + j] + 2.0 * rows[(i + 1) * n + j] + rows[(i + 2) * n + j]);
      }
    }
    Eigen::Matrix2d A = Eigen::Matrix2d::Zero();
    Eigen::Vector2d b = Eigen::Vector2d::Zero();
    double gradient_sum = 0.0, weight_sum = 0.0;
    for (int i = 1; i < n - 1; ++i) {
      for (int j = 1; j < n - 1; ++j) {
        const Eigen::Vector2d d(j - half - 1, i - half - 1);  // offset from q
        if (d.squaredNorm() > radius * radius) continue;
        const double w = std::exp(-0.5 * d.squaredNorm() / (weight_sigma * weight_sigma));
        const Eigen::Vector2d g(0.5 * (values[i * n + j + 1] - values[i * n + j - 1]),
                                0.5 * (values[(i + 1) * n + j] - values[(i - 1) * n + j]));
        const Eigen::Matrix2d G = w * g * g.transpose();
        A += G;
        b += G * d;  // sum w g g^T (p - q), solved for the step of q
        gradient_sum += w * g.norm();
        weight_sum += w;
      }
    }
    if (gradient_sum < 2.0 * weight_sum || A.determinant() < 1e-9 * A.trace() * A.trace()) {
      return std::nullopt;  // flat or a single edge: no junction here
    }
    const Eigen::Vector2d step = A.ldlt().solve(b);
    q += step;
    if (!((q - start).norm() <= max_shift_px)) return std::nullopt;
    if (step.norm() < 0.002) return q;
  }
  return q;
}

}  // namespace mvis
