// The result directory users get (doc/formats.md): the calibration in the input format
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

// A batch's residuals into `dir` (scripts/evaluate reads them): corner_residuals.csv, one row
// per corner: stamp (its window state, base clock [s]), camera (name), the board point
// x, y, z [m] (nan without a board; then `corner` is its index 0-3 in its tag), the detected
// u, v, the residual du, dv = projected - detected [px] before the robust loss, and the pixel
// sigma the batch weighed it with;
// inertial_residuals.csv, one row per inertial factor: stamp, sensor, residuals (its size),
// chi_square (whitened); with the clustered covariance calibration_model.csv, calibration.csv's
// row with the model's standard deviations (the inverse information's) at `stamp_ns`.
Status writeBatchResiduals(const std::string& dir, const Rig& rig, const BatchSummary& batch,
                           TimeNs stamp_ns);

}  // namespace mvis
