// What the estimator does before its window starts, as functions of plain data: board poses,
// the camera clocks against the gyroscope, and velocity and gravity from board poses and
// preintegrated readings.
#pragma once

#include <Eigen/Core>
#include <deque>
#include <functional>
#include <utility>
#include <vector>

#include "mvis/common/lie.h"
#include "mvis/factors/tag_reprojection_factor.h"
#include "mvis/frontend/tag_observation.h"
#include "mvis/inertial/imu_preintegration.h"
#include "mvis/rig/rig.h"

namespace mvis {

// The board corners of a frame's tags with their detected pixels (tags not on the board are
// skipped).
std::vector<CornerObservation> boardCorners(const TagFrame& frame, const AprilGrid& grid);

// The camera's pose on the board from at least `min_tags` tags: PnP (OpenCV's IPPE for planar
// targets) on the undistorted corners. False when there are too few or it fails.
bool boardPose(const Camera& camera, const AprilGrid& grid, const TagFrame& frame, int min_tags,
               SE3* T_G_C);

// Without a board: the camera's pose T_T_C on one tag (id `tag_id`) of the frame, in the tag's
// frame (corner 0 at the origin, x along its bottom edge, z out of its face) with the tag's side
// taken as `size` [m]. False when the tag is not in the frame or PnP fails.
bool tagPose(const Camera& camera, const TagFrame& frame, int tag_id, double size, SE3* T_T_C);

// The correction [s] to a camera's time offset that best matches its angular velocity, from
// board rotations R_G_C at camera-clock stamps, with the gyroscope, searched within +-range_s at
// 1 ms and refined by a parabola. The camera's rate is the mean over ~0.15 s between board
// poses (frame-to-frame differences are too noisy), rotated into the IMU frame with R_I_C, and
// compared with the mean gyroscope reading over the same span (gyro_at gives the reading at a
// base-clock time within [imu_begin, imu_end]). Errors are truncated at 0.5 rad/s (a board pose
// flipped to its mirror solution). Returns 0 when the data do not decide: fewer than 8 rates,
// hardly any motion, or no minimum below 0.3 x the median cost.
double clockCorrection(const std::deque<std::pair<TimeNs, Eigen::Matrix3d>>& rotations,
                       const Eigen::Matrix3d& R_I_C, TimeNs time_offset_ns, TimeNs imu_begin,
                       TimeNs imu_end, const std::function<Eigen::Vector3d(TimeNs)>& gyro_at,
                       double range_s);

// Velocity and gravity from base-IMU poses T_G_I at times t_i and the readings preintegrated
// between them with zero biases (pre[i] from t_i to t_i+1). With tau_i = t_i - t_0 and
// T_i = t_i+1 - t_i:
//   v_i = v_0 + g tau_i + c_i,                      c_i+1 = c_i + R_i dv_i
//   p_i = p_0 + v_0 tau_i + 1/2 g tau_i^2 + d_i,    d_i+1 = d_i + c_i T_i + R_i dp_i
// linear in (v_0, g): least squares over every position.
// Without a board the poses come from one tag of unknown size: with `scaled`, the positions are
// p_i = s a_i + T_G_I[i].p with a_i = scaled[i] (the camera's position in tag sides) and the
// tag's side s [m] a third unknown, also linear.
struct GravityAlignment {
  Eigen::Vector3d gravity = Eigen::Vector3d::Zero();  // in the board frame [m/s^2]
  std::vector<Eigen::Vector3d> velocities;            // v_i [m/s]
  double scale = 1.0;                                 // s (1 without `scaled`)
};
GravityAlignment alignGravity(const std::vector<TimeNs>& t, const std::vector<SE3>& T_G_I,
                              const std::vector<const ImuPreintegration*>& pre,
                              const std::vector<Eigen::Vector3d>* scaled = nullptr);

}  // namespace mvis
