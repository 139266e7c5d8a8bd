// Seeded fuzzing of the messages the nodelet takes: sensor_msgs/Image (any encoding, size,
// step and data length), sensor_msgs/CompressedImage (damaged PNG and JPEG, noise),
// sensor_msgs/Imu (NaN, inf, huge) and mvis/TagDetectionArray, through the conversions and on
// into the front end. Nothing may crash; what a conversion accepts must be what it claims (an
// 8-bit image of the message's size, finite readings). MVIS_FUZZ_CASES sets the number of cases
// per test (scripts/fuzz: 100,000).
#include <gtest/gtest.h>

#include <boost/make_shared.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>

#include "../unit/fuzz_util.h"
#include "mvis/frontend/tag_frontend.h"
#include "mvis/rig/rig_io.h"
#include "mvis/ros/conversions.h"

namespace mvis {
namespace {

const std::string kRoot = std::string(MVIS_SOURCE_DIR) + "/";

TEST(FuzzMessages, ImagesAreConvertedOrRefused) {
  const Rig rig = loadRig(kRoot + "config/sim_small_rig").value();
  auto frontend = TagFrontend::create(rig, TagFrontendOptions()).value();
  const std::vector<std::string> encodings = {
      "mono8", "mono16", "bgr8",        "rgb8",   "bgra8", "rgba8",   "8UC1",  "8UC3",
      "16UC1", "32FC1",  "bayer_rggb8", "yuv422", "",      "garbage", "64FC4", "8SC1"};
  std::mt19937 rng(3);
  const auto pick = [&](int n) { return std::uniform_int_distribution<int>(0, n - 1)(rng); };
  const int n = fuzz::cases(3000);
  int converted = 0;
  for (int i = 0; i < n; ++i) {
    auto msg = boost::make_shared<sensor_msgs::Image>();
    msg->encoding = encodings[pick(encodings.size())];
    msg->width = pick(6) == 0 ? 376 : pick(64);
    msg->height = pick(6) == 0 ? 240 : pick(64);
    if (pick(50) == 0) msg->width = 1u << 30;  // absurd sizes with little data
    if (pick(50) == 0) msg->height = 1u << 30;
    const int bytes_per_pixel = 1 + pick(8);
    switch (pick(4)) {
      case 0:
        msg->step = msg->width * bytes_per_pixel;
        break;
      case 1:
        msg->step = pick(64);
        break;
      case 2:
        msg->step = msg->width * bytes_per_pixel + pick(8);
        break;
      default:
        msg->step = 0;
        break;
    }
    std::size_t size = static_cast<std::size_t>(msg->step) * std::min(msg->height, 4096u);
    if (pick(3) == 0) size = pick(4096);
    msg->data.resize(std::min<std::size_t>(size, 1 << 22));
    for (auto& b : msg->data) b = static_cast<std::uint8_t>(pick(256));
    cv::Mat gray;
    std::string why;
    const std::string what = "case " + std::to_string(i) + " " + msg->encoding + " " +
                             std::to_string(msg->width) + "x" + std::to_string(msg->height) +
                             " step " + std::to_string(msg->step) + ", " +
                             std::to_string(msg->data.size()) + " bytes";
    if (!ros_conversions::toGray(msg, &gray, &why)) {
      EXPECT_FALSE(why.empty()) << what;
      continue;
    }
    ++converted;
    ASSERT_EQ(gray.type(), CV_8UC1) << what;
    ASSERT_EQ(gray.cols, static_cast<int>(msg->width)) << what;
    ASSERT_EQ(gray.rows, static_cast<int>(msg->height)) << what;
    // The whole image must lie inside the message's data.
    if (gray.rows > 0 && gray.cols > 0) {
      const auto* first = gray.ptr<std::uint8_t>(0);
      const auto* last = gray.ptr<std::uint8_t>(gray.rows - 1) + gray.cols;
      const bool shared = first >= msg->data.data() && first < msg->data.data() + msg->data.size();
      if (shared) {
        ASSERT_LE(last, msg->data.data() + msg->data.size()) << what;
      }
    }
    const auto result = frontend->processImage(0, 1000 + i, gray);  // size checked there
    if (result.ok()) {
      EXPECT_EQ(gray.cols, 376) << what;
    }
  }
  std::printf("%d fuzzed Image messages: %d converted\n", n, converted);
}

TEST(FuzzMessages, CompressedImagesAreDecodedOrRefused) {
  cv::Mat board(120, 160, CV_8UC1);
  cv::randu(board, 0, 256);
  std::vector<std::uint8_t> png, jpg;
  cv::imencode(".png", board, png);
  cv::imencode(".jpg", board, jpg);
  std::mt19937 rng(5);
  const auto pick = [&](int n) { return std::uniform_int_distribution<int>(0, n - 1)(rng); };
  const int n = fuzz::cases(2000);
  int decoded = 0;
  for (int i = 0; i < n; ++i) {
    sensor_msgs::CompressedImage msg;
    msg.format = pick(2) ? "mono8; png compressed" : "jpeg";
    msg.data = pick(2) ? png : jpg;
    for (int k = 1 + pick(6); k > 0 && !msg.data.empty(); --k) {
      const std::size_t at = pick(static_cast<int>(msg.data.size()));
      if (pick(3) == 0) {
        msg.data.resize(at);
      } else {
        msg.data[at] = static_cast<std::uint8_t>(pick(256));
      }
    }
    if (pick(20) == 0) msg.data.assign(pick(64), static_cast<std::uint8_t>(pick(256)));
    cv::Mat gray;
    std::string why;
    if (!ros_conversions::toGray(msg, &gray, &why)) {
      EXPECT_FALSE(why.empty());
      continue;
    }
    ++decoded;
    ASSERT_EQ(gray.type(), CV_8UC1) << "case " << i;
    ASSERT_FALSE(gray.empty()) << "case " << i;
  }
  std::printf("%d damaged compressed images: %d still decoded\n", n, decoded);
}

TEST(FuzzMessages, ImuAndDetectionMessagesAreCheckedOrRefused) {
  std::mt19937 rng(9);
  const auto pick = [&](int n) { return std::uniform_int_distribution<int>(0, n - 1)(rng); };
  const std::vector<double> values = {0.0,       1.0,   -9.81,  std::nan(""), INFINITY,
                                      -INFINITY, 1e308, -1e308, 5e-324};
  const Rig rig = loadRig(kRoot + "config/sim_small_rig").value();
  auto frontend = TagFrontend::create(rig, TagFrontendOptions()).value();
  const int n = fuzz::cases(3000);
  int readings = 0, tags = 0;
  for (int i = 0; i < n; ++i) {
    sensor_msgs::Imu imu;
    imu.header.stamp.sec = pick(2) ? 1700000000 + i : pick(1000);
    imu.angular_velocity.x = values[pick(values.size())];
    imu.angular_velocity.y = values[pick(values.size())];
    imu.angular_velocity.z = values[pick(values.size())];
    imu.linear_acceleration.x = values[pick(values.size())];
    imu.linear_acceleration.y = values[pick(values.size())];
    imu.linear_acceleration.z = values[pick(values.size())];
    ImuMeasurement reading;
    std::string why;
    const bool gyroscope = pick(2);
    if (ros_conversions::toImuMeasurement(imu, gyroscope, &reading, &why)) {
      ++readings;
      ASSERT_TRUE(reading.gyro.allFinite());
      ASSERT_TRUE(reading.accel.allFinite());
    } else {
      EXPECT_FALSE(why.empty());
    }

    mvis::TagDetectionArray detections;
    detections.header.stamp.sec = 1700000000 + i;
    for (int t = pick(30); t > 0; --t) {
      mvis::TagDetection d;
      d.id = pick(10) == 0 ? pick(100000) - 50000 : pick(40);
      for (int c = 0; c < 8; ++c) {
        d.corners[c] = pick(15) == 0 ? values[pick(values.size())] : pick(400) - 10;
      }
      detections.detections.push_back(d);
    }
    const auto result = frontend->processDetections(ros_conversions::toTagFrame(detections, 0));
    ASSERT_TRUE(result.ok());
    for (const auto& tag : result.value().frame.tags) {
      ++tags;
      for (const auto& c : tag.corners_px) ASSERT_TRUE(c.allFinite());
      EXPECT_GE(tag.tag_id, 0);
    }
  }
  std::printf("%d fuzzed Imu and TagDetectionArray messages: %d readings, %d tags kept\n", n,
              readings, tags);
}

}  // namespace
}  // namespace mvis
