// report.md, the page of a result directory a person reads first (doc/formats.md):
// every calibrated quantity with its sigma and its change from the initial guess (in sigmas),
// residual statistics per sensor, what was held and why, warnings, declared changes and
// provenance. Written by mvis_offline and by the nodelet beside the calibration files.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "mvis/common/status.h"
#include "mvis/estimator/calibration_status.h"
#include "mvis/estimator/estimator.h"
#include "mvis/estimator/residual_statistics.h"
#include "mvis/rig/rig.h"

namespace mvis {

struct ReportInputs {
  std::string tool;     // who wrote it: "mvis_offline", "mvis nodelet /mvis"
  std::string source;   // the data: "bag imu_april.bag", "live topics"
  std::string pass;     // "online (sliding window)" or "batch over the recording"
  std::string written;  // when (UTC), or empty (mvis_offline: the same bytes for the same input)
  TimeNs first_ns = 0, last_ns = 0;  // the estimated states' span (base clock)
  const Rig* initial = nullptr;      // the configuration it started from
  const Rig* estimate = nullptr;     // with standard deviations
  ResidualStatistics residuals;
  EstimatorOptions options;
  std::vector<std::pair<std::string, std::string>> extra_options;  // e.g. the tag front end's
  std::vector<std::string> unobservable;  // held by the motion at the end, in words
  std::vector<CalibrationChange> changes;
  std::vector<std::string> warnings;  // what went wrong in the data, by kind, with counts
  EstimatorCounters counters;
  double sigma_inflation = 1.0;
  // Guided calibration: each quantity's status at the end and every change of status, with its
  // time [s from the start of the data] (the rig's verdict among them).
  std::vector<QuantityState> statuses;
  std::vector<std::pair<double, QuantityState>> status_timeline;
  std::vector<CameraCoverage> coverage;
};

// The page's Markdown.
std::string renderReport(const ReportInputs& in);
// Writes `dir`/report.md.
Status writeReport(const std::string& dir, const ReportInputs& in);

}  // namespace mvis
