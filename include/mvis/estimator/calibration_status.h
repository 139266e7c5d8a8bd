// Guided calibration: per calibrated quantity, whether it is done, what is missing and what motion
// would help; and the rig's verdict (../shared/interface.md, calibration_status.csv).
//
// Quantities: per camera its rotation, translation and time offset (the extrinsic T_cam_imu and
// timeshift_cam_imu) and, when estimated, its intrinsics (focal lengths and centre) and
// distortion; per auxiliary IMU its rotation, translation and time offset (a gyroscope: rotation
// and time offset); per inertial sensor whose intrinsics are estimated, its intrinsics (Tw, Ta
// and the accelerometer's or gyroscope's rotation) and gravity sensitivity Tg.
//
// Status, decided whenever the calibration's covariance is new (update()):
// - held: the configuration holds it (estimate_* false, hold, a calibrated IMU model);
// - unobservable: the observability check holds it (the motion cannot tell it), with its words;
// - converged: its largest standard deviation (along any axis, as reported) is under its target
//   and its estimate moved, over the last `settle_s`, by less than `settle_sigmas` of that
//   standard deviation along every axis; a camera's intrinsics and distortion also need the
//   image covered (below). Once converged, it stays so until its sigma or movement passes 1.5
//   times those bounds (the reported sigmas breathe with the measured inflation);
// - improving: otherwise, with advice on the motion that would help most.
// The rig is "ready" when every quantity that is estimated is converged, "improving" otherwise
// (a held or unobservable quantity keeps it from ready only when it is unobservable).
//
// Coverage (camera intrinsics): the image is split into kCoverageColumns x kCoverageRows cells;
// a cell is covered once kCornersPerCell corners of frames the estimator took fell in it. The
// intrinsics and distortion count as converged only with every corner cell of the grid covered
// and at least kCoverageShare of all cells; the advice names the largest uncovered region.
#pragma once

#include <deque>
#include <map>
#include <string>
#include <vector>

#include "mvis/estimator/estimator.h"
#include "mvis/frontend/tag_observation.h"
#include "mvis/rig/rig.h"

namespace mvis {

// Targets: the largest standard deviation (1 sigma, along any axis) at which a quantity counts
// as converged. Defaults from the simulated VI-Rig (three cameras at 0.5 px, a 500 Hz MEMS base
// IMU, hand-held motion): what its quantities reach after 20-40 s, so that their errors are
// then within 0.05 deg (3 sigma), 1 mm for cameras (about 1.7 sigma: with this rig's 0.5 px
// corners a camera's translation reaches 0.33 mm only after minutes), 2 mm for IMUs (3 sigma)
// and 0.1 ms (2.5 sigma).
struct StatusTargets {
  double rotation_deg = 0.016;
  double camera_translation_mm = 0.5;
  double imu_translation_mm = 0.65;
  double time_offset_ms = 0.04;
  double camera_intrinsics_px = 0.5;  // focal lengths and centre
  double camera_distortion = 0.002;   // each coefficient
  double imu_intrinsics = 1e-3;       // each element of Tw, Ta; the rotation in rad
  double gravity_sensitivity = 1e-4;  // each element of Tg [rad/s per m/s^2]
  double settle_s = 5.0;              // how far back "recent movement" looks [s]
  double settle_sigmas = 1.5;         // how far, in sigmas, it may have moved
};

enum class QuantityStatus { kImproving, kConverged, kUnobservable, kHeld };
const char* toString(QuantityStatus status);

struct QuantityState {
  std::string sensor;    // cam0, imu1, ... or "rig"
  std::string quantity;  // rotation, translation, time_offset, intrinsics, distortion,
                         // gravity_sensitivity; "all" for the rig
  QuantityStatus status = QuantityStatus::kImproving;
  bool ready = false;   // the rig's row: every estimated quantity converged
  double sigma = 0.0;   // largest standard deviation, in `unit` (NaN: none yet)
  double target = 0.0;  // in `unit`
  std::string unit;     // deg, mm, ms, px, or "" (dimensionless)
  std::string advice;   // the motion that would help, in words; empty when none
  // The rig's row: "ready" or "improving"; else toString(status).
  std::string statusText() const;
};

// A camera's image coverage: corners per cell, row-major from the top-left cell.
struct CameraCoverage {
  std::string camera;
  int columns = 0, rows = 0;
  std::vector<int> corners;
  bool covered(int column, int row) const;
  double share() const;  // covered cells / all
  // The largest uncovered region in words ("the image's lower-left corner"), empty if none.
  std::string missing() const;
};

class CalibrationStatusTracker {
 public:
  static constexpr int kCoverageColumns = 8, kCoverageRows = 6;
  static constexpr int kCornersPerCell = 20;
  static constexpr double kCoverageShare = 0.75;

  CalibrationStatusTracker(const Rig& rig, const EstimatorOptions& options,
                           StatusTargets targets = StatusTargets());

  // A frame the estimator took: its corners count towards the camera's coverage.
  void addFrame(const TagFrame& frame);
  // With a new covariance: `calibration` with its (reported) standard deviations at `stamp_ns`,
  // what the observability check holds. Returns the states whose status changed (the rig's row
  // last, when its verdict changed), for calibration_status.csv.
  std::vector<QuantityState> update(TimeNs stamp_ns, const Rig& calibration,
                                    const std::vector<UnobservableCalibration>& unobservable);

  const std::vector<QuantityState>& states() const { return states_; }
  bool ready() const { return ready_; }
  TimeNs readySince() const { return ready_since_; }  // 0 while not ready
  const std::vector<CameraCoverage>& coverage() const { return coverage_; }

 private:
  struct History {
    std::deque<std::pair<TimeNs, Eigen::VectorXd>> values;  // the estimate over time
  };
  // The quantity's value (rotations as quaternions' coefficients, handled apart), its
  // per-axis sigma, in the quantity's unit.
  void evaluate(QuantityState* s, const Rig& calibration, TimeNs stamp_ns,
                const std::vector<UnobservableCalibration>& unobservable);

  Rig rig_;
  EstimatorOptions options_;
  StatusTargets targets_;
  std::vector<QuantityState> states_;
  std::map<std::string, History> history_;  // per "sensor.quantity"
  std::vector<CameraCoverage> coverage_;
  bool ready_ = false;
  bool any_update_ = false;
  TimeNs ready_since_ = 0;
};

}  // namespace mvis
