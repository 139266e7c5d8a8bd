// Corner accuracy of the tag detector on boards rendered by two independent renderers (mvis's
// and a texture renderer built from OpenCV, board_images.h), both kinds of board (plain tags and
// Kalibr AprilGrids), blur from none to 1.5 px, noise sigma 2 on a contrast of 190; and the
// texture renderer's images gamma-encoded (2.2, blur 0 and 0.5 px), where plain tags' edges move
// into the black (without the detector's response correction -0.118 and -0.205 px outward,
// with it +0.009 and -0.009).
//
// The bounds are the detector's contract: no systematic outward or inward error beyond 0.01 px
// (the mean over the 864 corners of a case: its noise is ~0.06 / sqrt(864) = 0.002 px, so
// 0.01 px is a bias, not noise) and RMS <= 0.08 px. One case falls short on RMS and is held to
// what it does, so that it cannot get worse unnoticed: plain tags (a border one cell wide)
// under the heaviest blur, sigma 1.5 px on cells of ~5.5 px, where the data cells' blur reaches
// the outer edge: RMS 0.10 px, its bias still within 0.008 px (Kalibr's boards, two-cell
// borders and corners at junctions, stay within the contract there).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "board_images.h"
#include "mvis/camera/camera_model.h"
#include "mvis/frontend/tag_detector.h"
#include "mvis/frontend/tag_observation.h"
#include "mvis/rig/rig_io.h"
#include "mvis/sim/coverage_renderer.h"

namespace mvis {
namespace {

struct Errors {
  int tags = 0, wrong_ids = 0, corners = 0;
  double outward_sum = 0.0, sum_sq = 0.0, max = 0.0;
  double outward() const { return corners ? outward_sum / corners : 0.0; }
  double rms() const { return corners ? std::sqrt(sum_sq / corners) : 0.0; }
};

void measure(const test::BoardView& view, const std::vector<TagObservation>& tags, Errors* e) {
  for (const auto& tag : tags) {
    if (tag.tag_id < 0 || tag.tag_id >= view.grid.numTags()) {
      ++e->wrong_ids;
      continue;
    }
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    for (int c = 0; c < 4; ++c) centre += 0.25 * view.truth(tag.tag_id, c);
    ++e->tags;
    for (int c = 0; c < 4; ++c) {
      const Eigen::Vector2d truth = view.truth(tag.tag_id, c);
      const Eigen::Vector2d error = tag.corners_px[c] - truth;
      if (error.norm() > 5.0) {  // a wrong id lands a tag pitch away
        ++e->wrong_ids;
        break;
      }
      e->outward_sum += error.dot((truth - centre).normalized());
      e->sum_sq += error.squaredNorm();
      e->max = std::max(e->max, error.norm());
      ++e->corners;
    }
  }
}

const std::vector<SE3>& views() {
  static const std::vector<SE3> kViews = {
      test::viewOfBoard(0.0, 0.0, 0.9),    test::viewOfBoard(0.35, 0.05, 0.9),
      test::viewOfBoard(0.05, -0.45, 1.0), test::viewOfBoard(0.3, 0.3, 0.8),
      test::viewOfBoard(-0.45, 0.2, 0.95), test::viewOfBoard(0.12, -0.08, 0.85),
  };
  return kViews;
}

// The detector as for the boards here (gaps of 0.3 tags).
std::unique_ptr<TagDetector> boardDetector() {
  TagDetectorOptions options;
  options.tag_spacing = 0.3;
  auto detector = TagDetector::create(options);
  EXPECT_TRUE(detector.ok());
  return std::move(detector).value();
}

struct Case {
  test::Renderer renderer;
  BoardKind kind;
  double blur;
  double gamma = 1.0;  // texture renderer only
};

class CornerAccuracy : public ::testing::TestWithParam<Case> {};

TEST_P(CornerAccuracy, IsUnbiasedAndPrecise) {
  const Case c = GetParam();
  const auto detector = boardDetector();
  Errors e;
  std::uint32_t seed = 1;
  for (const SE3& T : views()) {
    test::ViewOptions options;
    options.renderer = c.renderer;
    options.kind = c.kind;
    options.blur_sigma = c.blur;
    options.gamma = c.gamma;
    options.seed = seed++;
    const test::BoardView view = test::renderBoard(T, options);
    const auto found = detector->detect(view.image);
    ASSERT_TRUE(found.ok());
    const int before = e.tags;
    measure(view, found.value(), &e);
    std::string missing;
    for (int id = 0; id < view.grid.numTags(); ++id) {
      bool seen = false;
      for (const auto& tag : found.value()) seen = seen || tag.tag_id == id;
      if (!seen) missing += " " + std::to_string(id);
    }
    EXPECT_EQ(e.tags - before, view.grid.numTags()) << "view " << seed - 1 << " misses" << missing;
  }
  std::printf(
      "%-7s %-6s blur %.1f gamma %.1f: %d tags, outward %+.4f px, RMS %.4f px, max %.3f px\n",
      c.renderer == test::Renderer::kMvis ? "mvis" : "texture",
      c.kind == BoardKind::kPlain ? "plain" : "kalibr", c.blur, c.gamma, e.tags, e.outward(),
      e.rms(), e.max);
  EXPECT_EQ(e.wrong_ids, 0);
  const bool thin_and_blurred = c.kind == BoardKind::kPlain && c.blur > 1.2;
  EXPECT_LT(std::abs(e.outward()), 0.01);
  EXPECT_LT(e.rms(), thin_and_blurred ? 0.12 : 0.08);
}

std::vector<Case> cases() {
  std::vector<Case> all;
  for (const auto renderer : {test::Renderer::kMvis, test::Renderer::kTexture}) {
    for (const auto kind : {BoardKind::kPlain, BoardKind::kKalibrGrid}) {
      for (const double blur : {0.0, 0.5, 1.0, 1.5}) all.push_back({renderer, kind, blur});
    }
  }
  for (const auto kind : {BoardKind::kPlain, BoardKind::kKalibrGrid}) {
    for (const double blur : {0.0, 0.5}) all.push_back({test::Renderer::kTexture, kind, blur, 2.2});
  }
  return all;
}

INSTANTIATE_TEST_SUITE_P(Renderers, CornerAccuracy, ::testing::ValuesIn(cases()));

TEST(CoverageRenderer, PixelCoverageIsTheExactArea) {
  // The unit square [0, 1]^2 and a triangle over pixels at various offsets.
  const std::vector<Eigen::Vector2d> square = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  EXPECT_NEAR(pixelCoverage(square, 0.5, 0.5), 1.0, 1e-15);
  EXPECT_NEAR(pixelCoverage(square, 1.0, 0.5), 0.5, 1e-15);
  EXPECT_NEAR(pixelCoverage(square, 1.25, 1.25), 0.0625, 1e-15);
  EXPECT_NEAR(pixelCoverage(square, 2.0, 0.5), 0.0, 1e-15);
  // Clockwise, and a diagonal edge: the half below y = x of the pixel centred at (0.5, 0.5).
  const std::vector<Eigen::Vector2d> triangle = {{-1, -1}, {3, 3}, {3, -1}};
  EXPECT_NEAR(pixelCoverage(triangle, 0.5, 0.5), 0.5, 1e-15);
}

// Through a real lens model: cam1 of the simulated VI-Rig (752x480, radtan k1 = -0.12), the
// coverage renderer bending each cell's sides (four segments a side), plain tags, blur 0.5 px.
// The refinement fits straight edges, which the lens bends by under 0.01 px across a tag here.
TEST(CoverageRenderer, CornersThroughALensAreUnbiased) {
  const auto rig = loadRig(std::string(MVIS_SOURCE_DIR) + "/config/sim_vi_rig");
  ASSERT_TRUE(rig.ok());
  const Camera& camera = rig.value().cameras[1];
  const auto detector = boardDetector();
  AprilGrid grid;
  grid.tag_cols = grid.tag_rows = 6;
  grid.tag_size = 0.088;
  grid.tag_spacing = 0.3;
  double outward = 0.0, sum_sq = 0.0;
  int corners = 0;
  std::uint32_t seed = 1;
  for (const SE3& T : views()) {
    const auto project = [&](const Eigen::Vector3d& p_board, Eigen::Vector2d* pixel) {
      return projectToPixel(camera, T * p_board, pixel);
    };
    CoverageOptions options;
    options.blur_sigma = 0.5;
    options.subdivisions = 4;
    options.seed = seed++;
    const auto image = renderByCoverage(
        grid,
        [&](const Eigen::Vector2d& b, Eigen::Vector2d* pixel) {
          return project(Eigen::Vector3d(b.x(), b.y(), 0.0), pixel);
        },
        options);
    ASSERT_TRUE(image.ok());
    const auto found = detector->detect(image.value());
    ASSERT_TRUE(found.ok());
    for (const auto& tag : found.value()) {
      ASSERT_TRUE(tag.tag_id >= 0 && tag.tag_id < 36);
      Eigen::Vector2d truth[4], centre = Eigen::Vector2d::Zero();
      for (int c = 0; c < 4; ++c) {
        ASSERT_TRUE(project(grid.corner(tag.tag_id, c), &truth[c]));
        centre += 0.25 * truth[c];
      }
      for (int c = 0; c < 4; ++c) {
        const Eigen::Vector2d error = tag.corners_px[c] - truth[c];
        outward += error.dot((truth[c] - centre).normalized());
        sum_sq += error.squaredNorm();
        ++corners;
      }
    }
  }
  const double mean = outward / corners, rms = std::sqrt(sum_sq / corners);
  std::printf("through cam1's lens: %d corners, outward %+.4f px, RMS %.4f px\n", corners, mean,
              rms);
  EXPECT_GE(corners, 800);  // of 864: cam1's narrower view cuts a few tags off (measured 812)
  EXPECT_LT(std::abs(mean), 0.005);  // measured +0.0034
  EXPECT_LT(rms, 0.06);              // measured 0.034
}

// The same on images made by exact area coverage (coverage_renderer.h: no sampling, no code or
// tag patterns shared with mvis), across what cameras do to edges: blur, a gamma response,
// vignetting, and tags at two sizes (cells of ~5.5 px at 0.9 m, ~2.7 px at 1.8 m; Kalibr's
// ~4.4 and ~2.2 px). Each case states the bound it is held to: 0.005 px of outward bias where
// the corners are unbiased (the mean over ~860 corners; its noise is ~0.001-0.003 px), and where
// they are not (doc/results.md's table), a bound just above what they do now, so that it cannot
// get worse unnoticed:
// - plain tags under a gamma response: every edge moves into the black (0.1 px without blur,
//   0.55 px at 1.5 px of blur) and the sides are moved back by what the tags' stripes show,
//   all of it up to 0.5 px of blur, two thirds at 1 px, half at 1.5 px; Kalibr's junctions
//   do not move;
// - cells under ~3 px: edges and junctions alike lose their windows' room (Kalibr's inward
//   0.02-0.05 px; plain tags', 0.01-0.04 px, taken back by the stripes).
struct CoverageCase {
  BoardKind kind;
  double blur, gamma, vignetting, distance;
  double max_outward;  // bound on |mean outward error| [px]
  int min_tags;        // of 216
};

class CoverageAccuracy : public ::testing::TestWithParam<CoverageCase> {};

TEST_P(CoverageAccuracy, IsUnbiasedWhereCellsAreWideAndTheResponseLinear) {
  const CoverageCase c = GetParam();
  const auto detector = boardDetector();
  Errors e;
  std::uint32_t seed = 1;
  // The views above, moved back along the camera's axis to `distance`.
  const SE3 back =
      test::viewOfBoard(0.0, 0.0, c.distance) * test::viewOfBoard(0.0, 0.0, 0.9).inverse();
  for (const SE3& T0 : views()) {
    test::BoardView view;
    view.grid.tag_cols = view.grid.tag_rows = 6;
    view.grid.tag_size = 0.088;
    view.grid.tag_spacing = 0.3;
    view.kind = c.kind;
    view.T_cam_board = back * T0;
    CoverageOptions options;
    options.kalibr_squares = c.kind == BoardKind::kKalibrGrid;
    options.blur_sigma = c.blur;
    options.gamma = c.gamma;
    options.vignetting = c.vignetting;
    options.seed = seed++;
    const auto image = renderByCoverage(
        view.grid,
        [&view](const Eigen::Vector2d& board, Eigen::Vector2d* pixel) {
          *pixel = projectPinhole(view.intrinsics, view.T_cam_board,
                                  Eigen::Vector3d(board.x(), board.y(), 0.0));
          return true;
        },
        options);
    ASSERT_TRUE(image.ok());
    view.image = image.value();
    const auto found = detector->detect(view.image);
    ASSERT_TRUE(found.ok());
    measure(view, found.value(), &e);
  }
  std::printf(
      "coverage %-6s blur %.1f gamma %.1f vignetting %.1f at %.1f m: %d tags, outward "
      "%+.4f px, RMS %.4f px, max %.3f px\n",
      c.kind == BoardKind::kPlain ? "plain" : "kalibr", c.blur, c.gamma, c.vignetting, c.distance,
      e.tags, e.outward(), e.rms(), e.max);
  EXPECT_EQ(e.wrong_ids, 0);
  EXPECT_GE(e.tags, c.min_tags);
  EXPECT_LT(std::abs(e.outward()), c.max_outward);
}

std::vector<CoverageCase> coverageCases() {
  constexpr auto kPlain = BoardKind::kPlain;
  constexpr auto kKalibr = BoardKind::kKalibrGrid;
  return {
      // kind, blur, gamma, vignetting, distance, bound, tags
      {kPlain, 0.0, 1.0, 0.0, 0.9, 0.005, 216},
      {kPlain, 0.5, 1.0, 0.0, 0.9, 0.005, 216},
      {kPlain, 1.0, 1.0, 0.0, 0.9, 0.005, 216},
      {kPlain, 1.5, 1.0, 0.0, 0.9, 0.01, 215},
      {kPlain, 0.5, 1.0, 0.4, 0.9, 0.005, 216},
      {kKalibr, 0.0, 1.0, 0.0, 0.9, 0.005, 216},
      {kKalibr, 0.5, 1.0, 0.0, 0.9, 0.005, 216},
      {kKalibr, 1.0, 1.0, 0.0, 0.9, 0.005, 216},
      {kKalibr, 1.5, 1.0, 0.0, 0.9, 0.006, 216},
      {kKalibr, 0.5, 1.0, 0.4, 0.9, 0.005, 216},
      {kKalibr, 0.0, 2.2, 0.0, 0.9, 0.005, 216},
      {kKalibr, 0.5, 2.2, 0.0, 0.9, 0.005, 216},
      {kKalibr, 1.0, 2.2, 0.0, 0.9, 0.005, 216},
      // Plain tags under gamma: the edges moved into the black, the sides moved back by what
      // the tags' stripes show (measureEdgeShift): two thirds of it at 1 px of blur, half at 1.5.
      {kPlain, 0.0, 2.2, 0.0, 0.9, 0.01, 216},
      {kPlain, 0.5, 2.2, 0.0, 0.9, 0.02, 216},
      {kPlain, 1.0, 2.2, 0.0, 0.9, 0.15, 216},
      {kPlain, 1.5, 2.2, 0.0, 0.9, 0.3, 215},
      // Small cells.
      {kPlain, 0.5, 1.0, 0.0, 1.8, 0.007, 216},
      {kPlain, 1.0, 1.0, 0.0, 1.8, 0.007, 216},
      {kKalibr, 0.0, 1.0, 0.0, 1.8, 0.03, 216},
      {kKalibr, 0.5, 1.0, 0.0, 1.8, 0.065, 216},
      {kKalibr, 1.5, 2.2, 0.0, 0.9, 0.065, 212},
  };
}

INSTANTIATE_TEST_SUITE_P(Coverage, CoverageAccuracy, ::testing::ValuesIn(coverageCases()));

}  // namespace
}  // namespace mvis
