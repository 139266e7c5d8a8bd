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
#include <chrono>
#include <cmath>
#include <map>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "mvis/frontend/corner_refinement.h"
#include "tag_codebook.h"
#include "tag_quads.h"
#include "tag_reading.h"

namespace mvis {
namespace {

// libapriltag 3.3 puts (0, 0) at the top-left corner of the top-left pixel; mvis (OpenCV,
// Kalibr) at its centre. Measured by test_tag_detector on rendered images with known corners.
constexpr double kLibraryToMvisPx = -0.5;
constexpr int kLibraryMinSidePx = 16;

double msSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

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
  if (count < 0) count = static_cast<int>(handle.family->ncodes);
  if (static_cast<std::uint32_t>(count) > handle.family->ncodes) {
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

StatusOr<cv::Mat> grayForDetection(const cv::Mat& image) {
  if (image.empty()) return Status::Error("empty image");
  const int depth = image.depth(), channels = image.channels();
  if ((depth != CV_8U && depth != CV_16U) || (channels != 1 && channels != 3 && channels != 4)) {
    return Status::Error("unsupported image type: " + std::to_string(channels) + " channels of " +
                         (depth == CV_8U    ? "8"
                          : depth == CV_16U ? "16"
                                            : "other") +
                         " bits (expected 8 or 16 bits, 1, 3 or 4 channels)");
  }
  cv::Mat gray;
  if (channels == 1) {
    gray = image;
  } else {
    cv::cvtColor(image, gray, channels == 3 ? cv::COLOR_BGR2GRAY : cv::COLOR_BGRA2GRAY);
  }
  if (depth == CV_16U) {
    double lo = 0.0, hi = 0.0;
    cv::minMaxLoc(gray, &lo, &hi);
    cv::Mat scaled;
    gray.convertTo(scaled, CV_8U, 255.0 / std::max(hi, 1.0));
    return scaled;
  }
  return gray;
}

struct TagDetector::Impl {
  std::optional<TagCodebook> codebook;  // the family's words, when it has them
  bool own_engine = false;              // mvis's quads and decoder; else libapriltag's
  FamilyFunctions functions{};
  apriltag_family_t* family = nullptr;
  apriltag_detector_t* detector = nullptr;

  // Tags found, each with its border width in cells (see tag_codebook.h).
  using Found = std::vector<std::pair<TagObservation, int>>;
  Found detectOwn(const cv::Mat& gray, const cv::Rect& region, const TagDetectorOptions& options,
                  TagDetectionStages* stages) const;
  Found detectLibrary(const cv::Mat& gray) const;

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
  if (!(min_contrast >= 1.0 && min_contrast <= 255.0)) return "min_contrast must be in [1, 255]";
  if (!(tag_spacing >= 0.0 && tag_spacing < 10.0)) return "tag_spacing must be in [0, 10)";
  return "";
}

StatusOr<std::unique_ptr<TagDetector>> TagDetector::create(const TagDetectorOptions& options) {
  if (const std::string problem = options.validate(); !problem.empty()) {
    return Status::Error("tag detector: " + problem);
  }
  auto impl = std::make_unique<Impl>();
  if (auto codebook = TagCodebook::create(options.family); codebook.ok()) {
    impl->codebook = std::move(codebook).value();
  }
  impl->own_engine = impl->codebook.has_value() && !options.use_libapriltag;
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
  auto found = find(gray, cv::Rect(0, 0, gray.cols, gray.rows));
  if (!found.ok()) return found.status();
  return refine(gray, std::move(found).value());
}

StatusOr<FoundTags> TagDetector::find(const cv::Mat& gray, const cv::Rect& region) const {
  if (gray.empty() || gray.cols < 1 || gray.rows < 1) return Status::Error("empty image");
  if (gray.type() != CV_8UC1) return Status::Error("expected an 8-bit single-channel image");
  FoundTags out;
  const auto t0 = std::chrono::steady_clock::now();
  Impl::Found found;
  if (impl_->own_engine) {
    found = impl_->detectOwn(gray, region, options_, &out.stages);
  } else {
    found = impl_->detectLibrary(gray);
    out.stages.quads_ms = msSince(t0);
  }
  for (auto& [tag, border] : found) {
    out.tags.push_back(tag);
    out.borders.push_back(border);
  }
  return out;
}

std::vector<TagObservation> TagDetector::refine(const cv::Mat& gray, FoundTags found,
                                                TagDetectionStages* stages) const {
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<TagObservation> tags;
  tags.reserve(found.tags.size());
  // Plain tags refined by their edges, and what their stripes say of the camera's response.
  std::vector<std::size_t> plain;
  std::vector<double> shifts;
  for (std::size_t k = 0; k < found.tags.size(); ++k) {
    TagObservation& tag = found.tags[k];
    const int border = found.borders[k];
    if (options_.refine_corners && impl_->codebook) {
      const TagCodebook& book = *impl_->codebook;
      const int id = tag.tag_id, b = border;
      const int width = book.dataWidth() + 2 * border;
      CornerRefinementOptions refinement;
      // The board's gap is white but for Kalibr's squares at the corners; a lone tag has its
      // one-cell ring.
      refinement.white_outside_cells = std::max(1.0, options_.tag_spacing * width);
      refinement.corner_cells = border == 1;
      refinement.junctions = border == 2;
      refinement.max_shift_px = 2.5;  // from the quad finder's corners, good to ~1 px
      // The junctions need only a start within a pixel; edges alone take three passes under heavy
      // blur.
      refinement.passes = refinement.junctions ? 1 : 3;
      const bool refined = refineTagCorners(
          gray, &tag, width,
          [&book, id, b](int row, int col) { return book.black(id, b, row, col); }, refinement);
      // On a board (tag_spacing set), a tag big enough to refine whose edges cannot be measured
      // (blurred into a neighbour, cut by a shadow) would bring corners a pixel or more off
      // into the calibration: dropped. Smaller ones, and lone tags, keep the found corners.
      double side_px = 1e9;
      for (int c = 0; c < 4; ++c) {
        side_px = std::min(side_px, (tag.corners_px[(c + 1) % 4] - tag.corners_px[c]).norm());
      }
      if (!refined && impl_->own_engine && options_.tag_spacing > 0.0 && side_px / width >= 3.0) {
        continue;
      }
      if (refined && border == 1 && options_.response_correction) {
        EdgeShift shift;
        measureEdgeShift(
            gray, tag, width,
            [&book, id, b](int row, int col) { return book.black(id, b, row, col); }, refinement,
            &shift);
        plain.push_back(tags.size());
        if (shift.count >= 2) shifts.push_back(shift.sum / shift.count);
      }
    }
    tags.push_back(tag);
  }
  // One shift for the image (the response and the blur are the camera's): the median of the
  // tags' own, from at least three tags, where it stands out of its noise (over 3 of its
  // standard errors, from the tags' spread: 1.4826 MAD, times 1.25 / sqrt(n) for a median); every
  // plain tag's sides moved by it. A linear camera's images keep their corners.
  if (shifts.size() >= 3) {
    const std::size_t n = shifts.size();
    std::nth_element(shifts.begin(), shifts.begin() + n / 2, shifts.end());
    const double shift = shifts[n / 2];
    std::vector<double> deviation;
    for (const double v : shifts) deviation.push_back(std::abs(v - shift));
    std::nth_element(deviation.begin(), deviation.begin() + n / 2, deviation.end());
    const double standard_error = 1.25 * 1.4826 * deviation[n / 2] / std::sqrt(double(n));
    if (std::abs(shift) > 3.0 * standard_error) {
      for (const std::size_t k : plain) moveTagSides(&tags[k], shift);
    }
  }
  if (stages) stages->corners_ms = msSince(t0);
  return tags;
}

TagDetector::Impl::Found TagDetector::Impl::detectOwn(const cv::Mat& gray, const cv::Rect& region,
                                                      const TagDetectorOptions& options,
                                                      TagDetectionStages* stages) const {
  const auto t0 = std::chrono::steady_clock::now();
  QuadFinderOptions quad_options;
  quad_options.min_contrast = options.min_contrast;
  std::vector<Quad> quads;
  if (options.decimate > 1.0) {
    cv::Mat small;
    cv::resize(gray, small, cv::Size(), 1.0 / options.decimate, 1.0 / options.decimate,
               cv::INTER_AREA);
    const double fx = static_cast<double>(gray.cols) / small.cols;
    const double fy = static_cast<double>(gray.rows) / small.rows;
    quad_options.min_side_px = std::max(4, static_cast<int>(quad_options.min_side_px / fx));
    const int x0 = static_cast<int>(std::floor(region.x / fx));
    const int y0 = static_cast<int>(std::floor(region.y / fy));
    const int x1 = static_cast<int>(std::ceil((region.x + region.width) / fx));
    const int y1 = static_cast<int>(std::ceil((region.y + region.height) / fy));
    quads = findQuads(small, cv::Rect(x0, y0, x1 - x0, y1 - y0), quad_options);
    for (auto& quad : quads) {
      for (auto& q : quad) q = Eigen::Vector2d((q.x() + 0.5) * fx - 0.5, (q.y() + 0.5) * fy - 0.5);
    }
  } else {
    quads = findQuads(gray, region, quad_options);
  }
  stages->quads_ms = msSince(t0);
  const auto t1 = std::chrono::steady_clock::now();
  TagReadingOptions reading;
  reading.max_hamming = options.max_hamming;
  reading.min_contrast = options.min_contrast;
  Found tags;
  CornerRefinementOptions sharpen;
  sharpen.passes = 1;
  sharpen.min_cell_px = 1.2;
  sharpen.max_shift_px = 2.5;
  // libapriltag's border of one cell, or Kalibr's of two: whichever reads better. A board's
  // tags share theirs: the border of the image's last tag is tried first, and a reading without
  // an error is taken (the other border's grid of cells does not fit such a tag's square).
  int likely_border = 2;
  const auto read = [&](const Quad& quad, int* border) {
    const int first = likely_border, second = 3 - likely_border;
    auto tag = readTag(gray, quad, *codebook, first, reading);
    *border = first;
    if (!tag || tag->hamming > 0) {
      if (auto other = readTag(gray, quad, *codebook, second, reading);
          other && (!tag || other->hamming < tag->hamming ||
                    (other->hamming == tag->hamming && second == 2))) {
        tag = other;
        *border = second;
      }
    }
    if (tag) likely_border = *border;
    return tag;
  };
  for (Quad quad : quads) {
    if (options.decimate > 1.0) {
      // Quads from the smaller image are good to a pixel of it: sharpened at full resolution
      // before anything else (by the edges, as below).
      TagObservation solid;
      solid.corners_px = {quad[3], quad[2], quad[1], quad[0]};
      sharpen.junctions = false;
      if (refineTagCorners(
              gray, &solid, 10, [](int, int) { return true; }, sharpen)) {
        quad = {solid.corners_px[3], solid.corners_px[2], solid.corners_px[1], solid.corners_px[0]};
      }
    }
    int border = 1;
    auto tag = read(quad, &border);
    // Sharper corners, then again: small tags' cells are missed by a rough quad. The edges as if
    // the tag were solid black inside (true of Kalibr's two-cell border, nearly so of one
    // cell), then also the junctions where Kalibr's squares touch the corners.
    for (const bool junctions : {false, true}) {
      if (tag) break;
      TagObservation solid;
      solid.corners_px = {quad[3], quad[2], quad[1], quad[0]};
      sharpen.junctions = junctions;
      if (!refineTagCorners(
              gray, &solid, 10, [](int, int) { return true; }, sharpen)) {
        continue;
      }
      tag =
          read({solid.corners_px[3], solid.corners_px[2], solid.corners_px[1], solid.corners_px[0]},
               &border);
    }
    if (!tag) continue;
    // One id once: a second reading of the same tag (e.g. from a split component) is dropped,
    // the better one kept; two far apart are both kept for the checks to refuse.
    const Eigen::Vector2d centre =
        0.25 * (tag->corners_px[0] + tag->corners_px[1] + tag->corners_px[2] + tag->corners_px[3]);
    const double size = (tag->corners_px[2] - tag->corners_px[0]).norm();
    bool duplicate = false;
    for (auto& [other, other_border] : tags) {
      const Eigen::Vector2d other_centre = 0.25 * (other.corners_px[0] + other.corners_px[1] +
                                                   other.corners_px[2] + other.corners_px[3]);
      if (other.tag_id == tag->tag_id && (other_centre - centre).norm() < 0.5 * size) {
        if (tag->hamming < other.hamming) other = *tag, other_border = border;
        duplicate = true;
      }
    }
    if (!duplicate) tags.emplace_back(*tag, border);
  }
  stages->reading_ms = msSince(t1);
  return tags;
}

TagDetector::Impl::Found TagDetector::Impl::detectLibrary(const cv::Mat& gray) const {
  // libapriltag 3.3 reads past its buffers on tiny images (found by test_fuzz: a segfault in
  // its quad finder); nothing that small holds a tag anyway.
  if (gray.cols < kLibraryMinSidePx || gray.rows < kLibraryMinSidePx) return {};
  image_u8_t image{gray.cols, gray.rows, static_cast<int32_t>(gray.step[0]),
                   const_cast<uint8_t*>(gray.ptr<uint8_t>(0))};
  zarray_t* found = apriltag_detector_detect(detector, &image);
  Found tags;
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
    tags.emplace_back(tag, 1);
  }
  apriltag_detections_destroy(found);
  return tags;
}

}  // namespace mvis
