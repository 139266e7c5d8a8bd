// The detector on real photos of Kalibr AprilGrids (test/data/real_aprilgrid, see ORIGIN.md
// there): EuRoC frames with every tag in view and off-board tags around, and RealSense frames
// with the corners another detector (yac's) found.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <sstream>

#include "mvis/frontend/tag_detector.h"
#include "mvis/rig/rig.h"

namespace mvis {
namespace {

const std::string kData = std::string(MVIS_SOURCE_DIR) + "/test/data/real_aprilgrid/";

std::unique_ptr<TagDetector> gridDetector() {
  TagDetectorOptions options;
  options.tag_spacing = 0.3;  // aprilgrid_target.yaml
  auto detector = TagDetector::create(options);
  EXPECT_TRUE(detector.ok());
  return std::move(detector).value();
}

// Libapriltag alone finds one tag in two of these 13 images (ORIGIN.md): the board's squares
// join every tag's border. Every tag of the 6x6 board is in view in the EuRoC frames; the tag on
// the wall above the board and the floor markers must not be taken for board tags.
TEST(RealAprilGrid, EurocFramesGiveEveryBoardTagOnce) {
  const auto detector = gridDetector();
  for (const std::string name :
       {"cam0_1403709395937837056.png", "cam1_1403709395937837056.png", "euroc_aprilgrid.png"}) {
    const cv::Mat image = cv::imread(kData + name, cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(image.empty()) << name;
    const auto found = detector->detect(image);
    ASSERT_TRUE(found.ok());
    std::multiset<int> ids;
    for (const auto& tag : found.value()) ids.insert(tag.tag_id);
    for (int id = 0; id < 36; ++id) EXPECT_EQ(ids.count(id), 1u) << name << " tag " << id;
    EXPECT_EQ(ids.size(), 36u) << name << ": tags off the board";
  }
}

struct Reference {
  std::map<int, std::map<int, Eigen::Vector2d>> corners;  // id -> corner -> pixel
  std::map<int, std::map<int, Eigen::Vector2d>> board;    // id -> corner -> board point [m]
};

Reference readReference(const std::string& path) {
  Reference ref;
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::stringstream fields(line);
    std::vector<double> v;
    for (std::string field; std::getline(fields, field, ',');) v.push_back(std::stod(field));
    if (v.size() != 12) continue;
    const int id = static_cast<int>(v[10]), corner = static_cast<int>(v[11]);
    ref.corners[id][corner] = Eigen::Vector2d(v[5], v[6]);
    ref.board[id][corner] = Eigen::Vector2d(v[7], v[8]);
  }
  return ref;
}

// The reference is another detector's output, not truth: the bounds are what two good
// detectors agree to (0.3 px RMS) and what they each find. Measured: 340 of the 344 tags the
// reference lists (the 4 missed are in two oblique frames: a bottom corner tag whose square
// sticks to it, three tags at 60 degrees' obliquity), and 5 the reference missed, each where the
// board's homography (fitted to the reference's corners) puts it.
TEST(RealAprilGrid, RealSenseFramesAgreeWithAnotherDetector) {
  const auto detector = gridDetector();
  AprilGrid grid;
  grid.tag_cols = grid.tag_rows = 6;
  grid.tag_size = 0.088;
  grid.tag_spacing = 0.3;
  int listed = 0, matched = 0, extra = 0, corners = 0;
  double sum_sq = 0.0, outward = 0.0;
  const std::vector<std::string> stamps = {
      "1606153907495166540", "1606153915653051138", "1606153921853466272", "1606153950890122890",
      "1606153963139782667", "1606153971086688995", "1606153977721161127", "1606153983972179413",
      "1606153997421799183", "1606154004360154629"};
  for (const auto& stamp : stamps) {
    const cv::Mat image = cv::imread(kData + "frames/" + stamp + ".jpg", cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(image.empty()) << stamp;
    const Reference ref = readReference(kData + "frames/" + stamp + ".csv");
    ASSERT_FALSE(ref.corners.empty()) << stamp;
    // The board's homography from the reference's corners, to check tags it does not list.
    std::vector<cv::Point2f> board_points, image_points;
    for (const auto& [id, by_corner] : ref.corners) {
      for (const auto& [c, px] : by_corner) {
        board_points.emplace_back(ref.board.at(id).at(c).x(), ref.board.at(id).at(c).y());
        image_points.emplace_back(px.x(), px.y());
      }
    }
    const cv::Mat H = cv::findHomography(board_points, image_points);
    ASSERT_FALSE(H.empty());
    const auto found = detector->detect(image);
    ASSERT_TRUE(found.ok());
    listed += static_cast<int>(ref.corners.size());
    for (const auto& tag : found.value()) {
      ASSERT_GE(tag.tag_id, 0);
      ASSERT_LT(tag.tag_id, grid.numTags()) << stamp;
      const Eigen::Vector2d centre =
          0.25 * (tag.corners_px[0] + tag.corners_px[1] + tag.corners_px[2] + tag.corners_px[3]);
      const auto it = ref.corners.find(tag.tag_id);
      if (it == ref.corners.end()) {
        ++extra;
        for (int c = 0; c < 4; ++c) {
          const Eigen::Vector3d X = grid.corner(tag.tag_id, c);
          std::vector<cv::Point2f> in{cv::Point2f(X.x(), X.y())}, out;
          cv::perspectiveTransform(in, out, H);
          EXPECT_LT((tag.corners_px[c] - Eigen::Vector2d(out[0].x, out[0].y)).norm(), 2.0)
              << stamp << " tag " << tag.tag_id << " corner " << c << " is not where it belongs";
        }
        continue;
      }
      ++matched;
      for (const auto& [c, px] : it->second) {
        const Eigen::Vector2d error = tag.corners_px[c] - px;
        sum_sq += error.squaredNorm();
        outward += error.dot((px - centre).normalized());
        ++corners;
      }
    }
  }
  const double rms = std::sqrt(sum_sq / corners);
  std::printf(
      "RealSense frames: %d of %d listed tags found, %d more; corners vs the reference: "
      "RMS %.3f px, mean outward %+.3f px\n",
      matched, listed, extra, rms, outward / corners);
  EXPECT_GE(matched, listed - 4);
  EXPECT_LT(rms, 0.3);
  EXPECT_LT(std::abs(outward / corners), 0.05);
}

}  // namespace
}  // namespace mvis

namespace mvis {
namespace {

// What cameras and files give: the same detections from 16-bit (10 bits used, as many cameras
// store them) and from colour.
TEST(RealAprilGrid, SixteenBitAndColourImagesGiveTheSameTags) {
  const auto detector = gridDetector();
  const cv::Mat gray = cv::imread(kData + "cam0_1403709395937837056.png", cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(gray.empty());
  cv::Mat ten_bits, colour;
  gray.convertTo(ten_bits, CV_16U, 4.0);  // 0..1020
  cv::cvtColor(gray, colour, cv::COLOR_GRAY2BGR);
  const auto reference = detector->detect(gray).value();
  for (const cv::Mat& image : {ten_bits, colour}) {
    const auto converted = grayForDetection(image);
    ASSERT_TRUE(converted.ok()) << converted.status().message();
    const auto found = detector->detect(converted.value()).value();
    ASSERT_EQ(found.size(), reference.size());
    for (std::size_t i = 0; i < found.size(); ++i) {
      EXPECT_EQ(found[i].tag_id, reference[i].tag_id);
      // 16 bits scaled by 255 / 1020 round differently from the original: corners move little.
      for (int c = 0; c < 4; ++c) {
        EXPECT_LT((found[i].corners_px[c] - reference[i].corners_px[c]).norm(), 0.05);
      }
    }
  }
  EXPECT_EQ(grayForDetection(cv::Mat(4, 4, CV_32FC1)).status().message(),
            "unsupported image type: 1 channels of other bits (expected 8 or 16 bits, 1, 3 or 4 "
            "channels)");
}

}  // namespace
}  // namespace mvis
