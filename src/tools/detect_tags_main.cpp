// mvis_detect_tags [--family F] [--no-refine] IMAGE...
// Prints one line per detected tag: FILE ID u0 v0 u1 v1 u2 v2 u3 v3, corners in mvis's pixel
// convention ((0, 0) at the centre of the top-left pixel) and order (bottom-left, bottom-right,
// top-right, top-left of the upright tag). Lets users check what mvis sees of their target.
#include <cstdio>
#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "mvis/frontend/tag_checks.h"
#include "mvis/frontend/tag_detector.h"

namespace {

int usage(const char* message) {
  std::fprintf(stderr,
               "%s\nusage: mvis_detect_tags [--family F] [--no-refine] IMAGE...\n"
               "  --family F    tag family (default tag36h11)\n"
               "  --no-refine   libapriltag's corners without mvis's edge refinement\n",
               message);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  mvis::TagDetectorOptions options;
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--family") == 0) {
      if (++i == argc) return usage("--family needs a value");
      options.family = argv[i];
    } else if (std::strcmp(argv[i], "--no-refine") == 0) {
      options.refine_corners = false;
    } else if (std::strcmp(argv[i], "--help") == 0 || std::strcmp(argv[i], "-h") == 0) {
      return usage("Detects AprilTags and prints their corners.");
    } else {
      files.emplace_back(argv[i]);
    }
  }
  if (files.empty()) return usage("no image given");
  auto detector = mvis::TagDetector::create(options);
  if (!detector.ok()) return usage(detector.status().message().c_str());
  int failures = 0;
  for (const auto& file : files) {
    const cv::Mat image = cv::imread(file, cv::IMREAD_GRAYSCALE);
    if (image.empty()) {
      std::fprintf(stderr, "%s: cannot read the image\n", file.c_str());
      ++failures;
      continue;
    }
    auto found = detector.value()->detect(image);
    if (!found.ok()) {
      std::fprintf(stderr, "%s: %s\n", file.c_str(), found.status().message().c_str());
      ++failures;
      continue;
    }
    mvis::TagFrame frame;
    frame.width = image.cols;
    frame.height = image.rows;
    frame.tags = std::move(found).value();
    mvis::TagCheckOptions checks;
    checks.max_hamming = options.max_hamming;
    checks.reject_duplicates = false;  // show them all; a board would have each id once
    mvis::TagRejections rejected;
    mvis::checkTagFrame(&frame, checks, &rejected);
    for (const auto& tag : frame.tags) {
      std::printf("%s %d", file.c_str(), tag.tag_id);
      for (const auto& c : tag.corners_px) std::printf(" %.3f %.3f", c.x(), c.y());
      std::printf("\n");
    }
    if (rejected.total() > 0) {
      std::fprintf(stderr, "%s: rejected %s\n", file.c_str(), rejected.describe().c_str());
    }
  }
  return failures == 0 ? 0 : 1;
}
