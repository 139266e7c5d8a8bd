#include "mvis/frontend/tag_frontend.h"

#include <algorithm>
#include <cmath>
#include <optional>

namespace mvis {

std::string TagFrontendOptions::validate() const {
  if (full_search_every < 1) return "full_search_every must be >= 1";
  if (!(max_prediction_gap_s > 0.0)) return "max_prediction_gap_s must be > 0";
  return "";
}

TagPrediction predictTags(const std::vector<TagObservation>& last, TimeNs last_ns,
                          const std::vector<TagObservation>& before, TimeNs before_ns,
                          TimeNs stamp_ns, int width, int height) {
  TagPrediction prediction;
  if (last.empty() || stamp_ns <= last_ns) return prediction;
  // The corners move on as they moved between the two images before (not beyond twice that
  // interval's motion).
  const double ratio =
      before_ns < last_ns
          ? std::min(2.0, static_cast<double>(stamp_ns - last_ns) / (last_ns - before_ns))
          : 0.0;
  double lo_x = 1e18, lo_y = 1e18, hi_x = -1e18, hi_y = -1e18, side = 0.0, motion = 0.0;
  for (const TagObservation& tag : last) {
    const TagObservation* earlier = nullptr;
    for (const TagObservation& other : before) {
      if (other.tag_id == tag.tag_id) earlier = &other;
    }
    TagObservation next = tag;
    bool inside = true;
    for (int c = 0; c < 4; ++c) {
      const Eigen::Vector2d& now = tag.corners_px[c];
      const Eigen::Vector2d step =
          earlier ? Eigen::Vector2d(ratio * (now - earlier->corners_px[c])) : Eigen::Vector2d(0, 0);
      next.corners_px[c] = now + step;
      for (const Eigen::Vector2d& p : {now, next.corners_px[c]}) {
        lo_x = std::min(lo_x, p.x()), hi_x = std::max(hi_x, p.x());
        lo_y = std::min(lo_y, p.y()), hi_y = std::max(hi_y, p.y());
      }
      const Eigen::Vector2d& q = next.corners_px[c];
      inside =
          inside && q.x() >= 2.0 && q.y() >= 2.0 && q.x() <= width - 3.0 && q.y() <= height - 3.0;
      side = std::max(side, (tag.corners_px[(c + 1) % 4] - now).norm());
      motion = std::max(motion, step.norm());
    }
    if (inside) prediction.expected.push_back(next);
  }
  // A tag's side around the box (its white ring and the board's gap, and what a change of
  // scale adds), plus the motion (what a change of speed may add).
  prediction.margin_px = std::max(16.0, side) + motion;
  const double margin = prediction.margin_px;
  const int x0 = std::max(0, static_cast<int>(std::floor(lo_x - margin)));
  const int y0 = std::max(0, static_cast<int>(std::floor(lo_y - margin)));
  const int x1 = std::min(width, static_cast<int>(std::ceil(hi_x + margin)) + 1);
  const int y1 = std::min(height, static_cast<int>(std::ceil(hi_y + margin)) + 1);
  if (x1 <= x0 || y1 <= y0) return TagPrediction{};
  prediction.region = cv::Rect(x0, y0, x1 - x0, y1 - y0);
  return prediction;
}

namespace {

// Whether the tags found in a predicted region bear the prediction out (see
// TagFrontendOptions::full_search_every): a tag predicted inside the box lies at least the
// margin from its border, so a missed one could only have been cut off by the border if the
// tags found are off their predictions by a good part of the margin.
bool predictionHeld(const TagPrediction& prediction, const std::vector<TagObservation>& found) {
  std::size_t missed = 0;
  double error = 0.0;
  for (const TagObservation& expected : prediction.expected) {
    const auto it = std::find_if(found.begin(), found.end(), [&](const TagObservation& t) {
      return t.tag_id == expected.tag_id;
    });
    if (it == found.end()) {
      ++missed;
      continue;
    }
    for (int c = 0; c < 4; ++c) {
      error = std::max(error, (it->corners_px[c] - expected.corners_px[c]).norm());
    }
  }
  if (prediction.expected.empty()) return !found.empty();
  if (2 * missed >= prediction.expected.size()) return false;
  return missed == 0 || error <= 0.5 * prediction.margin_px;
}

}  // namespace

TagFrontend::TagFrontend(const Rig& rig, TagFrontendOptions options)
    : search_(rig.cameras.size()), options_(std::move(options)), tracks_(rig.cameras.size()) {
  for (const auto& camera : rig.cameras) resolutions_.push_back(camera.resolution);
}

StatusOr<std::unique_ptr<TagFrontend>> TagFrontend::create(const Rig& rig,
                                                           TagFrontendOptions options) {
  if (rig.target) {
    options.detector.family = rig.target->tag_family;
    options.detector.tag_spacing = rig.target->tag_spacing;
    options.checks.num_board_tags = rig.target->numTags();
  }
  if (const std::string problem = options.checks.validate(); !problem.empty()) {
    return Status::Error("tag checks: " + problem);
  }
  if (const std::string problem = options.validate(); !problem.empty()) {
    return Status::Error("tag front end: " + problem);
  }
  std::unique_ptr<TagFrontend> frontend(new TagFrontend(rig, options));
  for (std::size_t c = 0; c < rig.cameras.size(); ++c) {
    auto detector = TagDetector::create(options.detector);
    if (!detector.ok()) return detector.status();
    frontend->detectors_.push_back(std::move(detector).value());
  }
  return frontend;
}

StatusOr<TagFrontendResult> TagFrontend::processImage(std::size_t camera, TimeNs stamp_ns,
                                                      const cv::Mat& gray) {
  auto located = locateTags(camera, stamp_ns, gray);
  if (!located.ok()) return located.status();
  return finishImage(camera, gray, std::move(located).value());
}

StatusOr<LocatedTags> TagFrontend::locateTags(std::size_t camera, TimeNs stamp_ns,
                                              const cv::Mat& gray) {
  if (camera >= detectors_.size()) return Status::Error("no camera " + std::to_string(camera));
  const auto& resolution = resolutions_[camera];
  if (!gray.empty() && (gray.cols != resolution[0] || gray.rows != resolution[1])) {
    return Status::Error("image is " + std::to_string(gray.cols) + "x" + std::to_string(gray.rows) +
                         ", the camera's resolution is " + std::to_string(resolution[0]) + "x" +
                         std::to_string(resolution[1]));
  }
  if (gray.empty()) return Status::Error("empty image");
  SearchHistory& history = search_[camera];
  const TagDetector& detector = *detectors_[camera];
  // The predicted region, unless it is time for a whole search.
  TagPrediction prediction;
  const bool recent =
      !history.last.empty() && stamp_ns > history.last_ns &&
      static_cast<double>(stamp_ns - history.last_ns) <= options_.max_prediction_gap_s * 1e9;
  if (recent && history.since_full_search + 1 < options_.full_search_every) {
    prediction = predictTags(history.last, history.last_ns, history.before, history.before_ns,
                             stamp_ns, gray.cols, gray.rows);
  }
  const cv::Rect& region = prediction.region;
  std::optional<StatusOr<FoundTags>> found;
  TagDetectionStages spent;
  if (!region.empty()) {
    found = detector.find(gray, region);
    if (found->ok()) spent = found->value().stages;
    if (found->ok() && !predictionHeld(prediction, found->value().tags)) found.reset();
  }
  LocatedTags located;
  located.stamp_ns = stamp_ns;
  located.predicted_region = found.has_value();
  if (!located.predicted_region) {
    found = detector.find(gray, cv::Rect(0, 0, gray.cols, gray.rows));
    if (found->ok()) {
      spent.quads_ms += found->value().stages.quads_ms;
      spent.reading_ms += found->value().stages.reading_ms;
    }
  }
  if (!found->ok()) return found->status();
  located.found = std::move(*found).value();
  located.found.stages = spent;
  located.searched_fraction =
      located.predicted_region
          ? static_cast<double>(region.area()) / (static_cast<double>(gray.cols) * gray.rows)
          : 1.0;
  history.since_full_search = located.predicted_region ? history.since_full_search + 1 : 0;
  history.before = std::move(history.last);
  history.before_ns = history.last_ns;
  history.last = located.found.tags;
  history.last_ns = stamp_ns;
  return located;
}

StatusOr<TagFrontendResult> TagFrontend::finishImage(std::size_t camera, const cv::Mat& gray,
                                                     LocatedTags located) {
  if (camera >= detectors_.size()) return Status::Error("no camera " + std::to_string(camera));
  TagDetectionStages stages = located.found.stages;
  TagFrame frame;
  frame.camera = camera;
  frame.stamp_ns = located.stamp_ns;
  frame.tags = detectors_[camera]->refine(gray, std::move(located.found), &stages);
  TagFrontendResult result = record(std::move(frame));
  result.predicted_region = located.predicted_region;
  result.stages = stages;
  result.searched_fraction = located.searched_fraction;
  return result;
}

StatusOr<TagFrontendResult> TagFrontend::processDetections(TagFrame frame) {
  if (frame.camera >= resolutions_.size()) {
    return Status::Error("no camera " + std::to_string(frame.camera));
  }
  return record(std::move(frame));
}

TagFrontendResult TagFrontend::record(TagFrame frame) {
  frame.width = resolutions_[frame.camera][0];
  frame.height = resolutions_[frame.camera][1];
  TagFrontendResult result;
  checkTagFrame(&frame, options_.checks, &result.rejections);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    tracks_.add(frame);
  }
  result.frame = std::move(frame);
  return result;
}

TagTracks TagFrontend::tracks() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return tracks_;
}

void TagFrontend::dropBefore(std::size_t camera, TimeNs stamp_ns) {
  std::lock_guard<std::mutex> lock(mutex_);
  tracks_.dropBefore(camera, stamp_ns);
}

}  // namespace mvis
