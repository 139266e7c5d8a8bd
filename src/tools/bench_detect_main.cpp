// mvis_bench_detect [REPEATS]: tag detection time per image on one core, for rendered 6x6
// boards (plain tags and Kalibr AprilGrids, blur 0.5 px, noise sigma 2) at 752x480 and 1280x800,
// mvis's engine at full and half resolution quad search, with and without corner refinement,
// and libapriltag's for comparison (plain boards only: it cannot see AprilGrids). Prints median
// and p99 [ms] over REPEATS detections (default 200) of 8 different views, the tags found per
// image, and the real-time factor of detection for two cameras at 20 Hz (1 / (40 x median)).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "mvis/frontend/tag_detector.h"
#include "mvis/sim/tag_renderer.h"

namespace {

double percentile(std::vector<double> values, double q) {
  std::sort(values.begin(), values.end());
  return values[std::min(values.size() - 1, static_cast<std::size_t>(q * values.size()))];
}

struct Engine {
  const char* name;
  bool libapriltag;
  double decimate;
  bool refine;
};

}  // namespace

int main(int argc, char** argv) {
  const int repeats = argc > 1 ? std::max(8, std::atoi(argv[1])) : 200;
  mvis::AprilGrid grid;
  grid.tag_cols = 6;
  grid.tag_rows = 6;
  grid.tag_size = 0.088;
  grid.tag_spacing = 0.3;
  std::printf("%-10s %-7s %-12s %-8s %-6s %10s %10s %6s %10s\n", "image", "board", "engine",
              "decimate", "refine", "median_ms", "p99_ms", "tags", "rt_2x20Hz");
  for (const auto kind : {mvis::BoardKind::kKalibrGrid, mvis::BoardKind::kPlain}) {
    auto renderer = mvis::TagBoardRenderer::create(grid, kind);
    if (!renderer.ok()) return 1;
    for (const auto& [width, height, focal] :
         std::vector<std::tuple<int, int, double>>{{752, 480, 450.0}, {1280, 800, 760.0}}) {
      std::vector<cv::Mat> images;
      for (int v = 0; v < 8; ++v) {
        Eigen::Matrix3d R;
        R << 1, 0, 0, 0, -1, 0, 0, 0, -1;
        R = mvis::lie::expSO3(Eigen::Vector3d(0.3 * std::cos(v), 0.3 * std::sin(v), 0.1 * v)) * R;
        const Eigen::Vector3d p =
            Eigen::Vector3d(0.3212, 0.3212, 0.0) - (0.85 + 0.05 * v) * R.col(2);
        const Eigen::Vector4d K(focal, focal, 0.5 * (width - 1), 0.5 * (height - 1));
        mvis::RenderOptions options;
        options.noise_sigma = 2.0;
        options.blur_sigma = 0.5;
        options.seed = v + 1;
        images.push_back(renderer.value()->render(
            width, height, mvis::pinholeToBoard(K, mvis::SE3(R, p).inverse()), options));
      }
      std::vector<Engine> engines = {
          {"mvis", false, 1.0, true}, {"mvis", false, 2.0, true}, {"mvis", false, 2.0, false}};
      if (kind == mvis::BoardKind::kPlain) {
        engines.push_back({"libapriltag", true, 2.0, false});
        engines.push_back({"libapriltag", true, 2.0, true});
      }
      for (const Engine& engine : engines) {
        mvis::TagDetectorOptions options;
        options.use_libapriltag = engine.libapriltag;
        options.decimate = engine.decimate;
        options.refine_corners = engine.refine;
        options.tag_spacing = grid.tag_spacing;
        options.threads = 1;
        auto detector = mvis::TagDetector::create(options);
        if (!detector.ok()) return 1;
        std::vector<double> ms;
        std::size_t tags = 0;
        for (int i = 0; i < repeats; ++i) {
          const auto start = std::chrono::steady_clock::now();
          const auto found = detector.value()->detect(images[i % images.size()]);
          ms.push_back(
              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                  .count());
          tags += found.ok() ? found.value().size() : 0;
        }
        char size[16];
        std::snprintf(size, sizeof(size), "%dx%d", width, height);
        const double median = percentile(ms, 0.5);
        std::printf("%-10s %-7s %-12s %-8.0f %-6s %10.2f %10.2f %6.1f %10.1f\n", size,
                    kind == mvis::BoardKind::kPlain ? "plain" : "kalibr", engine.name,
                    engine.decimate, engine.refine ? "yes" : "no", median, percentile(ms, 0.99),
                    static_cast<double>(tags) / repeats, 1000.0 / (40.0 * median));
      }
    }
  }
  return 0;
}
