// The estimate over time, for convergence plots, 3-sigma bounds and NEES (scripts/evaluate).
// Two CSV files in the result directory; their columns are stable (new ones only ever appended).
//
// calibration.csv: one row per calibrated sensor (every camera, auxiliary IMU and gyroscope, and
// the base IMU when its model is rpng) after every solve:
//   stamp,sensor,kind,rx,ry,rz,px,py,pz,time_offset,
//   std_rx,std_ry,std_rz,std_px,std_py,std_pz,std_time_offset,
//   fu,fv,pu,pv,k1,k2,k3,k4,std_fu,std_fv,std_pu,std_pv,std_k1,std_k2,std_k3,std_k4,
//   tw11,tw12,tw22,tw13,tw23,tw33,ta11,ta12,ta22,ta13,ta23,ta33,tg11,tg12,...,tg33,
//   acc_rx,acc_ry,acc_rz, and std_ of each of those 24
//   stamp        base-clock time of the newest window state [s] ("sec.nsec", exact)
//   sensor       name (cam0, imu1, ...); kind: camera | imu | gyroscope
//   rx ry rz     rotation vector Log(R) [rad] of T_cam_imu (cameras) or T_i_b (IMUs, gyroscopes)
//   px py pz     its translation [m] (nan for gyroscopes)
//   time_offset  timeshift_cam_imu (cameras) or time_offset (IMUs, gyroscopes) [s]
//   std_*        standard deviations of the same, rotation in the tangent of the estimate (right
//                perturbation, doc/conventions.md); nan before the first covariance, 0 for a
//                quantity held constant; they are the latest covariance's (computed every
//                `covariance_every` solves)
//   fu ... k4    a camera's intrinsics [px] and distortion coefficients (radtan k1 k2 p1 p2 or
//                equidistant k1 k2 k3 k4, as distortion_coeffs), with std_* as above (0 when not
//                estimated); nan for IMUs and gyroscopes
//   tw11 ... acc_rz  an rpng inertial sensor's intrinsics: Tw's and Ta's upper-triangular
//                elements (row, column), Tg's elements, Log(R_IMUtoACC) [rad]; std_* their
//                standard deviations (rpng *_std keys; 0 when held); nan for cameras and
//                calibrated sensors. The base IMU's row has nan extrinsic and time offset.
//
// pose_covariance.csv: one row per covariance of the newest window pose:
//   stamp,tx,ty,tz,qx,qy,qz,qw,c00,c01,...,c55
//   the pose T_G_I of imu0 in the world (board) frame [m, Hamilton quaternion x y z w] and the
//   row-major 6x6 covariance of its tangent [dtheta (rad), dp (m)]: R = R_hat Exp(dtheta),
//   p = p_hat + dp.
//
// calibration_changes.csv: one row per quantity of a sensor found changed (a knocked mount;
// EstimatorOptions::detect_changes), header even when empty:
//   stamp,sensor,quantity,size,size_sigma
//   stamp        base-clock time when the change was declared [s]
//   quantity     rotation | translation | time_offset
//   size         the change: [deg] (angle), [mm] (norm), [ms] (signed)
//   size_sigma   that change over its standard deviation
// Nothing else writes rows there: a restart after a fault is not a change.
//
// A long live run stays bounded: past `max_rows` rows a table keeps the rows of every other
// stamp (the whole run at half the time resolution) and goes on. The default, 20,000 rows
// (~13 MB for calibration rows, ~8 MB for poses), keeps an hour of the VI-Rig (five calibrated
// sensors) at about one row per sensor and second; 200,000 let the log grow by ~200 MB.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdio>
#include <string>
#include <vector>

#include "mvis/common/lie.h"
#include "mvis/common/status.h"
#include "mvis/common/time.h"
#include "mvis/rig/rig.h"

namespace mvis {

// Writes a stamp as seconds with nine decimals (exact, as the result directory's files have it).
void writeStamp(std::FILE* file, TimeNs stamp);

class EstimateLog {
 public:
  explicit EstimateLog(std::size_t max_rows = 20000) : max_rows_(max_rows) {}

  // Every calibrated sensor of `rig` (all but the base IMU, unless its model is rpng) at
  // `stamp_ns`.
  void addCalibration(TimeNs stamp_ns, const Rig& rig);
  // The newest pose and its covariance (skipped when the covariance is not finite).
  void addPose(TimeNs stamp_ns, const SE3& T_G_I, const Eigen::Matrix<double, 6, 6>& covariance);

  // A quantity of a sensor found changed (see calibration_changes.csv above).
  void addChange(TimeNs stamp_ns, const std::string& sensor, const std::string& quantity,
                 double size, double size_sigma);

  // A quantity's status changed (calibration_status.csv: stamp, sensor, quantity, status, sigma
  // and target in the quantity's unit, advice in words; calibration_status.h).
  void addStatus(TimeNs stamp_ns, const std::string& sensor, const std::string& quantity,
                 const std::string& status, double sigma, double target, const std::string& advice);

  // Writes calibration.csv, pose_covariance.csv, calibration_changes.csv and
  // calibration_status.csv into `dir` (which must exist).
  Status write(const std::string& dir) const;
  // Writes the calibration rows alone to `path` (calibration.csv's columns).
  Status writeCalibration(const std::string& path) const;

  std::size_t calibrationRows() const { return calibration_.size(); }

 private:
  static constexpr int kColumns = 15 + 24;
  struct CalibrationRow {
    TimeNs stamp_ns;
    int sensor;  // index into names_
    // extrinsic, time offset, camera intrinsics, IMU intrinsics
    Eigen::Matrix<double, kColumns, 1> value, std;
  };
  struct PoseRow {
    TimeNs stamp_ns;
    SE3 T_G_I;
    Eigen::Matrix<double, 6, 6> covariance;
  };
  int sensorIndex(const std::string& name, const char* kind);

  std::size_t max_rows_;
  std::vector<std::string> names_, kinds_;
  std::vector<CalibrationRow> calibration_;
  std::vector<PoseRow> poses_;
  struct ChangeRow {
    TimeNs stamp_ns;
    std::string sensor, quantity;
    double size, size_sigma;
  };
  std::vector<ChangeRow> changes_;
  struct StatusRow {
    TimeNs stamp_ns;
    std::string sensor, quantity, status;
    double sigma, target;
    std::string advice;
  };
  std::vector<StatusRow> statuses_;
};

}  // namespace mvis
