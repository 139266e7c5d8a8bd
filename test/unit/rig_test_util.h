// Shared fixtures for the rig I/O tests: valid file texts to break one key at a time.
#pragma once

#include <string>

namespace mvis::test {

inline std::string validImuChain() {
  return R"(imu0:
  rostopic: /imu0
  update_rate: 400.0
  accelerometer_noise_density: 2.0e-3
  accelerometer_random_walk: 3.0e-3
  gyroscope_noise_density: 1.6968e-4
  gyroscope_random_walk: 1.9393e-5
  model: rpng
  Tw:
    - [1.001, 0.002, -0.001]
    - [0.0, 0.998, 0.003]
    - [0.0, 0.0, 1.002]
imu1:
  T_i_b:
    - [0.0, -1.0, 0.0, 0.05]
    - [1.0, 0.0, 0.0, -0.02]
    - [0.0, 0.0, 1.0, 0.01]
    - [0.0, 0.0, 0.0, 1.0]
  time_offset: 0.004
  rostopic: /imu1
  update_rate: 200.0
  accelerometer_noise_density: 2.0e-3
  accelerometer_random_walk: 3.0e-3
  gyroscope_noise_density: 1.6968e-4
  gyroscope_random_walk: 1.9393e-5
imu2:
  sensor_type: gyroscope
  T_i_b:
    - [1.0, 0.0, 0.0, 0.0]
    - [0.0, 1.0, 0.0, 0.0]
    - [0.0, 0.0, 1.0, 0.0]
    - [0.0, 0.0, 0.0, 1.0]
  rostopic: /gyro
  update_rate: 200.0
  gyroscope_noise_density: 1.0e-4
  gyroscope_random_walk: 1.0e-5
)";
}

inline std::string validCamChain() {
  return R"(cam0:
  T_cam_imu:
    - [0.0, -1.0, 0.0, 0.02]
    - [0.0, 0.0, -1.0, 0.01]
    - [1.0, 0.0, 0.0, -0.1]
    - [0.0, 0.0, 0.0, 1.0]
  cam_overlaps: []
  timeshift_cam_imu: -0.012
  camera_model: pinhole
  distortion_model: radtan
  distortion_coeffs: [-0.28, 0.07, 0.0002, 0.00002]
  intrinsics: [458.654, 457.296, 367.215, 248.375]
  resolution: [752, 480]
  rostopic: /cam0/image_raw
)";
}

// `text` with the first occurrence of `from` replaced by `to` (which must exist).
inline std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  if (at == std::string::npos) return "replaced(): '" + from + "' not in the text";
  return text.replace(at, from.size(), to);
}

}  // namespace mvis::test
