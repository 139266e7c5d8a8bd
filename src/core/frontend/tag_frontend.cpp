#include "mvis/frontend/tag_frontend.h"

namespace mvis {

TagFrontend::TagFrontend(const Rig& rig, TagFrontendOptions options)
    : options_(std::move(options)), tracks_(rig.cameras.size()) {
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
  if (camera >= detectors_.size()) return Status::Error("no camera " + std::to_string(camera));
  const auto& resolution = resolutions_[camera];
  if (!gray.empty() && (gray.cols != resolution[0] || gray.rows != resolution[1])) {
    return Status::Error("image is " + std::to_string(gray.cols) + "x" + std::to_string(gray.rows) +
                         ", the camera's resolution is " + std::to_string(resolution[0]) + "x" +
                         std::to_string(resolution[1]));
  }
  auto tags = detectors_[camera]->detect(gray);
  if (!tags.ok()) return tags.status();
  TagFrame frame;
  frame.camera = camera;
  frame.stamp_ns = stamp_ns;
  frame.tags = std::move(tags).value();
  return record(std::move(frame));
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
