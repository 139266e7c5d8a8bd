#include "mvis/frontend/debug_image.h"

#include <opencv2/imgproc.hpp>
#include <string>

namespace mvis {

cv::Mat drawTagFrame(const cv::Mat& gray, const TagFrame& frame) {
  cv::Mat bgr;
  cv::cvtColor(gray, bgr, cv::COLOR_GRAY2BGR);
  // Sub-pixel drawing: OpenCV takes fixed-point coordinates with `shift` fractional bits.
  constexpr int kShift = 4;
  const auto point = [](const Eigen::Vector2d& p) {
    return cv::Point(static_cast<int>(std::lround(p.x() * (1 << kShift))),
                     static_cast<int>(std::lround(p.y() * (1 << kShift))));
  };
  for (const auto& tag : frame.tags) {
    for (int c = 0; c < 4; ++c) {
      cv::line(bgr, point(tag.corners_px[c]), point(tag.corners_px[(c + 1) % 4]),
               cv::Scalar(0, 255, 0), 1, cv::LINE_AA, kShift);
    }
    cv::circle(bgr, point(tag.corners_px[0]), 3 << kShift, cv::Scalar(0, 0, 255), 1, cv::LINE_AA,
               kShift);
    const Eigen::Vector2d centre =
        0.25 * (tag.corners_px[0] + tag.corners_px[1] + tag.corners_px[2] + tag.corners_px[3]);
    cv::putText(bgr, std::to_string(tag.tag_id),
                cv::Point(static_cast<int>(centre.x()) - 6, static_cast<int>(centre.y()) + 4),
                cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(255, 64, 0), 1, cv::LINE_AA);
  }
  return bgr;
}

}  // namespace mvis
