#include "mvis/estimator/initialization.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>

#include "mvis/camera/camera_model.h"

namespace mvis {

std::vector<CornerObservation> boardCorners(const TagFrame& frame, const AprilGrid& grid) {
  std::vector<CornerObservation> out;
  for (const auto& tag : frame.tags) {
    if (tag.tag_id < 0 || tag.tag_id >= grid.numTags()) continue;
    for (int k = 0; k < 4; ++k) out.push_back({grid.corner(tag.tag_id, k), tag.corners_px[k]});
  }
  return out;
}

namespace {

// PnP (OpenCV's IPPE for planar targets) on the undistorted corners.
bool planarPose(const Camera& camera, const std::vector<CornerObservation>& corners,
                std::size_t min_corners, SE3* T_G_C) {
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image;
  for (const auto& o : corners) {
    Eigen::Vector2d m;
    if (!unprojectPixel(camera, o.uv, &m)) continue;
    object.emplace_back(o.p_G.x(), o.p_G.y(), o.p_G.z());
    image.emplace_back(m.x(), m.y());
  }
  if (object.size() < std::max<std::size_t>(4, min_corners)) return false;
  cv::Mat rvec, tvec;
  const cv::Mat K = cv::Mat::eye(3, 3, CV_64F);
  if (!cv::solvePnP(object, image, K, cv::noArray(), rvec, tvec, false, cv::SOLVEPNP_IPPE)) {
    return false;
  }
  const Eigen::Vector3d w(rvec.at<double>(0), rvec.at<double>(1), rvec.at<double>(2));
  const Eigen::Vector3d tr(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
  *T_G_C = SE3(lie::expSO3(w), tr).inverse();
  return T_G_C->p.allFinite();
}

}  // namespace

bool boardPose(const Camera& camera, const AprilGrid& grid, const TagFrame& frame, int min_tags,
               SE3* T_G_C) {
  return planarPose(camera, boardCorners(frame, grid),
                    4 * static_cast<std::size_t>(std::max(1, min_tags)), T_G_C);
}

bool tagPose(const Camera& camera, const TagFrame& frame, int tag_id, double size, SE3* T_T_C) {
  for (const auto& tag : frame.tags) {
    if (tag.tag_id != tag_id) continue;
    std::vector<CornerObservation> corners;
    for (int k = 0; k < 4; ++k) corners.push_back({tagCorner(k, size), tag.corners_px[k]});
    return planarPose(camera, corners, 4, T_T_C);
  }
  return false;
}

double clockCorrection(const std::deque<std::pair<TimeNs, Eigen::Matrix3d>>& h,
                       const Eigen::Matrix3d& R_I_C, TimeNs time_offset_ns, TimeNs imu_begin,
                       TimeNs imu_end, const std::function<Eigen::Vector3d(TimeNs)>& gyro_at,
                       double range_s) {
  struct Rate {
    double t0, t1;  // camera clock, relative to the first rotation [s]
    Eigen::Vector3d w_I;
  };
  std::vector<Rate> rates;
  for (std::size_t i = 0, j = 0; i < h.size(); i = j) {
    j = i + 1;
    while (j < h.size() && h[j].first - h[i].first < fromSeconds(0.15)) ++j;
    if (j >= h.size()) break;
    const double dt = toSeconds(h[j].first - h[i].first);
    if (dt > 0.3) continue;  // a hole in the board poses
    const Eigen::Vector3d w_C = lie::logSO3(h[i].second.transpose() * h[j].second) / dt;
    if (w_C.norm() > 10.0) continue;  // not a hand-held motion: a flipped board pose
    rates.push_back({toSeconds(h[i].first - h.front().first),
                     toSeconds(h[j].first - h.front().first), R_I_C * w_C});
  }
  if (rates.size() < 8 || imu_end <= imu_begin) return 0.0;
  double mean_speed = 0.0, var_speed = 0.0;
  for (const auto& r : rates) mean_speed += r.w_I.norm() / rates.size();
  for (const auto& r : rates) var_speed += std::pow(r.w_I.norm() - mean_speed, 2) / rates.size();
  if (std::sqrt(var_speed) < 0.05 && mean_speed < 0.1) return 0.0;  // hardly moving
  const TimeNs base = h.front().first + time_offset_ns;
  auto cost = [&](double delta) {
    double sum = 0.0;
    int n = 0;
    for (const auto& r : rates) {
      const TimeNs a = base + fromSeconds(r.t0 + delta), b = base + fromSeconds(r.t1 + delta);
      if (a < imu_begin || b > imu_end) continue;
      Eigen::Vector3d mean = Eigen::Vector3d::Zero();
      for (int k = 0; k <= 8; ++k) mean += gyro_at(a + (b - a) * k / 8) / 9.0;
      sum += std::min((r.w_I - mean).squaredNorm(), 0.25);
      ++n;
    }
    return n >= static_cast<int>(0.7 * rates.size()) ? sum / n
                                                     : std::numeric_limits<double>::infinity();
  };
  const int steps = static_cast<int>(range_s / 0.001);
  std::vector<double> costs(2 * steps + 1);
  int best = steps;
  for (int k = -steps; k <= steps; ++k) {
    costs[k + steps] = cost(k * 0.001);
    if (costs[k + steps] < costs[best]) best = k + steps;
  }
  if (!std::isfinite(costs[best])) return 0.0;
  std::vector<double> sorted(costs.begin(), costs.end());
  std::sort(sorted.begin(), sorted.end());
  if (!(costs[best] < 0.3 * sorted[sorted.size() / 2])) return 0.0;  // no clear winner
  // Near the true offset the cost is flat (within 25% over +-40 ms on hand-held motion): only an
  // offset clearly worse than the best is corrected, or a few-ms error would be "corrected"
  // by tens of ms.
  if (!(costs[steps] > 2.0 * costs[best])) return 0.0;
  double delta = (best - steps) * 0.001;
  if (best > 0 && best < 2 * steps && std::isfinite(costs[best - 1]) &&
      std::isfinite(costs[best + 1])) {
    const double a = costs[best - 1], b = costs[best], d = costs[best + 1];
    const double curvature = a - 2.0 * b + d;
    if (curvature > 0.0) delta += 0.001 * 0.5 * (a - d) / curvature;
  }
  return delta;
}

GravityAlignment alignGravity(const std::vector<TimeNs>& t, const std::vector<SE3>& T_G_I,
                              const std::vector<const ImuPreintegration*>& pre,
                              const std::vector<Eigen::Vector3d>* scaled) {
  const std::size_t n = t.size();
  GravityAlignment out;
  if (n < 3 || T_G_I.size() != n || pre.size() + 1 != n || (scaled && scaled->size() != n)) {
    out.gravity.setConstant(std::numeric_limits<double>::quiet_NaN());
    return out;
  }
  const int unknowns = scaled ? 7 : 6;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(3 * (n - 1), unknowns);
  Eigen::VectorXd b(3 * (n - 1));
  std::vector<Eigen::Vector3d> c(n, Eigen::Vector3d::Zero()), d(n, Eigen::Vector3d::Zero());
  for (std::size_t i = 0; i + 1 < n; ++i) {
    const double T = toSeconds(t[i + 1] - t[i]);
    const Eigen::Matrix3d R = T_G_I[i].rotation();
    d[i + 1] = d[i] + c[i] * T + R * pre[i]->deltaP();
    c[i + 1] = c[i] + R * pre[i]->deltaV();
  }
  for (std::size_t i = 1; i < n; ++i) {
    const double tau = toSeconds(t[i] - t[0]);
    A.block<3, 3>(3 * (i - 1), 0) = Eigen::Matrix3d::Identity() * tau;
    A.block<3, 3>(3 * (i - 1), 3) = Eigen::Matrix3d::Identity() * 0.5 * tau * tau;
    b.segment<3>(3 * (i - 1)) = T_G_I[i].p - T_G_I[0].p - d[i];
    if (scaled) A.block<3, 1>(3 * (i - 1), 6) = (*scaled)[0] - (*scaled)[i];
  }
  const Eigen::VectorXd x = A.colPivHouseholderQr().solve(b);
  out.gravity = x.segment<3>(3);
  if (scaled) out.scale = x[6];
  for (std::size_t i = 0; i < n; ++i) {
    out.velocities.push_back(x.head<3>() + out.gravity * toSeconds(t[i] - t[0]) + c[i]);
  }
  return out;
}

}  // namespace mvis
