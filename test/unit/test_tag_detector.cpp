// Tag detection against real photos with the library's expected detections, and on rendered
// boards with exactly known corners (the small tags, the refinement's gain, corrupt images).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <regex>

#include "board_images.h"
#include "mvis/frontend/tag_checks.h"
#include "mvis/frontend/tag_detector.h"

namespace mvis {
namespace {

const std::string kRealTags = std::string(MVIS_SOURCE_DIR) + "/test/data/real_tags/";

struct Expected {
  int id;
  std::array<Eigen::Vector2d, 4> corners;  // libapriltag's pixel convention
};

std::vector<Expected> readExpected(const std::string& path) {
  std::ifstream in(path);
  std::vector<Expected> tags;
  const std::regex number(R"([-+]?[0-9]*\.?[0-9]+)");
  for (std::string line; std::getline(in, line);) {
    std::vector<double> v;
    for (auto it = std::sregex_iterator(line.begin(), line.end(), number);
         it != std::sregex_iterator(); ++it) {
      v.push_back(std::stod(it->str()));
    }
    if (v.size() != 9) continue;
    Expected e{static_cast<int>(v[0]), {}};
    for (int c = 0; c < 4; ++c) e.corners[c] = Eigen::Vector2d(v[1 + 2 * c], v[2 + 2 * c]);
    tags.push_back(e);
  }
  return tags;
}

Eigen::Vector2d centre(const std::array<Eigen::Vector2d, 4>& corners) {
  return 0.25 * (corners[0] + corners[1] + corners[2] + corners[3]);
}

std::unique_ptr<TagDetector> makeDetector(const TagDetectorOptions& options) {
  auto detector = TagDetector::create(options);
  EXPECT_TRUE(detector.ok()) << detector.status().message();
  return std::move(detector).value();
}

// The expected corners are libapriltag's own output at its test settings (see
// test/data/real_tags/ORIGIN.md), not ground truth. With libapriltag as the engine and no
// refinement this checks the wrapping, the pixel convention and the ids against the library's
// reference; with mvis's engine it checks that mvis finds the same tags in photos it was not
// made on (single tags on cubes, with shadows and clutter), its corners within the library's own
// scatter (its refine_edges alone moves them by ~0.4 px).
struct PhotoResult {
  int expected = 0, found = 0;
  double worst_px = 0.0;
};

PhotoResult comparePhotos(const TagDetector& detector, double max_corner_px) {
  PhotoResult result;
  for (const std::string name :
       {"33369213973_9d9bb4cc96_c", "34085369442_304b6bafd9_c", "34139872896_defdb2f8d9_c"}) {
    const cv::Mat image = cv::imread(kRealTags + name + ".jpg", cv::IMREAD_GRAYSCALE);
    EXPECT_FALSE(image.empty()) << name;
    const auto expected = readExpected(kRealTags + name + ".txt");
    EXPECT_FALSE(expected.empty()) << name;
    const auto found = detector.detect(image);
    EXPECT_TRUE(found.ok());
    for (const auto& e : expected) {
      ++result.expected;
      // The same id, nearest centre (every tag in these photos has id 0).
      const TagObservation* best = nullptr;
      double best_distance = 1e9;
      for (const auto& tag : found.value()) {
        // Back to the library's convention: ours is half a pixel less in u and v.
        std::array<Eigen::Vector2d, 4> lib;
        for (int c = 0; c < 4; ++c) lib[c] = tag.corners_px[c] + Eigen::Vector2d(0.5, 0.5);
        const double d = (centre(lib) - centre(e.corners)).norm();
        if (tag.tag_id == e.id && d < best_distance) {
          best_distance = d;
          best = &tag;
        }
      }
      if (!best || best_distance > 3.0) continue;
      ++result.found;
      for (int c = 0; c < 4; ++c) {
        const double error =
            (best->corners_px[c] + Eigen::Vector2d(0.5, 0.5) - e.corners[c]).norm();
        result.worst_px = std::max(result.worst_px, error);
        EXPECT_LT(error, max_corner_px)
            << name << " tag at " << centre(e.corners).transpose() << " corner " << c;
      }
    }
  }
  return result;
}

TEST(TagDetector, LibapriltagFindsItsOwnTagsInRealPhotos) {
  TagDetectorOptions options;
  options.use_libapriltag = true;
  options.decimate = 1.0;
  options.refine_edges = false;
  options.refine_corners = false;
  options.max_hamming = 2;
  const PhotoResult r = comparePhotos(*makeDetector(options), 0.5);
  std::printf("libapriltag on real photos: %d of %d expected tags, worst corner %.3f px\n", r.found,
              r.expected, r.worst_px);
  EXPECT_GE(r.found, r.expected - 1);  // Debian's 3.3.0 misses one (ORIGIN.md)
}

// Measured: 43 of 47; the four missed are tags of 13-19 px on cubes at the image's edge or
// behind others, which libapriltag's gradient-based quads reach and mvis's thresholded ones
// do not. Corners: tags under 20 px (cells under 2.5 px) keep the quad finder's corners, up to
// ~1.6 px from the library's, as does one half-hidden tag under a cube; the rest within 1 px.
TEST(TagDetector, MvisFindsTheLibrarysTagsInRealPhotos) {
  const PhotoResult r = comparePhotos(*makeDetector(TagDetectorOptions()), 2.0);
  std::printf(
      "mvis on real photos: %d of %d expected tags, worst corner %.3f px from the "
      "library's\n",
      r.found, r.expected, r.worst_px);
  EXPECT_GE(r.found, r.expected - 4);
}

struct CornerErrors {
  int tags = 0;
  int wrong_ids = 0;
  double rms = 0.0;
  double max = 0.0;
};

// A board (plain tags, mvis's renderer, noise sigma 2) seen from `T_cam_board`.
test::BoardView renderScene(const SE3& T_cam_board, std::uint32_t seed) {
  test::ViewOptions options;
  options.seed = seed;
  return test::renderBoard(T_cam_board, options);
}

CornerErrors measure(const test::BoardView& scene, const std::vector<TagObservation>& tags) {
  CornerErrors e;
  double sum_sq = 0.0;
  for (const auto& tag : tags) {
    if (tag.tag_id < 0 || tag.tag_id >= scene.grid.numTags()) {
      ++e.wrong_ids;
      continue;
    }
    double tag_max = 0.0;
    for (int c = 0; c < 4; ++c) {
      const double error = (tag.corners_px[c] - scene.truth(tag.tag_id, c)).norm();
      tag_max = std::max(tag_max, error);
      sum_sq += error * error;
    }
    // A wrong id puts its corners a tag pitch (tens of pixels) from where that id's are.
    if (tag_max > 5.0) {
      ++e.wrong_ids;
      continue;
    }
    ++e.tags;
    e.max = std::max(e.max, tag_max);
  }
  e.rms = e.tags ? std::sqrt(sum_sq / (4.0 * e.tags)) : 0.0;
  return e;
}

// Corner accuracy per renderer, board kind and blur is test_tag_corners'; here the small end:
// tags of 26 px (cells of ~3 px) are all found with the right ids, their corners refined where
// the cells allow and the quad finder's elsewhere.
TEST(TagDetector, SmallTagsAreFoundWithTheRightIds) {
  const auto detector = makeDetector(TagDetectorOptions());
  const test::BoardView scene = renderScene(test::viewOfBoard(0.2, 0.1, 1.5), 11);
  const CornerErrors e = measure(scene, detector->detect(scene.image).value());
  std::printf("small tags (26 px): %d found, corner RMS %.3f px, max %.3f px\n", e.tags, e.rms,
              e.max);
  EXPECT_EQ(e.tags, scene.grid.numTags());
  EXPECT_EQ(e.wrong_ids, 0);
  EXPECT_LT(e.rms, 0.25);
}

// The refinement is what makes the corners: the quad finder's own (thresholded contours) are
// several times further off.
TEST(TagDetector, RefinementBeatsTheQuadFindersCorners) {
  TagDetectorOptions unrefined;
  unrefined.refine_corners = false;
  const auto rough = makeDetector(unrefined);
  const auto refined = makeDetector(TagDetectorOptions());
  const test::BoardView scene = renderScene(test::viewOfBoard(0.25, -0.2, 0.9), 7);
  const CornerErrors before = measure(scene, rough->detect(scene.image).value());
  const CornerErrors after = measure(scene, refined->detect(scene.image).value());
  std::printf("corner RMS: quads %.3f px, refined %.3f px\n", before.rms, after.rms);
  ASSERT_EQ(before.tags, after.tags);
  EXPECT_LT(after.rms, 0.5 * before.rms);
}

TEST(TagDetector, RefusesCorruptImages) {
  const auto detector = makeDetector(TagDetectorOptions());
  EXPECT_EQ(detector->detect(cv::Mat()).status().message(), "empty image");
  EXPECT_EQ(detector->detect(cv::Mat(0, 0, CV_8UC1)).status().message(), "empty image");
  EXPECT_EQ(detector->detect(cv::Mat(10, 10, CV_8UC3, cv::Scalar(0))).status().message(),
            "expected an 8-bit single-channel image");
  EXPECT_EQ(detector->detect(cv::Mat(10, 10, CV_16UC1, cv::Scalar(0))).status().message(),
            "expected an 8-bit single-channel image");
  const auto blank = detector->detect(cv::Mat(480, 752, CV_8UC1, cv::Scalar(128)));
  ASSERT_TRUE(blank.ok());
  EXPECT_TRUE(blank.value().empty());
}

TEST(TagDetector, RefusesBadOptions) {
  TagDetectorOptions options;
  options.family = "tag99h1";
  EXPECT_EQ(TagDetector::create(options).status().message(),
            "tag detector: unknown tag family 'tag99h1'");
  options = TagDetectorOptions();
  options.decimate = 0.5;
  EXPECT_EQ(TagDetector::create(options).status().message(), "tag detector: decimate must be >= 1");
}

}  // namespace
}  // namespace mvis
