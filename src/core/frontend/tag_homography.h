// The homography from a tag's pattern plane (x right, y down, in cells; the detected square is
// [0, W] x [0, W]) to the image, from the square's four corners.
#pragma once

#include <Eigen/Core>
#include <Eigen/LU>
#include <array>

namespace mvis {

class TagHomography {
 public:
  // Image positions of pattern points (0, 0), (W, 0), (W, W), (0, W): the upright tag's
  // top-left, top-right, bottom-right and bottom-left corners.
  TagHomography(const std::array<Eigen::Vector2d, 4>& image, double width) {
    const std::array<Eigen::Vector2d, 4> pattern{Eigen::Vector2d(0, 0), Eigen::Vector2d(width, 0),
                                                 Eigen::Vector2d(width, width),
                                                 Eigen::Vector2d(0, width)};
    Eigen::Matrix<double, 8, 8> A;
    Eigen::Matrix<double, 8, 1> b;
    for (int k = 0; k < 4; ++k) {
      const double x = pattern[k].x(), y = pattern[k].y();
      const double u = image[k].x(), v = image[k].y();
      A.row(2 * k) << x, y, 1, 0, 0, 0, -u * x, -u * y;
      A.row(2 * k + 1) << 0, 0, 0, x, y, 1, -v * x, -v * y;
      b(2 * k) = u;
      b(2 * k + 1) = v;
    }
    const Eigen::Matrix<double, 8, 1> h = A.partialPivLu().solve(b);
    H_ << h(0), h(1), h(2), h(3), h(4), h(5), h(6), h(7), 1.0;
  }

  Eigen::Vector2d operator()(double x, double y) const {
    const Eigen::Vector3d p = H_ * Eigen::Vector3d(x, y, 1.0);
    return p.head<2>() / p.z();
  }
  Eigen::Vector2d operator()(const Eigen::Vector2d& pattern) const {
    return (*this)(pattern.x(), pattern.y());
  }
  bool valid() const { return H_.allFinite(); }

 private:
  Eigen::Matrix3d H_;
};

}  // namespace mvis
