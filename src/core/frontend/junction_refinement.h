// The centre of an X-junction (two black and two white sectors meeting at a point, as where a
// Kalibr AprilGrid's tag touches the black square at its corner) to sub-pixel accuracy.
//
// Around a junction the image is point-symmetric, I(c + d) = I(c - d), whatever the blur (any
// symmetric point spread), the perspective (the sectors need not be square) and any monotone
// response of the camera (gamma, which moves every edge towards the dark side and so biases a
// corner taken from edges). Its gradient is then antisymmetric, and c is the point q where
//   sum_d w(d) g(d) g(d)^T (q - p_d) = 0
// over a window centred on q (each gradient is orthogonal to the line from its point to c; in
// pairs d, -d the terms cancel exactly at q = c). The window is sampled by bilinear
// interpolation on a grid centred on the current q, smoothed by a [1 2 1] / 4 kernel both ways
// (symmetric, so c stays; without it the differences alias on sharp edges and the centre
// scatters by 0.1 px), weighted by a Gaussian of 0.8 radius, and re-centred until
// q moves less than 0.002 px (at most 12 times). The sectors must stay what they are out to the
// window's radius plus the blur: for an AprilGrid, about 1.5 cells (the border is two cells, the
// square three).
#pragma once

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>
#include <optional>

namespace mvis {

// The junction near `start` [px, mvis's pixel convention] within a window of `radius` px;
// nullopt if the window leaves the image, has no contrast or the iteration moves more than
// `max_shift_px` from start.
std::optional<Eigen::Vector2d> refineJunction(const cv::Mat& gray, const Eigen::Vector2d& start,
                                              double radius, double max_shift_px);

}  // namespace mvis
