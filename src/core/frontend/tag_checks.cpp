#include "mvis/frontend/tag_checks.h"

#include <cmath>
#include <map>

namespace mvis {
namespace {

bool finiteCorners(const TagObservation& tag) {
  for (const auto& c : tag.corners_px) {
    if (!c.allFinite()) return false;
  }
  return true;
}

bool insideImage(const TagObservation& tag, int width, int height) {
  // Pixel centres run from 0 to size - 1; pixel edges half a pixel further out.
  for (const auto& c : tag.corners_px) {
    if (c.x() < -0.5 || c.y() < -0.5 || c.x() > width - 0.5 || c.y() > height - 0.5) return false;
  }
  return true;
}

// Convex, every side long enough, every interior angle away from 0 and 180 degrees.
bool wellShaped(const TagObservation& tag, double min_side_px, double min_angle_deg) {
  const double cos_limit = std::cos(min_angle_deg * M_PI / 180.0);
  int sign = 0;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d& prev = tag.corners_px[(i + 3) % 4];
    const Eigen::Vector2d& here = tag.corners_px[i];
    const Eigen::Vector2d& next = tag.corners_px[(i + 1) % 4];
    const Eigen::Vector2d a = prev - here, b = next - here;
    if (b.norm() < min_side_px) return false;
    const double cross = a.x() * b.y() - a.y() * b.x();
    const int s = cross > 0.0 ? 1 : (cross < 0.0 ? -1 : 0);
    if (s == 0 || (sign != 0 && s != sign)) return false;
    sign = s;
    const double cos_angle = a.dot(b) / (a.norm() * b.norm());
    if (std::abs(cos_angle) > cos_limit) return false;
  }
  return true;
}

}  // namespace

std::string TagCheckOptions::validate() const {
  if (num_board_tags == 0 || num_board_tags < -1) return "num_board_tags must be -1 or positive";
  if (max_hamming < 0 || max_hamming > 3) return "max_hamming must be in [0, 3]";
  if (!(min_side_px >= 0.0)) return "min_side_px must not be negative";
  if (!(min_angle_deg >= 0.0 && min_angle_deg < 90.0)) return "min_angle_deg must be in [0, 90)";
  return "";
}

std::string TagRejections::describe() const {
  std::string text;
  const auto add = [&text](int count, const char* what) {
    if (count == 0) return;
    text += (text.empty() ? "" : ", ") + std::to_string(count) + " " + what;
  };
  add(non_finite, "with NaN or inf corners");
  add(outside, "outside the image");
  add(unknown_id, "with an id not on the board");
  add(hamming, "with too many corrected bits");
  add(degenerate, "degenerate");
  add(duplicate, "duplicated ids");
  return text;
}

void checkTagFrame(TagFrame* frame, const TagCheckOptions& options, TagRejections* rejections) {
  std::vector<TagObservation> kept;
  kept.reserve(frame->tags.size());
  for (auto& tag : frame->tags) {
    if (!finiteCorners(tag)) {
      ++rejections->non_finite;
    } else if (!insideImage(tag, frame->width, frame->height)) {
      ++rejections->outside;
    } else if (tag.tag_id < 0 ||
               (options.num_board_tags > 0 && tag.tag_id >= options.num_board_tags)) {
      ++rejections->unknown_id;
    } else if (tag.hamming > options.max_hamming) {
      ++rejections->hamming;
    } else if (!wellShaped(tag, options.min_side_px, options.min_angle_deg)) {
      ++rejections->degenerate;
    } else {
      kept.push_back(std::move(tag));
    }
  }
  // On a board every id exists once: two copies mean at least one is wrong, and we cannot tell
  // which. Without a board (landmarks) the same rule holds, ids being unique in a scene.
  std::map<int, int> count;
  for (const auto& tag : kept) ++count[tag.tag_id];
  frame->tags.clear();
  for (auto& tag : kept) {
    if (options.reject_duplicates && count[tag.tag_id] > 1) {
      ++rejections->duplicate;
    } else {
      frame->tags.push_back(std::move(tag));
    }
  }
}

}  // namespace mvis
