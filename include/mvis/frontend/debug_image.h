// A picture of what the front end kept: tag outlines, corner 0 marked, ids.
#pragma once

#include <opencv2/core/mat.hpp>

#include "mvis/frontend/tag_observation.h"

namespace mvis {

// BGR copy of `gray` (CV_8UC1) with every tag of `frame` outlined in green, its corner 0
// (bottom-left) circled in red and its id written at its centre.
cv::Mat drawTagFrame(const cv::Mat& gray, const TagFrame& frame);

}  // namespace mvis
