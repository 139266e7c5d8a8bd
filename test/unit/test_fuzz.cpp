// Seeded fuzzing of what reaches the core from outside: configuration files (mutated example
// files through every parser), images (noise, odd sizes, real and rendered boards damaged at
// random) through the tag detectors, and tag observations (NaN, huge, repeated) through the
// checks and the front end. Nothing may crash or hang; every refusal of a file names the file
// (the "FILE: KEY: problem" convention); every tag that comes out has finite corners near the
// image, a valid id, and (after the checks) lies inside the image on the board.
// MVIS_FUZZ_CASES sets the number of cases per test (scripts/fuzz: 100,000).
#include <gtest/gtest.h>

#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "fuzz_util.h"
#include "mvis/frontend/tag_checks.h"
#include "mvis/frontend/tag_detector.h"
#include "mvis/frontend/tag_frontend.h"
#include "mvis/rig/rig_io.h"
#include "mvis/sim/simulation_config.h"

namespace mvis {
namespace {

const std::string kRoot = std::string(MVIS_SOURCE_DIR) + "/";

std::string readText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

TEST(Fuzz, ConfigurationFilesAreParsedOrRefusedByName) {
  struct Seed {
    std::string path;
    int kind;  // 0 imu chain, 1 cam chain, 2 aprilgrid, 3 sim.yaml
  };
  const std::vector<Seed> seeds = {
      {"config/sim_vi_rig/kalibr_imu_chain.yaml", 0},
      {"config/sim_vi_rig/kalibr_imucam_chain.yaml", 1},
      {"config/sim_vi_rig/aprilgrid.yaml", 2},
      {"config/sim_vi_rig/sim.yaml", 3},
      {"test/data/formats/kalibr_results/imu-rig.yaml", 0},
      {"test/data/formats/kalibr_results/camchain-imucam-rig.yaml", 1},
      {"test/data/formats/openvins_euroc/kalibr_imu_chain.yaml", 0},
      {"test/data/formats/openvins_euroc/kalibr_imucam_chain.yaml", 1},
      {"test/data/real_aprilgrid/aprilgrid.yaml", 2},
  };
  std::vector<std::string> texts;
  for (const auto& seed : seeds) {
    texts.push_back(readText(kRoot + seed.path));
    ASSERT_FALSE(texts.back().empty()) << seed.path;
  }
  std::mt19937 rng(20261124);
  const int n = fuzz::cases(3000);
  int accepted = 0, refused = 0;
  for (int i = 0; i < n; ++i) {
    const std::size_t s = i % seeds.size();
    const std::string text = fuzz::mutate(texts[s], rng);
    const std::string path = "fuzz/" + seeds[s].path;
    Status status = Status::Ok();
    std::vector<std::string> warnings;
    switch (seeds[s].kind) {
      case 0:
        status = parseImuChain(text, path, &warnings).status();
        break;
      case 1:
        status = parseCamChain(text, path, &warnings).status();
        break;
      case 2:
        status = parseAprilGrid(text, path).status();
        break;
      default:
        status = parseSimulationConfig(text, path, 3).status();
        break;
    }
    if (status.ok()) {
      ++accepted;
      continue;
    }
    ++refused;
    EXPECT_EQ(status.message().rfind(path, 0), 0u)
        << "case " << i << ": the refusal does not name the file: " << status.message();
  }
  std::printf("%d mutated configuration files: %d accepted, %d refused by name\n", n, accepted,
              refused);
  EXPECT_GT(refused, n / 10);  // the mutations do break files
}

void expectSane(const std::vector<TagObservation>& tags, const cv::Mat& image, int num_codes,
                const std::string& what) {
  for (const auto& tag : tags) {
    EXPECT_GE(tag.tag_id, 0) << what;
    EXPECT_LT(tag.tag_id, num_codes) << what;
    for (const auto& c : tag.corners_px) {
      ASSERT_TRUE(c.allFinite()) << what;
      EXPECT_GT(c.x(), -10.0) << what;
      EXPECT_GT(c.y(), -10.0) << what;
      EXPECT_LT(c.x(), image.cols + 10.0) << what;
      EXPECT_LT(c.y(), image.rows + 10.0) << what;
    }
  }
}

TEST(Fuzz, ImagesNeverBreakTheDetectors) {
  TagDetectorOptions grid_options;
  grid_options.tag_spacing = 0.3;
  const auto mvis_detector = TagDetector::create(grid_options).value();
  TagDetectorOptions library_options;
  library_options.use_libapriltag = true;
  const auto library_detector = TagDetector::create(library_options).value();
  const cv::Mat euroc = cv::imread(kRoot + "test/data/real_aprilgrid/cam0_1403709395937837056.png",
                                   cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(euroc.empty());
  std::mt19937 rng(7);
  const auto uniform = [&](int lo, int hi) {
    return std::uniform_int_distribution<int>(lo, hi)(rng);
  };
  const int n = fuzz::cases(600);
  int tags = 0;
  for (int i = 0; i < n; ++i) {
    cv::Mat image;
    switch (i % 4) {
      case 0: {  // noise of any size, down to one pixel
        image.create(uniform(1, 120), uniform(1, 120), CV_8UC1);
        cv::randu(image, 0, 256);
        break;
      }
      case 1: {  // blocks: quads everywhere, almost none a tag
        image.create(uniform(8, 200), uniform(8, 200), CV_8UC1);
        image.setTo(uniform(0, 255));
        for (int k = uniform(0, 30); k > 0; --k) {
          cv::rectangle(image, cv::Point(uniform(-20, image.cols), uniform(-20, image.rows)),
                        cv::Point(uniform(0, image.cols + 20), uniform(0, image.rows + 20)),
                        cv::Scalar(uniform(0, 255)), uniform(-1, 3));
        }
        break;
      }
      default: {  // a real board cut, scaled, damaged
        const cv::Rect roi(uniform(0, euroc.cols - 40), uniform(0, euroc.rows - 40),
                           uniform(20, 400), uniform(20, 300));
        image = euroc(roi & cv::Rect(0, 0, euroc.cols, euroc.rows)).clone();
        if (uniform(0, 1)) {
          cv::resize(image, image, cv::Size(), 0.3 + 0.1 * uniform(0, 10),
                     0.3 + 0.1 * uniform(0, 10));
        }
        for (int k = uniform(0, 20); k > 0; --k) {
          const cv::Point p(uniform(0, image.cols), uniform(0, image.rows));
          cv::circle(image, p, uniform(0, 6), cv::Scalar(uniform(0, 1) * 255), -1);
        }
        image.convertTo(image, CV_8U, 0.2 + 0.2 * uniform(0, 6), uniform(-100, 100));
        break;
      }
    }
    const std::string what = "case " + std::to_string(i) + " (" + std::to_string(image.cols) + "x" +
                             std::to_string(image.rows) + ")";
    const auto found = mvis_detector->detect(image);
    ASSERT_TRUE(found.ok()) << what << ": " << found.status().message();
    expectSane(found.value(), image, 587, what);
    tags += static_cast<int>(found.value().size());
    if (i % 10 == 0) {
      const auto library = library_detector->detect(image);
      ASSERT_TRUE(library.ok()) << what;
      expectSane(library.value(), image, 587, what);
    }
  }
  std::printf("%d fuzzed images: %d tags found, every one sane\n", n, tags);
}

TEST(Fuzz, HostileDetectionsAreCheckedOut) {
  const Rig rig = loadRig(kRoot + "config/sim_vi_rig").value();
  auto frontend = TagFrontend::create(rig, TagFrontendOptions()).value();
  std::mt19937 rng(11);
  const std::vector<double> hostile = {std::nan(""), INFINITY, -INFINITY, 1e300,
                                       -1e300,       -0.5,     1e-310,    0.0};
  const auto pick = [&](int n) { return std::uniform_int_distribution<int>(0, n - 1)(rng); };
  const int n = fuzz::cases(3000);
  int kept = 0;
  TimeNs stamp = 1;
  for (int i = 0; i < n; ++i) {
    TagFrame frame;
    frame.camera = pick(4);  // one more than the rig has
    frame.stamp_ns = pick(10) == 0 ? -stamp : stamp;
    stamp += pick(3) == 0 ? -1000 : 33000000;
    for (int t = pick(40); t > 0; --t) {
      TagObservation tag;
      tag.tag_id = pick(8) == 0 ? pick(2000) - 100 : pick(36);
      tag.hamming = pick(5);
      const Eigen::Vector2d centre(pick(900) - 50, pick(700) - 50);
      for (int c = 0; c < 4; ++c) {
        tag.corners_px[c] = centre + Eigen::Vector2d(c == 1 || c == 2 ? 20 : 0, c >= 2 ? -20 : 0);
        if (pick(20) == 0) tag.corners_px[c].x() = hostile[pick(hostile.size())];
        if (pick(20) == 0) tag.corners_px[c].y() = hostile[pick(hostile.size())];
      }
      frame.tags.push_back(tag);
    }
    const auto result = frontend->processDetections(frame);
    if (!result.ok()) continue;  // a camera the rig does not have
    const auto& checked = result.value().frame;
    for (const auto& tag : checked.tags) {
      ++kept;
      EXPECT_GE(tag.tag_id, 0);
      EXPECT_LT(tag.tag_id, 36);
      EXPECT_LE(tag.hamming, 1);
      for (const auto& c : tag.corners_px) {
        ASSERT_TRUE(c.allFinite());
        EXPECT_GE(c.x(), -0.5);
        EXPECT_GE(c.y(), -0.5);
        EXPECT_LE(c.x(), checked.width - 0.5);
        EXPECT_LE(c.y(), checked.height - 0.5);
      }
    }
  }
  std::printf("%d hostile detection frames: %d tags kept, every one on the board and image\n", n,
              kept);
}

}  // namespace
}  // namespace mvis
