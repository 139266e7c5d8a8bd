#include "mvis/sim/rig_simulator.h"

#include <cmath>

#include "mvis/camera/camera_model.h"

namespace mvis {

bool parseMotionKind(const std::string& text, MotionKind* kind) {
  if (text == "handheld") {
    *kind = MotionKind::kHandheld;
  } else if (text == "yaw_only") {
    *kind = MotionKind::kYawOnly;
  } else if (text == "translation_only") {
    *kind = MotionKind::kTranslationOnly;
  } else {
    return false;
  }
  return true;
}

const char* toString(MotionKind kind) {
  switch (kind) {
    case MotionKind::kHandheld:
      return "handheld";
    case MotionKind::kYawOnly:
      return "yaw_only";
    case MotionKind::kTranslationOnly:
      return "translation_only";
  }
  return "?";
}

SinusoidTrajectory makeBoardTrajectory(const Rig& rig, const MotionOptions& options) {
  // Board centre, or the origin when the rig has no board.
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  if (rig.target) {
    const AprilGrid& g = *rig.target;
    const double pitch = (1.0 + g.tag_spacing) * g.tag_size;
    centre = 0.5 * Eigen::Vector2d(g.tag_cols * pitch - g.tag_spacing * g.tag_size,
                                   g.tag_rows * pitch - g.tag_spacing * g.tag_size);
  }
  // cam0 looking straight down, its x along the world x: R_G_C0 = diag(1, -1, -1).
  Eigen::Matrix3d R_G_C0;
  R_G_C0 << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  const Eigen::Matrix3d R_offset =
      rig.cameras.empty() ? Eigen::Matrix3d::Identity()
                          : Eigen::Matrix3d(R_G_C0 * rig.cameras[0].T_cam_imu.rotation());
  const double s = options.amplitude;
  const double h = options.height_m;
  // Incommensurate frequencies so the motion never repeats within a run.
  std::array<Signal, 3> position = {
      Signal{centre.x(), {{0.25 * s, 0.21, 0.0}, {0.04 * s, 0.73, 1.0}}},
      Signal{centre.y(), {{0.20 * s, 0.29, 0.5}, {0.04 * s, 0.81, 2.0}}},
      Signal{h, {{0.15 * s, 0.25, 1.2}, {0.03 * s, 0.93, 0.3}}}};
  std::array<Signal, 3> euler = {Signal{0.0, {{0.45 * s, 0.17, 0.0}, {0.08 * s, 0.67, 0.4}}},
                                 Signal{0.0, {{0.25 * s, 0.27, 1.1}, {0.06 * s, 0.71, 0.2}}},
                                 Signal{0.0, {{0.25 * s, 0.23, 2.1}, {0.06 * s, 0.89, 0.9}}}};
  switch (options.kind) {
    case MotionKind::kHandheld:
      break;
    case MotionKind::kYawOnly:
      euler[1].terms.clear();
      euler[2].terms.clear();
      position[2].terms.clear();
      break;
    case MotionKind::kTranslationOnly:
      for (auto& angle : euler) angle.terms.clear();
      break;
  }
  return SinusoidTrajectory(position, euler, R_offset);
}

SE3 cameraPose(const Rig& rig, std::size_t camera, const TrajectoryFunction& base, TimeNs t0_ns,
               TimeNs stamp_ns) {
  const Camera& cam = rig.cameras.at(camera);
  const TimeNs base_ns = stamp_ns + fromSeconds(cam.timeshift_cam_imu);
  return base(toSeconds(base_ns - t0_ns)).T_G_I * cam.T_cam_imu.inverse();
}

std::vector<TagFrame> simulateTagFrames(const Rig& rig, std::size_t camera, double rate_hz,
                                        const TrajectoryFunction& base, TimeNs t0_ns,
                                        TimeNs start_ns, TimeNs end_ns, double pixel_noise_px,
                                        std::uint64_t seed) {
  std::vector<TagFrame> frames;
  if (!rig.target || camera >= rig.cameras.size() || !(rate_hz > 0.0)) return frames;
  const Camera& cam = rig.cameras[camera];
  const AprilGrid& grid = *rig.target;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  const TimeNs period_ns = fromSeconds(1.0 / rate_hz);
  for (TimeNs stamp = start_ns; stamp <= end_ns; stamp += period_ns) {
    const SE3 T_C_G = cameraPose(rig, camera, base, t0_ns, stamp).inverse();
    TagFrame frame;
    frame.camera = camera;
    frame.stamp_ns = stamp;
    frame.width = cam.resolution[0];
    frame.height = cam.resolution[1];
    for (int id = 0; id < grid.numTags(); ++id) {
      TagObservation tag;
      tag.tag_id = id;
      bool visible = true;
      for (int c = 0; c < 4 && visible; ++c) {
        const Eigen::Vector3d p_C = T_C_G * grid.corner(id, c);
        Eigen::Vector2d uv = Eigen::Vector2d::Zero();
        visible = p_C.z() > 0.05 && projectToPixel(cam, p_C, &uv) && uv.x() >= 0.0 &&
                  uv.y() >= 0.0 && uv.x() <= frame.width - 1.0 && uv.y() <= frame.height - 1.0;
        tag.corners_px[c] = uv;
      }
      if (!visible) continue;
      if (pixel_noise_px > 0.0) {
        for (auto& corner : tag.corners_px) {
          corner += pixel_noise_px * Eigen::Vector2d(noise(rng), noise(rng));
        }
      }
      frame.tags.push_back(tag);
    }
    frames.push_back(std::move(frame));
  }
  return frames;
}

PixelToBoard cameraToBoard(const Camera& camera, const SE3& T_G_C) {
  const Eigen::Matrix3d R = T_G_C.rotation();
  const Eigen::Vector3d origin = T_G_C.p;
  return [camera, R, origin](const Eigen::Vector2d& pixel, Eigen::Vector2d* board) {
    Eigen::Vector2d m;
    if (!unprojectPixel(camera, pixel, &m)) return false;
    const Eigen::Vector3d ray = R * Eigen::Vector3d(m.x(), m.y(), 1.0);
    if (std::abs(ray.z()) < 1e-12) return false;
    const double t = -origin.z() / ray.z();
    if (t <= 0.0) return false;
    *board = (origin + t * ray).head<2>();
    return true;
  };
}

Rig perturbRig(const Rig& truth, const PerturbationSizes& sizes, std::uint64_t seed) {
  Rig rig = truth;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const auto gaussian3 = [&](double sigma) -> Eigen::Vector3d {  // a value, not an expression
    return Eigen::Vector3d(normal(rng), normal(rng), normal(rng)) * sigma;
  };
  const auto perturbPose = [&](const SE3& T, double rotation_rad, double translation_m) {
    // Perturb the sensor's pose in the base frame (what the estimator states), then return the
    // file's direction of the transform.
    const SE3 T_b_s = T.inverse();
    const SE3 perturbed(T_b_s.q * lie::expQuat(gaussian3(rotation_rad)),
                        T_b_s.p + gaussian3(translation_m));
    return perturbed.inverse();
  };
  // A gyroscope's Tg from a stream of its own, so that adding it left the other quantities'
  // draws (and every earlier seed's guess) as they were.
  std::mt19937_64 rng_tg(seed ^ 0x5467ULL);
  std::normal_distribution<double> normal_tg(0.0, 1.0);  // normal's would mix the streams
  const auto perturbGyroscopeTg = [&](InertialSensor* s) {
    if (!(sizes.imu_gravity_sensitivity > 0.0)) return;
    for (int k = 0; k < 9; ++k) {
      s->intrinsics.Tg(k / 3, k % 3) += sizes.imu_gravity_sensitivity * normal_tg(rng_tg);
    }
  };
  for (std::size_t i = 0; i < rig.inertial.size(); ++i) {
    InertialSensor& s = rig.inertial[i];
    if (i > 0) {
      s.T_i_b = perturbPose(s.T_i_b, sizes.aux_rotation_rad, sizes.aux_translation_m);
      s.time_offset += sizes.aux_time_offset_s * normal(rng);
    }
    if (s.model == ImuModel::kRpng && s.type == InertialType::kGyroscope) {
      // A gyroscope has Tw and Tg (no accelerometer for Ta and R_IMUtoACC).
      for (int r = 0; r < 3; ++r) {
        for (int c = r; c < 3; ++c) {
          s.intrinsics.Tw(r, c) += sizes.imu_scale_misalignment * normal(rng);
        }
      }
      perturbGyroscopeTg(&s);
    } else if (s.model == ImuModel::kRpng) {
      for (Eigen::Matrix3d* T : {&s.intrinsics.Tw, &s.intrinsics.Ta}) {
        for (int r = 0; r < 3; ++r) {
          for (int c = r; c < 3; ++c) (*T)(r, c) += sizes.imu_scale_misalignment * normal(rng);
        }
      }
      for (int k = 0; k < 9; ++k) {
        s.intrinsics.Tg(k / 3, k % 3) += sizes.imu_gravity_sensitivity * normal(rng);
      }
      s.intrinsics.R_IMUtoACC =
          s.intrinsics.R_IMUtoACC * lie::expSO3(gaussian3(sizes.imu_acc_rotation_rad));
    } else if (s.model == ImuModel::kKalibr) {
      // Lower triangular; the rotation on the gyroscope (a gyroscope's is its extrinsic's).
      const bool gyro = s.type == InertialType::kGyroscope;
      for (Eigen::Matrix3d* T : {&s.intrinsics.Tw, &s.intrinsics.Ta}) {
        if (gyro && T == &s.intrinsics.Ta) continue;
        for (int r = 0; r < 3; ++r) {
          for (int c = 0; c <= r; ++c) (*T)(r, c) += sizes.imu_scale_misalignment * normal(rng);
        }
      }
      if (gyro) perturbGyroscopeTg(&s);
      if (!gyro) {
        for (int k = 0; k < 9; ++k) {
          s.intrinsics.Tg(k / 3, k % 3) += sizes.imu_gravity_sensitivity * normal(rng);
        }
        s.intrinsics.R_IMUtoGYRO =
            s.intrinsics.R_IMUtoGYRO * lie::expSO3(gaussian3(sizes.imu_acc_rotation_rad));
      }
    }
  }
  for (Camera& cam : rig.cameras) {
    cam.T_cam_imu =
        perturbPose(cam.T_cam_imu, sizes.camera_rotation_rad, sizes.camera_translation_m);
    cam.timeshift_cam_imu += sizes.camera_time_offset_s * normal(rng);
    cam.intrinsics[0] += sizes.camera_focal_px * normal(rng);
    cam.intrinsics[1] += sizes.camera_focal_px * normal(rng);
    cam.intrinsics[2] += sizes.camera_centre_px * normal(rng);
    cam.intrinsics[3] += sizes.camera_centre_px * normal(rng);
    for (int k = 0; k < 4; ++k) cam.distortion_coeffs[k] += sizes.camera_distortion * normal(rng);
  }
  return rig;
}

}  // namespace mvis
