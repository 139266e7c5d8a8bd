// Residual statistics per sensor, for the report (report.h): a camera's corner errors in pixels
// (RMS, median, largest) and every sensor's whitened chi-square per residual. Online they are
// the residuals of each window state's factors at the estimate it had when it left the window
// (its last solve), plus the window's at the time asked; after a batch, the batch's at its
// solution.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace mvis {

struct SensorResidualStatistics {
  std::string sensor;  // its name
  std::string kind;    // "camera", "base IMU", "auxiliary IMU", "gyroscope"
  long factors = 0;
  long residuals = 0;       // scalar residuals
  double chi_square = 0.0;  // sum of squared whitened residuals (a corner loss undone)
  // Cameras: every corner's error |projected - detected| [px], before the robust loss.
  long corners = 0;
  double corner_sum_sq = 0.0;  // [px^2]
  double corner_max = 0.0;     // [px]
  static constexpr double kBinPx = 0.01;
  std::array<std::uint32_t, 2001> corner_histogram{};  // kBinPx bins; the last: beyond 20 px

  void addCorner(double error_px);
  double cornerRms() const;     // [px]; 0 without corners
  double cornerMedian() const;  // [px], to kBinPx (the upper edge of its bin)
  double chiSquarePerResidual() const;
};

struct ResidualStatistics {
  std::vector<SensorResidualStatistics> sensors;  // cameras, then the inertial sensors
};

}  // namespace mvis
