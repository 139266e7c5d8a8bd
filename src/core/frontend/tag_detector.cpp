#include "mvis/frontend/tag_detector.h"

#include <apriltag/apriltag.h>
#include <apriltag/common/image_u8.h>
#include <apriltag/tag16h5.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagCircle21h7.h>
#include <apriltag/tagCircle49h12.h>
#include <apriltag/tagCustom48h12.h>
#include <apriltag/tagStandard41h12.h>
#include <apriltag/tagStandard52h13.h>

#include <algorithm>
#include <map>

#include "mvis/frontend/corner_refinement.h"

namespace mvis {
namespace {

// libapriltag 3.3 puts (0, 0) at the top-left corner of the top-left pixel; mvis (OpenCV,
// Kalibr) at its centre. Measured by test_tag_detector on rendered images with known corners.
constexpr double kLibraryToMvisPx = -0.5;

struct FamilyFunctions {
  apriltag_family_t* (*create)();
  void (*destroy)(apriltag_family_t*);
};

const std::map<std::string, FamilyFunctions>& families() {
  static const std::map<std::string, FamilyFunctions> kFamilies = {
      {"tag36h11", {tag36h11_create, tag36h11_destroy}},
      {"tag25h9", {tag25h9_create, tag25h9_destroy}},
      {"tag16h5", {tag16h5_create, tag16h5_destroy}},
      {"tagCircle21h7", {tagCircle21h7_create, tagCircle21h7_destroy}},
      {"tagCircle49h12", {tagCircle49h12_create, tagCircle49h12_destroy}},
      {"tagStandard41h12", {tagStandard41h12_create, tagStandard41h12_destroy}},
      {"tagStandard52h13", {tagStandard52h13_create, tagStandard52h13_destroy}},
      {"tagCustom48h12", {tagCustom48h12_create, tagCustom48h12_destroy}},
  };
  return kFamilies;
}

// A family instance that destroys itself.
struct FamilyHandle {
  FamilyFunctions functions{};
  apriltag_family_t* family = nullptr;
  FamilyHandle() = default;
  FamilyHandle(const FamilyHandle&) = delete;
  FamilyHandle& operator=(const FamilyHandle&) = delete;
  ~FamilyHandle() {
    if (family) functions.destroy(family);
  }
};

}  // namespace

StatusOr<TagPatterns> tagFamilyPatterns(const std::string& family, int count) {
  const auto it = families().find(family);
  if (it == families().end()) return Status::Error("unknown tag family '" + family + "'");
  FamilyHandle handle;
  handle.functions = it->second;
  handle.family = handle.functions.create();
  if (count < 0 || static_cast<std::uint32_t>(count) > handle.family->ncodes) {
    return Status::Error("tag family " + family + " has only " +
                         std::to_string(handle.family->ncodes) + " tags, " + std::to_string(count) +
                         " wanted");
  }
  TagPatterns patterns;
  patterns.total_width = handle.family->total_width;
  patterns.width_at_border = handle.family->width_at_border;
  for (int id = 0; id < count; ++id) {
    image_u8_t* image = apriltag_to_image(handle.family, id);
    std::vector<std::uint8_t> cells;
    cells.reserve(image->width * image->height);
    for (int r = 0; r < image->height; ++r) {
      cells.insert(cells.end(), image->buf + r * image->stride,
                   image->buf + r * image->stride + image->width);
    }
    image_u8_destroy(image);
    patterns.cells.push_back(std::move(cells));
  }
  return patterns;
}

struct TagDetector::Impl {
  FamilyFunctions functions{};
  apriltag_family_t* family = nullptr;
  apriltag_detector_t* detector = nullptr;

  ~Impl() {
    if (detector) apriltag_detector_destroy(detector);
    if (family) functions.destroy(family);
  }
};

std::string TagDetectorOptions::validate() const {
  if (!families().count(family)) return "unknown tag family '" + family + "'";
  if (!(decimate >= 1.0)) return "decimate must be >= 1";
  if (threads < 1) return "threads must be >= 1";
  if (max_hamming < 0 || max_hamming > 2) return "max_hamming must be 0, 1 or 2";
  return "";
}

StatusOr<std::unique_ptr<TagDetector>> TagDetector::create(const TagDetectorOptions& options) {
  if (const std::string problem = options.validate(); !problem.empty()) {
    return Status::Error("tag detector: " + problem);
  }
  auto impl = std::make_unique<Impl>();
  impl->functions = families().at(options.family);
  impl->family = impl->functions.create();
  impl->detector = apriltag_detector_create();
  if (!impl->family || !impl->detector) return Status::Error("tag detector: out of memory");
  // The decoder's tables grow quickly with the bits it may correct; it needs at least the
  // number we accept.
  apriltag_detector_add_family_bits(impl->detector, impl->family, options.max_hamming);
  impl->detector->quad_decimate = static_cast<float>(options.decimate);
  impl->detector->quad_sigma = static_cast<float>(options.blur_sigma);
  impl->detector->refine_edges = options.refine_edges;
  impl->detector->decode_sharpening = options.decode_sharpening;
  impl->detector->nthreads = options.threads;
  return std::unique_ptr<TagDetector>(new TagDetector(options, std::move(impl)));
}

TagDetector::TagDetector(const TagDetectorOptions& options, std::unique_ptr<Impl> impl)
    : options_(options), impl_(std::move(impl)) {}

TagDetector::~TagDetector() = default;

StatusOr<std::vector<TagObservation>> TagDetector::detect(const cv::Mat& gray) const {
  if (gray.empty() || gray.cols < 1 || gray.rows < 1) return Status::Error("empty image");
  if (gray.type() != CV_8UC1) return Status::Error("expected an 8-bit single-channel image");
  image_u8_t image{gray.cols, gray.rows, static_cast<int32_t>(gray.step[0]),
                   const_cast<uint8_t*>(gray.ptr<uint8_t>(0))};
  zarray_t* found = apriltag_detector_detect(impl_->detector, &image);
  std::vector<TagObservation> tags;
  tags.reserve(zarray_size(found));
  for (int i = 0; i < zarray_size(found); ++i) {
    apriltag_detection_t* det = nullptr;
    zarray_get(found, i, &det);
    TagObservation tag;
    tag.tag_id = det->id;
    tag.hamming = det->hamming;
    for (int c = 0; c < 4; ++c) {
      tag.corners_px[c] =
          Eigen::Vector2d(det->p[c][0], det->p[c][1]) + Eigen::Vector2d::Constant(kLibraryToMvisPx);
    }
    if (options_.refine_corners) {
      CornerRefinementOptions refinement;
      refinement.width_at_border = impl_->family->width_at_border;
      refineTagCorners(gray, &tag, refinement);  // keeps the library's corners if it cannot
    }
    tags.push_back(tag);
  }
  apriltag_detections_destroy(found);
  return tags;
}

}  // namespace mvis
