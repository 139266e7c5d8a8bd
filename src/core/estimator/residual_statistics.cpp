#include "mvis/estimator/residual_statistics.h"

#include <algorithm>
#include <cmath>

namespace mvis {

void SensorResidualStatistics::addCorner(double error_px) {
  ++corners;
  corner_sum_sq += error_px * error_px;
  corner_max = std::max(corner_max, error_px);
  const double bin = std::floor(error_px / kBinPx);
  const std::size_t last = corner_histogram.size() - 1;
  ++corner_histogram[bin >= static_cast<double>(last) ? last : static_cast<std::size_t>(bin)];
}

double SensorResidualStatistics::cornerRms() const {
  return corners > 0 ? std::sqrt(corner_sum_sq / static_cast<double>(corners)) : 0.0;
}

double SensorResidualStatistics::cornerMedian() const {
  if (corners == 0) return 0.0;
  const long half = corners / 2;
  long seen = 0;
  for (std::size_t b = 0; b < corner_histogram.size(); ++b) {
    seen += corner_histogram[b];
    if (seen > half) return static_cast<double>(b + 1) * kBinPx;
  }
  return corner_max;
}

double SensorResidualStatistics::chiSquarePerResidual() const {
  return residuals > 0 ? chi_square / static_cast<double>(residuals) : 0.0;
}

}  // namespace mvis
