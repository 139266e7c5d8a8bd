// Track bookkeeping, and the front end's one path for images and for detections from elsewhere.
#include <gtest/gtest.h>

#include <limits>

#include "mvis/frontend/debug_image.h"
#include "mvis/frontend/tag_frontend.h"
#include "mvis/sim/tag_renderer.h"

namespace mvis {
namespace {

TagObservation tagAt(int id, double u, double v) {
  TagObservation tag;
  tag.tag_id = id;
  tag.corners_px = {Eigen::Vector2d(u, v), Eigen::Vector2d(u + 40, v),
                    Eigen::Vector2d(u + 40, v - 40), Eigen::Vector2d(u, v - 40)};
  return tag;
}

TagFrame frameAt(std::size_t camera, TimeNs stamp, std::vector<TagObservation> tags) {
  TagFrame frame;
  frame.camera = camera;
  frame.stamp_ns = stamp;
  frame.width = 752;
  frame.height = 480;
  frame.tags = std::move(tags);
  return frame;
}

TEST(TagTracks, KeepsEachFeatureInTimeOrder) {
  TagTracks tracks(2);
  EXPECT_TRUE(tracks.add(frameAt(0, 300, {tagAt(3, 100, 200)})));
  EXPECT_TRUE(tracks.add(frameAt(0, 100, {tagAt(3, 90, 200), tagAt(4, 300, 200)})));
  EXPECT_TRUE(tracks.add(frameAt(0, 200, {tagAt(3, 95, 200)})));
  EXPECT_TRUE(tracks.add(frameAt(1, 150, {tagAt(3, 10, 100)})));
  const auto& cam0 = tracks.camera(0);
  ASSERT_EQ(cam0.size(), 8u);  // tags 3 and 4, four corners each
  const auto& corner1_of_3 = cam0.at(featureId(3, 1));
  ASSERT_EQ(corner1_of_3.size(), 3u);
  EXPECT_EQ(corner1_of_3[0].stamp_ns, 100);
  EXPECT_EQ(corner1_of_3[1].stamp_ns, 200);
  EXPECT_EQ(corner1_of_3[2].stamp_ns, 300);
  EXPECT_EQ(corner1_of_3[1].uv_px, Eigen::Vector2d(135, 200));  // corner 1 = bottom-right
  EXPECT_EQ(tracks.camera(1).at(featureId(3, 0)).size(), 1u);
  EXPECT_EQ(tracks.numObservations(), 4u * (3 + 1) + 4u);
}

TEST(TagTracks, ADuplicateFrameReplacesAndABadCameraIsRefused) {
  TagTracks tracks(1);
  tracks.add(frameAt(0, 100, {tagAt(3, 90, 200)}));
  tracks.add(frameAt(0, 100, {tagAt(3, 91, 200)}));
  const auto& track = tracks.camera(0).at(featureId(3, 0));
  ASSERT_EQ(track.size(), 1u);
  EXPECT_EQ(track[0].uv_px.x(), 91.0);
  EXPECT_FALSE(tracks.add(frameAt(1, 100, {tagAt(3, 90, 200)})));
  EXPECT_EQ(tracks.numObservations(), 4u);
}

TEST(TagTracks, DropsOldObservationsAndEmptyFeatures) {
  TagTracks tracks(1);
  tracks.add(frameAt(0, 100, {tagAt(3, 90, 200), tagAt(4, 300, 200)}));
  tracks.add(frameAt(0, 200, {tagAt(3, 95, 200)}));
  tracks.dropBefore(0, 150);
  EXPECT_EQ(tracks.camera(0).size(), 4u);  // tag 4 is gone
  EXPECT_EQ(tracks.camera(0).at(featureId(3, 2)).front().stamp_ns, 200);
}

Rig twoCameraRig() {
  Rig rig;
  InertialSensor imu;
  imu.name = "imu0";
  rig.inertial.push_back(imu);
  for (int c = 0; c < 2; ++c) {
    Camera cam;
    cam.name = "cam" + std::to_string(c);
    cam.intrinsics = Eigen::Vector4d(450, 450, 375.5, 239.5);
    cam.resolution = {752, 480};
    rig.cameras.push_back(cam);
  }
  AprilGrid grid;
  grid.tag_cols = 6;
  grid.tag_rows = 6;
  grid.tag_size = 0.088;
  grid.tag_spacing = 0.3;
  rig.target = grid;
  return rig;
}

cv::Mat renderedBoard(const Rig& rig) {
  Eigen::Matrix3d R_board_cam;
  R_board_cam << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  const SE3 T_board_cam(R_board_cam, Eigen::Vector3d(0.3212, 0.3212, 0.9));
  auto renderer = TagBoardRenderer::create(*rig.target);
  return renderer.value()->render(
      752, 480, pinholeToBoard(rig.cameras[0].intrinsics, T_board_cam.inverse()), RenderOptions());
}

TEST(TagFrontend, ImagesAndDetectionsTakeTheSamePath) {
  const Rig rig = twoCameraRig();
  auto frontend = TagFrontend::create(rig, TagFrontendOptions());
  ASSERT_TRUE(frontend.ok()) << frontend.status().message();
  const cv::Mat image = renderedBoard(rig);

  const auto from_image = frontend.value()->processImage(0, 1000, image);
  ASSERT_TRUE(from_image.ok()) << from_image.status().message();
  EXPECT_EQ(from_image.value().frame.tags.size(), 36u);
  EXPECT_EQ(from_image.value().rejections.total(), 0);

  // The same tags as if detected elsewhere for camera 1, with one corrupted and one foreign id.
  TagFrame message = from_image.value().frame;
  message.camera = 1;
  message.tags[5].corners_px[1].y() = std::numeric_limits<double>::quiet_NaN();
  message.tags[6].tag_id = 99;
  const auto from_message = frontend.value()->processDetections(message);
  ASSERT_TRUE(from_message.ok());
  EXPECT_EQ(from_message.value().frame.tags.size(), 34u);
  EXPECT_EQ(from_message.value().rejections.non_finite, 1);
  EXPECT_EQ(from_message.value().rejections.unknown_id, 1);

  const TagTracks tracks = frontend.value()->tracks();
  EXPECT_EQ(tracks.camera(0).size(), 36u * 4);
  EXPECT_EQ(tracks.camera(1).size(), 34u * 4);

  const cv::Mat debug = drawTagFrame(image, from_image.value().frame);
  EXPECT_EQ(debug.type(), CV_8UC3);
  // Tag 0's outline is drawn green over what was a white/black edge.
  const Eigen::Vector2d mid = 0.5 * (from_image.value().frame.tags[0].corners_px[0] +
                                     from_image.value().frame.tags[0].corners_px[1]);
  const cv::Vec3b pixel = debug.at<cv::Vec3b>(static_cast<int>(std::lround(mid.y())),
                                              static_cast<int>(std::lround(mid.x())));
  EXPECT_GT(pixel[1], pixel[0] + 50);
}

TEST(TagFrontend, RefusesUnusableInput) {
  const Rig rig = twoCameraRig();
  auto frontend = std::move(TagFrontend::create(rig, TagFrontendOptions())).value();
  EXPECT_EQ(frontend->processImage(0, 0, cv::Mat()).status().message(), "empty image");
  EXPECT_EQ(
      frontend->processImage(0, 0, cv::Mat(240, 376, CV_8UC1, cv::Scalar(0))).status().message(),
      "image is 376x240, the camera's resolution is 752x480");
  EXPECT_EQ(
      frontend->processImage(0, 0, cv::Mat(480, 752, CV_8UC3, cv::Scalar(0))).status().message(),
      "expected an 8-bit single-channel image");
  EXPECT_EQ(frontend->processImage(2, 0, cv::Mat()).status().message(), "no camera 2");
  TagFrame stray;
  stray.camera = 5;
  EXPECT_EQ(frontend->processDetections(stray).status().message(), "no camera 5");
  EXPECT_EQ(frontend->tracks().numObservations(), 0u);
}

}  // namespace
}  // namespace mvis
