// mvis_bench_detect [REPEATS]: tag detection time per image on one core, for rendered 6x6
// boards at 752x480 and 1280x800, with and without mvis's corner refinement.
// Prints median and p99 [ms] over REPEATS detections (default 200) of 8 different views.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "mvis/frontend/tag_detector.h"
#include "mvis/sim/tag_renderer.h"

namespace {

double percentile(std::vector<double> values, double q) {
  std::sort(values.begin(), values.end());
  return values[std::min(values.size() - 1, static_cast<std::size_t>(q * values.size()))];
}

}  // namespace

int main(int argc, char** argv) {
  const int repeats = argc > 1 ? std::max(8, std::atoi(argv[1])) : 200;
  mvis::AprilGrid grid;
  grid.tag_cols = 6;
  grid.tag_rows = 6;
  grid.tag_size = 0.088;
  grid.tag_spacing = 0.3;
  auto renderer = mvis::TagBoardRenderer::create(grid);
  if (!renderer.ok()) return 1;
  std::printf("%-10s %-8s %-8s %10s %10s %6s\n", "image", "decimate", "refine", "median_ms",
              "p99_ms", "tags");
  for (const auto& [width, height, focal] :
       std::vector<std::tuple<int, int, double>>{{752, 480, 450.0}, {1280, 800, 760.0}}) {
    std::vector<cv::Mat> images;
    for (int v = 0; v < 8; ++v) {
      Eigen::Matrix3d R;
      R << 1, 0, 0, 0, -1, 0, 0, 0, -1;
      R = mvis::lie::expSO3(Eigen::Vector3d(0.3 * std::cos(v), 0.3 * std::sin(v), 0.1 * v)) * R;
      const Eigen::Vector3d p = Eigen::Vector3d(0.3212, 0.3212, 0.0) - (0.85 + 0.05 * v) * R.col(2);
      const Eigen::Vector4d K(focal, focal, 0.5 * (width - 1), 0.5 * (height - 1));
      mvis::RenderOptions options;
      options.noise_sigma = 2.0;
      options.seed = v + 1;
      images.push_back(renderer.value()->render(
          width, height, mvis::pinholeToBoard(K, mvis::SE3(R, p).inverse()), options));
    }
    for (const auto& [decimate, refine] : std::vector<std::pair<double, bool>>{
             {1.0, false}, {1.0, true}, {2.0, false}, {2.0, true}}) {
      mvis::TagDetectorOptions options;
      options.decimate = decimate;
      options.refine_corners = refine;
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
      std::printf("%-10s %-8.0f %-8s %10.2f %10.2f %6.1f\n", size, decimate,
                  refine ? "mvis" : "off", percentile(ms, 0.5), percentile(ms, 0.99),
                  static_cast<double>(tags) / repeats);
    }
  }
  return 0;
}
