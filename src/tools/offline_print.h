// mvis_offline's printing and report (offline_main.cpp).
#pragma once

#include <cstdio>
#include <string>
#include <vector>

#include "mvis/ros/offline.h"

namespace mvis_offline {

void printUsage(std::FILE* out);
// The q-quantile of v (0 when empty).
double percentile(std::vector<double> v, double q);
// The batch's solve and its whitened residuals per sensor.
void printBatch(const mvis::OfflineResult& batch, const mvis::OfflineResult& online);
// report.md for one pass's result directory.
mvis::Status writeReport(const std::string& dir, const mvis::Rig& initial,
                         const mvis::OfflineResult& r, const mvis::OfflineOptions& options,
                         const std::string& bag_path, const char* pass);

}  // namespace mvis_offline
