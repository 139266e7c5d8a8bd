// mvis_detect_tags [--family F] [--target aprilgrid.yaml] [--libapriltag] [--no-refine] IMAGE...
// Prints one line per detected tag: FILE ID u0 v0 u1 v1 u2 v2 u3 v3, corners in mvis's pixel
// convention ((0, 0) at the centre of the top-left pixel) and order (bottom-left, bottom-right,
// top-right, top-left of the upright tag). Lets users check what mvis sees of their target.
// Plain tags and Kalibr AprilGrids alike; 8- and 16-bit PNG, colour or grey JPEG.
#include <cstdio>
#include <cstring>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "mvis/frontend/tag_checks.h"
#include "mvis/frontend/tag_detector.h"
#include "mvis/rig/rig_io.h"

namespace {

int usage(const char* message) {
  std::fprintf(stderr,
               "%s\nusage: mvis_detect_tags [--family F] [--target aprilgrid.yaml] [--libapriltag] "
               "[--no-refine] IMAGE...\n"
               "  --family F      tag family (default tag36h11; with --target, the target's)\n"
               "  --target FILE   a Kalibr aprilgrid.yaml: only its board's ids, its tag spacing\n"
               "  --libapriltag   libapriltag's detector (plain tags only) instead of mvis's\n"
               "  --no-refine     the detector's corners without the sub-pixel refinement\n",
               message);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  mvis::TagDetectorOptions options;
  mvis::TagCheckOptions checks;
  checks.reject_duplicates = false;  // show them all; a board would have each id once
  std::string family, target;
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--family") == 0) {
      if (++i == argc) return usage("--family needs a value");
      family = argv[i];
    } else if (std::strcmp(argv[i], "--target") == 0) {
      if (++i == argc) return usage("--target needs a file");
      target = argv[i];
    } else if (std::strcmp(argv[i], "--libapriltag") == 0) {
      options.use_libapriltag = true;
    } else if (std::strcmp(argv[i], "--no-refine") == 0) {
      options.refine_corners = false;
    } else if (std::strcmp(argv[i], "--help") == 0 || std::strcmp(argv[i], "-h") == 0) {
      return usage("Detects AprilTags and prints their corners.");
    } else {
      files.emplace_back(argv[i]);
    }
  }
  if (files.empty()) return usage("no image given");
  if (!target.empty()) {
    std::ifstream in(target);
    if (!in) return usage(("cannot read " + target).c_str());
    std::stringstream text;
    text << in.rdbuf();
    const auto grid = mvis::parseAprilGrid(text.str(), target);
    if (!grid.ok()) return usage(grid.status().message().c_str());
    if (!family.empty() && family != grid.value().tag_family) {
      return usage(
          ("--family " + family + " but " + target + " says " + grid.value().tag_family).c_str());
    }
    options.family = grid.value().tag_family;
    options.tag_spacing = grid.value().tag_spacing;
    checks.num_board_tags = grid.value().numTags();
  } else if (!family.empty()) {
    options.family = family;
  }
  checks.max_hamming = options.max_hamming;
  auto detector = mvis::TagDetector::create(options);
  if (!detector.ok()) return usage(detector.status().message().c_str());
  int failures = 0;
  for (const auto& file : files) {
    const cv::Mat raw = cv::imread(file, cv::IMREAD_UNCHANGED);
    if (raw.empty()) {
      std::fprintf(stderr, "%s: cannot read the image\n", file.c_str());
      ++failures;
      continue;
    }
    auto gray = mvis::grayForDetection(raw);
    auto found = gray.ok() ? detector.value()->detect(gray.value())
                           : mvis::StatusOr<std::vector<mvis::TagObservation>>(gray.status());
    if (!found.ok()) {
      std::fprintf(stderr, "%s: %s\n", file.c_str(), found.status().message().c_str());
      ++failures;
      continue;
    }
    mvis::TagFrame frame;
    frame.width = raw.cols;
    frame.height = raw.rows;
    frame.tags = std::move(found).value();
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
