// The result directory users get (../shared/interface.md): the calibration in the input format
// with *_std keys (rig_io.h), the trajectory in TUM format (trajectory_io.h) and the estimate
// over time (estimate_log.h). Written by mvis_offline, ~save_calibration and on shutdown.
#pragma once

#include <string>
#include <vector>

#include "mvis/common/status.h"
#include "mvis/estimator/estimator.h"
#include "mvis/rig/estimate_log.h"
#include "mvis/rig/rig.h"

namespace mvis {

// Creates `dir` if needed and writes kalibr_imu_chain.yaml, kalibr_imucam_chain.yaml,
// aprilgrid.yaml (with a board), trajectory.tum, calibration.csv and pose_covariance.csv.
Status writeResultDirectory(const std::string& dir, const Rig& calibration,
                            const std::vector<EstimatorState>& trajectory, const EstimateLog& log);

}  // namespace mvis
