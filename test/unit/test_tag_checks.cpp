// Each rejection rule of checkTagFrame, on hand-made observations.
#include <gtest/gtest.h>

#include <limits>

#include "mvis/frontend/tag_checks.h"

namespace mvis {
namespace {

// An upright 40 px square tag with its bottom-left corner at (u, v) (image y grows downwards,
// so the tag's bottom is the larger v).
TagObservation square(int id, double u, double v, double side = 40.0) {
  TagObservation tag;
  tag.tag_id = id;
  tag.corners_px = {Eigen::Vector2d(u, v), Eigen::Vector2d(u + side, v),
                    Eigen::Vector2d(u + side, v - side), Eigen::Vector2d(u, v - side)};
  return tag;
}

TagFrame frameOf(std::vector<TagObservation> tags) {
  TagFrame frame;
  frame.width = 752;
  frame.height = 480;
  frame.tags = std::move(tags);
  return frame;
}

TagCheckOptions boardOf36() {
  TagCheckOptions options;
  options.num_board_tags = 36;
  return options;
}

TEST(TagChecks, KeepsGoodTags) {
  TagFrame frame = frameOf({square(0, 100, 200), square(35, 300, 200)});
  TagRejections rejected;
  checkTagFrame(&frame, boardOf36(), &rejected);
  EXPECT_EQ(frame.tags.size(), 2u);
  EXPECT_EQ(rejected.total(), 0);
  EXPECT_EQ(rejected.describe(), "");
}

TEST(TagChecks, RejectsNonFiniteCorners) {
  TagObservation bad = square(1, 100, 200);
  bad.corners_px[2].x() = std::numeric_limits<double>::quiet_NaN();
  TagObservation worse = square(2, 200, 200);
  worse.corners_px[0].y() = std::numeric_limits<double>::infinity();
  TagFrame frame = frameOf({bad, worse, square(3, 300, 200)});
  TagRejections rejected;
  checkTagFrame(&frame, boardOf36(), &rejected);
  ASSERT_EQ(frame.tags.size(), 1u);
  EXPECT_EQ(frame.tags[0].tag_id, 3);
  EXPECT_EQ(rejected.non_finite, 2);
  EXPECT_EQ(rejected.describe(), "2 with NaN or inf corners");
}

TEST(TagChecks, RejectsCornersOutsideTheImage) {
  // Pixel edges lie at -0.5 and size - 0.5: a corner at -0.4 is inside, at -0.6 outside.
  TagFrame frame = frameOf({square(1, -0.4, 100), square(2, -0.6, 100), square(3, 711.4, 100),
                            square(4, 711.6, 100), square(5, 100, 479.6)});
  TagRejections rejected;
  checkTagFrame(&frame, boardOf36(), &rejected);
  ASSERT_EQ(frame.tags.size(), 2u);
  EXPECT_EQ(frame.tags[0].tag_id, 1);
  EXPECT_EQ(frame.tags[1].tag_id, 3);
  EXPECT_EQ(rejected.outside, 3);
}

TEST(TagChecks, RejectsIdsNotOnTheBoard) {
  TagFrame frame = frameOf({square(36, 100, 200), square(-1, 200, 200), square(7, 300, 200)});
  TagRejections rejected;
  checkTagFrame(&frame, boardOf36(), &rejected);
  ASSERT_EQ(frame.tags.size(), 1u);
  EXPECT_EQ(rejected.unknown_id, 2);
  // Without a board any non-negative id is fine.
  TagFrame landmarks = frameOf({square(36, 100, 200), square(500, 200, 200)});
  TagRejections none;
  checkTagFrame(&landmarks, TagCheckOptions(), &none);
  EXPECT_EQ(landmarks.tags.size(), 2u);
}

TEST(TagChecks, RejectsTooManyCorrectedBits) {
  TagObservation two_bits = square(4, 100, 200);
  two_bits.hamming = 2;
  TagFrame frame = frameOf({two_bits, square(5, 200, 200)});
  TagRejections rejected;
  checkTagFrame(&frame, boardOf36(), &rejected);  // max_hamming 1
  EXPECT_EQ(frame.tags.size(), 1u);
  EXPECT_EQ(rejected.hamming, 1);
}

TEST(TagChecks, RejectsDegenerateQuads) {
  TagObservation crossed = square(1, 100, 200);
  std::swap(crossed.corners_px[1], crossed.corners_px[2]);  // a bow tie, not convex
  TagObservation tiny = square(2, 200, 200, 5.0);           // sides below 6 px
  TagObservation sliver = square(3, 300, 200);
  sliver.corners_px[3] = Eigen::Vector2d(340, 195);  // a 7 degree interior angle at corner 0
  TagFrame frame = frameOf({crossed, tiny, sliver, square(4, 400, 200)});
  TagRejections rejected;
  checkTagFrame(&frame, boardOf36(), &rejected);
  ASSERT_EQ(frame.tags.size(), 1u);
  EXPECT_EQ(frame.tags[0].tag_id, 4);
  EXPECT_EQ(rejected.degenerate, 3);
}

TEST(TagChecks, DropsEveryCopyOfADuplicatedId) {
  TagFrame frame = frameOf({square(9, 100, 200), square(9, 300, 200), square(10, 500, 200)});
  TagRejections rejected;
  checkTagFrame(&frame, boardOf36(), &rejected);
  ASSERT_EQ(frame.tags.size(), 1u);
  EXPECT_EQ(frame.tags[0].tag_id, 10);
  EXPECT_EQ(rejected.duplicate, 2);
  EXPECT_EQ(rejected.describe(), "2 duplicated ids");
}

TEST(TagChecks, ValidatesOptions) {
  TagCheckOptions options;
  EXPECT_EQ(options.validate(), "");
  options.num_board_tags = 0;
  EXPECT_EQ(options.validate(), "num_board_tags must be -1 or positive");
  options = TagCheckOptions();
  options.min_angle_deg = 95.0;
  EXPECT_EQ(options.validate(), "min_angle_deg must be in [0, 90)");
}

}  // namespace
}  // namespace mvis
