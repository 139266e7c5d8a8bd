// Shared fixtures for the rig I/O tests: valid file texts to break one key at a time, and the
// comparison of two rigs after a write and a read.
#pragma once

#include <gtest/gtest.h>

#include <string>

#include "mvis/rig/rig.h"

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

// Numbers are written with the shortest text that reads back exactly, and rotations are
// re-orthonormalized on reading, which moves them by round-off only.
inline constexpr double kRoundOff = 1e-14;

inline void expectSameTransform(const SE3& a, const SE3& b) {
  EXPECT_LT((a.matrix() - b.matrix()).cwiseAbs().maxCoeff(), kRoundOff);
}

inline void expectSameRig(const Rig& a, const Rig& b) {
  ASSERT_EQ(a.inertial.size(), b.inertial.size());
  for (std::size_t i = 0; i < a.inertial.size(); ++i) {
    const auto &x = a.inertial[i], &y = b.inertial[i];
    SCOPED_TRACE(x.name);
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.type, y.type);
    EXPECT_EQ(x.model, y.model);
    EXPECT_EQ(x.rostopic, y.rostopic);
    EXPECT_EQ(x.update_rate, y.update_rate);
    EXPECT_EQ(x.time_offset, y.time_offset);
    expectSameTransform(x.T_i_b, y.T_i_b);
    EXPECT_EQ(x.noise.accelerometer_noise_density, y.noise.accelerometer_noise_density);
    EXPECT_EQ(x.noise.accelerometer_random_walk, y.noise.accelerometer_random_walk);
    EXPECT_EQ(x.noise.gyroscope_noise_density, y.noise.gyroscope_noise_density);
    EXPECT_EQ(x.noise.gyroscope_random_walk, y.noise.gyroscope_random_walk);
    EXPECT_EQ(x.intrinsics.Tw, y.intrinsics.Tw);
    EXPECT_EQ(x.intrinsics.Ta, y.intrinsics.Ta);
    EXPECT_EQ(x.intrinsics.Tg, y.intrinsics.Tg);
    EXPECT_LT((x.intrinsics.R_IMUtoACC - y.intrinsics.R_IMUtoACC).cwiseAbs().maxCoeff(), kRoundOff);
    EXPECT_LT((x.intrinsics.R_IMUtoGYRO - y.intrinsics.R_IMUtoGYRO).cwiseAbs().maxCoeff(),
              kRoundOff);
    ASSERT_EQ(x.std.has_value(), y.std.has_value());
    if (x.std) {
      EXPECT_EQ(x.std->rotation, y.std->rotation);
      EXPECT_EQ(x.std->translation, y.std->translation);
      EXPECT_EQ(x.std->time_offset, y.std->time_offset);
      EXPECT_EQ(x.std->Tw, y.std->Tw);
      EXPECT_EQ(x.std->Ta, y.std->Ta);
      EXPECT_EQ(x.std->Tg, y.std->Tg);
      EXPECT_EQ(x.std->R_IMUtoACC, y.std->R_IMUtoACC);
      EXPECT_EQ(x.std->R_IMUtoGYRO, y.std->R_IMUtoGYRO);
    }
  }
  ASSERT_EQ(a.cameras.size(), b.cameras.size());
  for (std::size_t i = 0; i < a.cameras.size(); ++i) {
    const auto &x = a.cameras[i], &y = b.cameras[i];
    SCOPED_TRACE(x.name);
    EXPECT_EQ(x.name, y.name);
    expectSameTransform(x.T_cam_imu, y.T_cam_imu);
    EXPECT_EQ(x.timeshift_cam_imu, y.timeshift_cam_imu);
    EXPECT_EQ(x.distortion_model, y.distortion_model);
    EXPECT_EQ(x.distortion_coeffs, y.distortion_coeffs);
    EXPECT_EQ(x.intrinsics, y.intrinsics);
    EXPECT_EQ(x.resolution, y.resolution);
    EXPECT_EQ(x.rostopic, y.rostopic);
    ASSERT_EQ(x.std.has_value(), y.std.has_value());
    if (x.std) {
      EXPECT_EQ(x.std->rotation, y.std->rotation);
      EXPECT_EQ(x.std->translation, y.std->translation);
      EXPECT_EQ(x.std->timeshift_cam_imu, y.std->timeshift_cam_imu);
      EXPECT_EQ(x.std->intrinsics, y.std->intrinsics);
      EXPECT_EQ(x.std->distortion_coeffs, y.std->distortion_coeffs);
    }
  }
  ASSERT_EQ(a.target.has_value(), b.target.has_value());
  if (a.target) {
    EXPECT_EQ(a.target->tag_cols, b.target->tag_cols);
    EXPECT_EQ(a.target->tag_rows, b.target->tag_rows);
    EXPECT_EQ(a.target->tag_size, b.target->tag_size);
    EXPECT_EQ(a.target->tag_spacing, b.target->tag_spacing);
    EXPECT_EQ(a.target->tag_family, b.target->tag_family);
  }
}

}  // namespace mvis::test
