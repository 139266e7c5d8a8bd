// Bilinear intensity of an 8-bit gray image at a sub-pixel position, for the front end's
// readers of cells, edges and junctions.
#pragma once

#include <cmath>
#include <cstdint>
#include <opencv2/core/mat.hpp>

namespace mvis {

// The intensity at (u, v) in mvis's pixel convention ((0, 0) at the centre of the top-left
// pixel) of `gray` (CV_8UC1); false, leaving `value` alone, where the four pixels around it are
// not all inside the image.
inline bool bilinear(const cv::Mat& gray, double u, double v, double* value) {
  const int c = static_cast<int>(std::floor(u));
  const int r = static_cast<int>(std::floor(v));
  if (c < 0 || r < 0 || c + 1 >= gray.cols || r + 1 >= gray.rows) return false;
  const double a = u - c, b = v - r;
  const auto* row0 = gray.ptr<std::uint8_t>(r);
  const auto* row1 = gray.ptr<std::uint8_t>(r + 1);
  *value =
      (1 - b) * ((1 - a) * row0[c] + a * row0[c + 1]) + b * ((1 - a) * row1[c] + a * row1[c + 1]);
  return true;
}

}  // namespace mvis
