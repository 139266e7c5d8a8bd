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

void ResidualStatistics::add(const ResidualStatistics& other) {
  if (sensors.empty()) {
    *this = other;
    return;
  }
  for (std::size_t k = 0; k < sensors.size() && k < other.sensors.size(); ++k) {
    SensorResidualStatistics& a = sensors[k];
    const SensorResidualStatistics& b = other.sensors[k];
    a.factors += b.factors;
    a.residuals += b.residuals;
    a.chi_square += b.chi_square;
    a.corners += b.corners;
    a.corner_sum_sq += b.corner_sum_sq;
    a.corner_max = std::max(a.corner_max, b.corner_max);
    for (std::size_t i = 0; i < a.corner_histogram.size(); ++i) {
      a.corner_histogram[i] += b.corner_histogram[i];
    }
  }
}

}  // namespace mvis
