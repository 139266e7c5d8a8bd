// Predicted regions (TagFrontendOptions::full_search_every): a camera's image searched only where
// its previous images' tags are heading must give the tags, and their corners, that the whole
// image's search gives. Checked on rendered sequences of both board kinds and on the real
// AprilGrid photos of test/data/real_aprilgrid, moved across the image.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "mvis/frontend/tag_frontend.h"
#include "mvis/sim/tag_renderer.h"

namespace mvis {
namespace {

const std::string kData = std::string(MVIS_SOURCE_DIR) + "/test/data/real_aprilgrid/";
constexpr TimeNs kFrameNs = 50'000'000;  // 20 Hz

Rig oneCameraRig(int width, int height, const AprilGrid& grid) {
  Rig rig;
  rig.inertial.emplace_back();
  rig.inertial.back().name = "imu0";
  Camera camera;
  camera.name = "cam0";
  camera.intrinsics = Eigen::Vector4d(450, 450, 0.5 * (width - 1), 0.5 * (height - 1));
  camera.resolution = {width, height};
  rig.cameras.push_back(camera);
  rig.target = grid;
  return rig;
}

AprilGrid realBoard() {  // aprilgrid_target.yaml
  AprilGrid grid;
  grid.tag_cols = grid.tag_rows = 6;
  grid.tag_size = 0.088;
  grid.tag_spacing = 0.3;
  return grid;
}

// Runs `images` through two front ends, one searching whole images, one with predicted regions,
// and compares what they found. Returns how many images were searched in a predicted region.
struct Comparison {
  int predicted = 0;
  double largest_fraction = 0.0;  // of the image searched in a predicted region
  double largest_difference_px = 0.0;
  int tags = 0;
};

Comparison compare(const Rig& rig, const std::vector<cv::Mat>& images, const std::string& what,
                   double decimate = 1.0) {
  TagFrontendOptions options;
  options.detector.decimate = decimate;
  TagFrontendOptions whole_options = options;
  whole_options.full_search_every = 1;
  auto whole = TagFrontend::create(rig, whole_options);
  auto predicted = TagFrontend::create(rig, options);
  EXPECT_TRUE(whole.ok() && predicted.ok());
  Comparison out;
  for (std::size_t k = 0; k < images.size(); ++k) {
    const TimeNs stamp = static_cast<TimeNs>(k) * kFrameNs;
    const auto a = whole.value()->processImage(0, stamp, images[k]);
    const auto b = predicted.value()->processImage(0, stamp, images[k]);
    EXPECT_TRUE(a.ok() && b.ok()) << what << " image " << k << ": "
                                  << (a.ok() ? b.status() : a.status()).message();
    if (!a.ok() || !b.ok()) continue;
    EXPECT_FALSE(a.value().predicted_region);
    if (b.value().predicted_region) {
      ++out.predicted;
      out.largest_fraction = std::max(out.largest_fraction, b.value().searched_fraction);
    }
    const auto& found_whole = a.value().frame.tags;
    const auto& found_region = b.value().frame.tags;
    EXPECT_EQ(found_whole.size(), found_region.size()) << what << " image " << k;
    std::map<int, const TagObservation*> by_id;
    for (const auto& tag : found_region) by_id[tag.tag_id] = &tag;
    for (const auto& tag : found_whole) {
      const auto it = by_id.find(tag.tag_id);
      EXPECT_NE(it, by_id.end()) << what << " image " << k << ": tag " << tag.tag_id
                                 << " not found in the predicted region";
      if (it == by_id.end()) continue;
      ++out.tags;
      for (int c = 0; c < 4; ++c) {
        out.largest_difference_px = std::max(
            out.largest_difference_px, (tag.corners_px[c] - it->second->corners_px[c]).norm());
      }
    }
  }
  return out;
}

// A camera gliding over the board and turning a little, 20 images at 20 Hz: the board's image
// moves 4-9 px per image and grows by a fifth.
std::vector<cv::Mat> renderedSequence(const AprilGrid& grid, BoardKind kind) {
  auto renderer = TagBoardRenderer::create(grid, kind);
  EXPECT_TRUE(renderer.ok());
  const double centre = 0.5 * (grid.tag_cols * grid.tag_size * (1.0 + grid.tag_spacing));
  std::vector<cv::Mat> images;
  for (int k = 0; k < 20; ++k) {
    const double s = k / 19.0;
    Eigen::Matrix3d R_board_cam;  // looking down at the board, rolled by up to 6 degrees
    const double roll = 0.1 * s;
    R_board_cam << std::cos(roll), std::sin(roll), 0, std::sin(roll), -std::cos(roll), 0, 0, 0, -1;
    const SE3 T_board_cam(R_board_cam, Eigen::Vector3d(centre - 0.08 + 0.16 * s,
                                                       centre + 0.05 - 0.1 * s, 1.1 - 0.2 * s));
    RenderOptions options;
    options.blur_sigma = 0.6;
    options.noise_sigma = 2.0;
    options.seed = 7 + k;
    options.supersample = 2;
    images.push_back(renderer.value()->render(
        752, 480, pinholeToBoard(Eigen::Vector4d(450, 450, 375.5, 239.5), T_board_cam.inverse()),
        options));
  }
  return images;
}

TEST(PredictedRegions, RenderedSequencesGiveTheWholeSearchsTagsAndCorners) {
  for (const BoardKind kind : {BoardKind::kPlain, BoardKind::kKalibrGrid}) {
    const std::string what = kind == BoardKind::kPlain ? "plain board" : "AprilGrid";
    AprilGrid grid = realBoard();
    if (kind == BoardKind::kPlain) grid.tag_cols = grid.tag_rows = 8, grid.tag_size = 0.05;
    const std::vector<cv::Mat> images = renderedSequence(grid, kind);
    // Quads searched at full and at half resolution (the nodelet's default).
    for (const double decimate : {1.0, 2.0}) {
      const std::string run = what + ", decimate " + std::to_string(decimate);
      const Comparison c = compare(oneCameraRig(752, 480, grid), images, run, decimate);
      // Every image but the first and every tenth searched in its predicted region only, a part
      // of the image; the corners the same to 0.01 px (they are the same bit for bit).
      EXPECT_EQ(c.predicted, 18) << run;
      EXPECT_LT(c.largest_fraction, 0.6) << run;
      EXPECT_GE(c.tags, 20 * grid.numTags() * 9 / 10) << run;
      EXPECT_LE(c.largest_difference_px, 0.01) << run;
    }
  }
}

// Each real photo moved across the image as a camera panning at 20 Hz would see it (8 px right
// and 5 px up per image, the uncovered part grey): the first image searched whole, the next
// ones in the predicted regions.
// locateTags in order, finishImage in any order (as mvis_offline's threads do): the frames of
// processImage, exactly.
TEST(PredictedRegions, LocatingInOrderAndRefiningInAnyOrderGivesTheSameFrames) {
  AprilGrid grid = realBoard();
  grid.tag_cols = grid.tag_rows = 8, grid.tag_size = 0.05;
  const Rig rig = oneCameraRig(752, 480, grid);
  const std::vector<cv::Mat> images = renderedSequence(grid, BoardKind::kPlain);
  auto in_one = TagFrontend::create(rig, TagFrontendOptions());
  auto split = TagFrontend::create(rig, TagFrontendOptions());
  ASSERT_TRUE(in_one.ok() && split.ok());
  std::vector<LocatedTags> located;
  for (std::size_t k = 0; k < images.size(); ++k) {
    auto l = split.value()->locateTags(0, static_cast<TimeNs>(k) * kFrameNs, images[k]);
    ASSERT_TRUE(l.ok());
    located.push_back(std::move(l).value());
  }
  int predicted = 0;
  std::vector<TagFrontendResult> expected;
  for (std::size_t k = 0; k < images.size(); ++k) {
    expected.push_back(
        in_one.value()->processImage(0, static_cast<TimeNs>(k) * kFrameNs, images[k]).value());
  }
  for (std::size_t k = images.size(); k-- > 0;) {
    const auto b = split.value()->finishImage(0, images[k], located[k]);
    ASSERT_TRUE(b.ok());
    predicted += b.value().predicted_region;
    const auto& want = expected[k].frame.tags;
    const auto& got = b.value().frame.tags;
    ASSERT_EQ(want.size(), got.size()) << "image " << k;
    for (std::size_t t = 0; t < want.size(); ++t) {
      EXPECT_EQ(want[t].tag_id, got[t].tag_id);
      for (int c = 0; c < 4; ++c) EXPECT_EQ(want[t].corners_px[c], got[t].corners_px[c]);
    }
  }
  EXPECT_EQ(predicted, 18);
}

TEST(PredictedRegions, RealAprilGridPhotosGiveTheWholeSearchsTagsAndCorners) {
  std::vector<std::string> names = {"cam0_1403709395937837056.png", "cam1_1403709395937837056.png",
                                    "euroc_aprilgrid.png"};
  for (const std::string stamp :
       {"1606153907495166540", "1606153915653051138", "1606153921853466272", "1606153950890122890",
        "1606153963139782667", "1606153971086688995", "1606153977721161127", "1606153983972179413",
        "1606153997421799183", "1606154004360154629"}) {
    names.push_back("frames/" + stamp + ".jpg");
  }
  int predicted = 0, tags = 0;
  double largest_difference = 0.0;
  for (const std::string& name : names) {
    const cv::Mat photo = cv::imread(kData + name, cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(photo.empty()) << name;
    std::vector<cv::Mat> images;
    for (int k = 0; k < 4; ++k) {
      cv::Mat moved(photo.size(), CV_8UC1, cv::Scalar(128));
      const int dx = 8 * k, dy = 5 * k;
      photo(cv::Rect(0, dy, photo.cols - dx, photo.rows - dy))
          .copyTo(moved(cv::Rect(dx, 0, photo.cols - dx, photo.rows - dy)));
      images.push_back(moved);
    }
    const Comparison c = compare(oneCameraRig(photo.cols, photo.rows, realBoard()), images, name);
    EXPECT_EQ(c.predicted, 3) << name;
    predicted += c.predicted;
    tags += c.tags;
    largest_difference = std::max(largest_difference, c.largest_difference_px);
  }
  // 13 photos with 24-36 tags each, four positions.
  EXPECT_GE(tags, 13 * 4 * 24);
  EXPECT_LE(largest_difference, 0.01);
  EXPECT_EQ(predicted, 13 * 3);
}

// The real RealSense frames in their own order, 50 ms apart as if one camera's: the views differ
// by more than the prediction allows for in some, where the whole image is searched again; the
// result is the whole search's either way.
TEST(PredictedRegions, RealFramesInSequenceGiveTheWholeSearchsTags) {
  std::vector<cv::Mat> images;
  for (const std::string stamp :
       {"1606153907495166540", "1606153915653051138", "1606153921853466272", "1606153950890122890",
        "1606153963139782667", "1606153971086688995", "1606153977721161127", "1606153983972179413",
        "1606153997421799183", "1606154004360154629"}) {
    images.push_back(cv::imread(kData + "frames/" + stamp + ".jpg", cv::IMREAD_GRAYSCALE));
    ASSERT_FALSE(images.back().empty()) << stamp;
  }
  const Comparison c = compare(oneCameraRig(640, 480, realBoard()), images, "RealSense frames");
  EXPECT_GE(c.tags, 10 * 24);
  EXPECT_LE(c.largest_difference_px, 0.01);
  // Both paths taken: 6 of the 9 frames after the first held their prediction, 3 did not.
  EXPECT_EQ(c.predicted, 6);
}

TEST(PredictedRegions, PredictionMovesTagsOnAndBoundsTheRegion) {
  TagObservation before, last;
  before.tag_id = last.tag_id = 4;
  for (int c = 0; c < 4; ++c) {
    const Eigen::Vector2d corner(100.0 + 20.0 * (c == 1 || c == 2), 200.0 - 20.0 * (c >= 2));
    before.corners_px[c] = corner;
    last.corners_px[c] = corner + Eigen::Vector2d(10.0, -4.0);
  }
  // Half an interval later: half the step on; the box holds the last and the predicted corners
  // with a margin of the tag's side (20 px) plus the step (5.4 px).
  const TagPrediction p = predictTags({last}, 100, {before}, 0, 150, 752, 480);
  ASSERT_EQ(p.expected.size(), 1u);
  EXPECT_NEAR((p.expected[0].corners_px[0] - Eigen::Vector2d(115.0, 194.0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(p.margin_px, 20.0 + std::hypot(5.0, 2.0), 1e-12);
  EXPECT_EQ(p.region.x, static_cast<int>(std::floor(110.0 - p.margin_px)));
  EXPECT_EQ(p.region.y, static_cast<int>(std::floor(174.0 - p.margin_px)));
  EXPECT_EQ(p.region.x + p.region.width, static_cast<int>(std::ceil(135.0 + p.margin_px)) + 1);
  // A tag heading out of the image is not expected; nothing to predict from: no region.
  const TagPrediction out = predictTags({last}, 100, {before}, 0, 1000, 140, 480);
  EXPECT_TRUE(out.expected.empty());
  EXPECT_TRUE(predictTags({}, 100, {}, 0, 150, 752, 480).region.empty());
  EXPECT_TRUE(predictTags({last}, 100, {}, 0, 100, 752, 480).region.empty());
}

}  // namespace
}  // namespace mvis
