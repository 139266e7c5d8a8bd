// The rig: every sensor's calibration and noise, as plain data.
//
// A sensor is data (an index into the rig), never a class. Frames and units follow
// doc/conventions.md: imu0 is the base IMU {I}; transforms are T_A_B with p_A = T_A_B * p_B.
#pragma once

#include <Eigen/Core>
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "mvis/common/lie.h"

namespace mvis {

enum class InertialType { kImu, kGyroscope };
// How an inertial sensor's intrinsics are parametrized (OpenVINS's models, see ImuIntrinsics).
enum class ImuModel { kCalibrated, kRpng, kKalibr };
enum class DistortionModel { kRadtan, kEquidistant };

const char* toString(InertialType type);
const char* toString(ImuModel model);
const char* toString(DistortionModel model);

// Standard deviations of an estimated inertial calibration, as written beside each key with the
// suffix _std. Rotations as 3-vectors [rad] in the tangent space of the estimate (right
// perturbation), translations [m]. 0 means held constant.
struct InertialCalibrationStd {
  Eigen::Vector3d rotation = Eigen::Vector3d::Zero();     // of T_i_b [rad]
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();  // of T_i_b [m]
  double time_offset = 0.0;                               // [s]
  Eigen::Matrix3d Tw = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d Ta = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d Tg = Eigen::Matrix3d::Zero();
  Eigen::Vector3d R_IMUtoACC = Eigen::Vector3d::Zero();   // [rad] (rpng)
  Eigen::Vector3d R_IMUtoGYRO = Eigen::Vector3d::Zero();  // [rad] (kalibr)
};

// Continuous-time noise densities, as Kalibr.
struct ImuNoise {
  double accelerometer_noise_density = 0.0;  // [m/s^2/sqrt(Hz)]
  double accelerometer_random_walk = 0.0;    // [m/s^3/sqrt(Hz)]
  double gyroscope_noise_density = 0.0;      // [rad/s/sqrt(Hz)]
  double gyroscope_random_walk = 0.0;        // [rad/s^2/sqrt(Hz)]
};

// The intrinsic model (report Eq. 1-4):
//   w_m = Tw * R_IMUtoGYRO * w_I + Tg * a_I + b_g + n_g
//   a_m = Ta * R_IMUtoACC * a_I + b_a + n_a
// rpng: Tw, Ta upper triangular, R_IMUtoGYRO identity ({I} on the gyroscope), Tg full.
// kalibr: Tw, Ta lower triangular, R_IMUtoACC identity ({I} on the accelerometer), Tg full
// (Kalibr's gyroscopes M, C_gyro_i, A and accelerometers M). Identity/zero when 'calibrated'.
struct ImuIntrinsics {
  Eigen::Matrix3d Tw = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d R_IMUtoGYRO = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d Ta = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d R_IMUtoACC = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d Tg = Eigen::Matrix3d::Zero();  // [rad/s per m/s^2]
};

// One entry imuN of kalibr_imu_chain.yaml: the base IMU (index 0), an auxiliary IMU or a
// gyroscope.
struct InertialSensor {
  std::string name;  // imu0, imu1, ...
  InertialType type = InertialType::kImu;
  SE3 T_i_b;                 // p_imui = T_i_b * p_imu0 [m]; identity for imu0
  double time_offset = 0.0;  // [s], t_imu0 = t_imui + time_offset; 0 for imu0
  std::string rostopic;      // sensor_msgs/Imu topic
  double update_rate = 0.0;  // nominal rate [Hz]
  ImuNoise noise;
  ImuModel model = ImuModel::kCalibrated;
  ImuIntrinsics intrinsics;
  std::optional<InertialCalibrationStd> std;  // written as *_std keys when present
};

struct CameraCalibrationStd {
  Eigen::Vector3d rotation = Eigen::Vector3d::Zero();     // of T_cam_imu [rad]
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();  // of T_cam_imu [m]
  double timeshift_cam_imu = 0.0;                         // [s]
  Eigen::Vector4d intrinsics = Eigen::Vector4d::Zero();   // [px]
  Eigen::Vector4d distortion_coeffs = Eigen::Vector4d::Zero();
};

// One entry camN of kalibr_imucam_chain.yaml: a pinhole camera.
struct Camera {
  std::string name;                // cam0, cam1, ...
  SE3 T_cam_imu;                   // p_cam = T_cam_imu * p_imu0 [m]
  double timeshift_cam_imu = 0.0;  // [s], t_imu0 = t_cam + timeshift_cam_imu
  DistortionModel distortion_model = DistortionModel::kRadtan;
  // radtan [k1 k2 p1 p2] or equidistant [k1 k2 k3 k4]
  Eigen::Vector4d distortion_coeffs = Eigen::Vector4d::Zero();
  Eigen::Vector4d intrinsics = Eigen::Vector4d::Zero();  // [fu fv pu pv] [px]
  std::array<int, 2> resolution = {0, 0};                // [width height] [px]
  std::string rostopic;                                  // sensor_msgs/Image topic
  std::optional<CameraCalibrationStd> std;
};

// Corner c (0 bottom-left, 1 bottom-right, 2 top-right, 3 top-left) of a tag of side `side` [m]
// in the tag's own frame: corner 0 at the origin, x along its bottom edge, z out of its face.
Eigen::Vector3d tagCorner(int c, double side);

// The tag board of aprilgrid.yaml (Kalibr's keys plus tagFamily).
struct AprilGrid {
  int tag_cols = 0;
  int tag_rows = 0;
  double tag_size = 0.0;     // edge of one tag's black square [m]
  double tag_spacing = 0.0;  // gap between tags / tag_size
  std::string tag_family = "tag36h11";

  int numTags() const { return tag_cols * tag_rows; }
  // Board-frame position [m] of corner c (0 bottom-left, 1 bottom-right, 2 top-right,
  // 3 top-left) of tag `id`. id must be in [0, numTags()), c in [0, 4).
  Eigen::Vector3d corner(int id, int c) const;
};

struct Rig {
  std::vector<InertialSensor> inertial;  // inertial[0] is the base IMU imu0
  std::vector<Camera> cameras;
  std::optional<AprilGrid> target;  // without it, tag corners are landmarks to estimate

  const InertialSensor& baseImu() const { return inertial.front(); }
  // One line per sensor, for logs and the demo.
  std::string summary() const;
};

// Tag families libapriltag 3.3 provides that mvis accepts in aprilgrid.yaml.
const std::vector<std::string>& supportedTagFamilies();

}  // namespace mvis
