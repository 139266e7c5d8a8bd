// The rig simulator: motion kinds, what the cameras see, images against detections, time
// offsets and perturbations.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "mvis/frontend/tag_checks.h"
#include "mvis/frontend/tag_detector.h"
#include "mvis/rig/rig_io.h"
#include "mvis/sim/rig_simulator.h"

namespace mvis {
namespace {

Rig viRig() {
  auto rig = loadRig(std::string(MVIS_SOURCE_DIR) + "/config/sim_vi_rig");
  EXPECT_TRUE(rig.ok()) << rig.status().message();
  return rig.value();
}

TrajectoryFunction functionOf(const SinusoidTrajectory& trajectory) {
  return [trajectory](double t) { return trajectory.evaluate(t); };
}

TEST(SimRig, MotionKindsExciteWhatTheySay) {
  const Rig rig = viRig();
  for (MotionKind kind :
       {MotionKind::kHandheld, MotionKind::kYawOnly, MotionKind::kTranslationOnly}) {
    MotionOptions options;
    options.kind = kind;
    const auto trajectory = makeBoardTrajectory(rig, options);
    double max_tilt_rate = 0.0, max_yaw_rate = 0.0, max_rate = 0.0;
    for (double t = 0.0; t < 20.0; t += 0.05) {
      const TrajectoryState s = trajectory.evaluate(t);
      const Eigen::Vector3d w_G = s.T_G_I.q * s.w_I;
      max_tilt_rate = std::max(max_tilt_rate, w_G.head<2>().norm());
      max_yaw_rate = std::max(max_yaw_rate, std::abs(w_G.z()));
      max_rate = std::max(max_rate, w_G.norm());
    }
    SCOPED_TRACE(toString(kind));
    if (kind == MotionKind::kHandheld) {
      EXPECT_GT(max_tilt_rate, 0.3);
      EXPECT_GT(max_yaw_rate, 0.3);
    } else if (kind == MotionKind::kYawOnly) {
      EXPECT_LT(max_tilt_rate, 1e-12);  // about the world z axis only
      EXPECT_GT(max_yaw_rate, 0.3);
    } else {
      EXPECT_EQ(max_rate, 0.0);
    }
  }
}

TEST(SimRig, EveryCameraKeepsSeeingTheBoard) {
  const Rig rig = viRig();
  const auto trajectory = functionOf(makeBoardTrajectory(rig, MotionOptions()));
  for (std::size_t c = 0; c < rig.cameras.size(); ++c) {
    const auto frames = simulateTagFrames(rig, c, 5.0, trajectory, 0, 0, fromSeconds(60.0), 0.0, 1);
    ASSERT_EQ(frames.size(), 301u);
    std::size_t fewest = 1000;
    for (const auto& frame : frames) fewest = std::min(fewest, frame.tags.size());
    // At least 8 tags (32 corners) in every frame, so every camera is always constrained.
    EXPECT_GE(fewest, 8u) << rig.cameras[c].name;
  }
}

// The renderer with the camera's distortion, the detector, and the simulated detections agree:
// extrinsics, distortion, corner order and ids are consistent across the simulator and the
// front end.
TEST(SimRig, RenderedImagesMatchSimulatedDetections) {
  const Rig rig = viRig();
  const std::size_t camera = 1;  // radtan, 752x480
  const auto trajectory = functionOf(makeBoardTrajectory(rig, MotionOptions()));
  const TimeNs stamp = fromSeconds(2.4);
  const auto frames = simulateTagFrames(rig, camera, 1.0, trajectory, 0, stamp, stamp, 0.0, 1);
  ASSERT_EQ(frames.size(), 1u);
  auto renderer = TagBoardRenderer::create(*rig.target);
  ASSERT_TRUE(renderer.ok());
  RenderOptions render;
  render.noise_sigma = 1.0;
  const Camera& cam = rig.cameras[camera];
  const SE3 T_G_C = cameraPose(rig, camera, trajectory, 0, stamp);
  // The fast path mvis_simulate takes (precomputed rays, two threads) and the direct one agree
  // to the noise: both are checked against the simulated detections.
  const CameraRays rays(cam, 3, 17);
  const cv::Mat image = renderer.value()->render(rays, T_G_C, render, 2);
  RenderOptions direct = render;
  direct.supersample = 3;
  const cv::Mat direct_image = renderer.value()->render(cam.resolution[0], cam.resolution[1],
                                                        cameraToBoard(cam, T_G_C), direct);
  const cv::Mat one_thread = renderer.value()->render(rays, T_G_C, render, 1);
  EXPECT_EQ(cv::norm(image, one_thread, cv::NORM_INF), 0.0);  // thread count does not matter
  auto detector = TagDetector::create(TagDetectorOptions());
  ASSERT_TRUE(detector.ok());
  for (const cv::Mat* picture : {&image, &direct_image}) {
    TagFrame detected;
    detected.width = cam.resolution[0];
    detected.height = cam.resolution[1];
    detected.tags = detector.value()->detect(*picture).value();
    TagCheckOptions checks;
    checks.num_board_tags = rig.target->numTags();
    TagRejections rejected;
    checkTagFrame(&detected, checks, &rejected);
    int matched = 0;
    double worst = 0.0, sum_sq = 0.0;
    for (const auto& tag : detected.tags) {
      for (const auto& truth : frames[0].tags) {
        if (truth.tag_id != tag.tag_id) continue;
        ++matched;
        for (int c = 0; c < 4; ++c) {
          const double e = (tag.corners_px[c] - truth.corners_px[c]).norm();
          worst = std::max(worst, e);
          sum_sq += e * e;
        }
      }
    }
    std::printf("cam1 rendered vs simulated: %d of %zu tags, corner RMS %.3f px, max %.3f px\n",
                matched, frames[0].tags.size(), std::sqrt(sum_sq / (4.0 * matched)), worst);
    EXPECT_EQ(rejected.unknown_id, 0);
    EXPECT_EQ(static_cast<std::size_t>(matched), detected.tags.size());  // no wrong ids
    EXPECT_GE(matched, static_cast<int>(frames[0].tags.size()) - 2);     // edge tags may be missed
    // Detector accuracy on rendered images is ~0.06 px RMS (test_tag_detector); the lens bends
    // tag edges by a few hundredths of a pixel here, and the straight-edge refinement absorbs
    // that into the corners.
    EXPECT_LT(std::sqrt(sum_sq / (4.0 * matched)), 0.15);
    EXPECT_LT(worst, 0.5);
  }
}

TEST(SimRig, CameraTimeShiftMovesTheStamps) {
  Rig rig = viRig();
  const auto trajectory = functionOf(makeBoardTrajectory(rig, MotionOptions()));
  const auto reference =
      simulateTagFrames(rig, 0, 1.0, trajectory, 0, fromSeconds(3.02), fromSeconds(3.02), 0.0, 1);
  rig.cameras[0].timeshift_cam_imu = 0.02;  // t_imu0 = t_cam + 0.02
  const auto shifted =
      simulateTagFrames(rig, 0, 1.0, trajectory, 0, fromSeconds(3.0), fromSeconds(3.0), 0.0, 1);
  ASSERT_EQ(shifted[0].tags.size(), reference[0].tags.size());
  for (std::size_t i = 0; i < shifted[0].tags.size(); ++i) {
    for (int c = 0; c < 4; ++c) {
      EXPECT_LT((shifted[0].tags[i].corners_px[c] - reference[0].tags[i].corners_px[c]).norm(),
                1e-9);
    }
  }
}

TEST(SimRig, PerturbationsHaveTheirSizesAndRepeat) {
  const Rig truth = viRig();
  const PerturbationSizes sizes;
  const Rig a = perturbRig(truth, sizes, 5), b = perturbRig(truth, sizes, 5);
  EXPECT_EQ(a.cameras[2].T_cam_imu.matrix(), b.cameras[2].T_cam_imu.matrix());
  EXPECT_EQ(a.inertial[1].time_offset, b.inertial[1].time_offset);
  EXPECT_EQ(a.inertial[0].T_i_b.matrix(), truth.inertial[0].T_i_b.matrix());
  EXPECT_EQ(a.inertial[0].time_offset, 0.0);
  double sum_sq_shift = 0.0, sum_sq_angle = 0.0;
  const int runs = 300;
  for (int seed = 0; seed < runs; ++seed) {
    const Rig p = perturbRig(truth, sizes, seed);
    sum_sq_shift +=
        std::pow(p.cameras[0].timeshift_cam_imu - truth.cameras[0].timeshift_cam_imu, 2);
    const Eigen::Vector3d d = lie::logQuat(truth.cameras[0].T_cam_imu.inverse().q.conjugate() *
                                           p.cameras[0].T_cam_imu.inverse().q);
    sum_sq_angle += d.squaredNorm() / 3.0;
  }
  // 300 draws: the relative standard error of a standard deviation is 1/sqrt(600) = 4%; a 15%
  // bound is almost 4 standard errors.
  EXPECT_NEAR(std::sqrt(sum_sq_shift / runs) / sizes.camera_time_offset_s, 1.0, 0.15);
  EXPECT_NEAR(std::sqrt(sum_sq_angle / runs) / sizes.camera_rotation_rad, 1.0, 0.15);
}

}  // namespace
}  // namespace mvis
