// Running the estimator over a bag as fast as possible, without a ROS master (mvis_offline,
// scripts/demo, scripts/bench).
//
// Every message of the rig's topics is read in bag order: sensor_msgs/Imu of each inertial
// sensor, and per camera the first of these the bag has: sensor_msgs/Image on its topic or
// sensor_msgs/CompressedImage (JPEG, PNG) on `<camera topic>/compressed`, both through the tag
// front end, or mvis/TagDetectionArray on `<camera topic>/tag_detections`. Bad messages are
// dropped and counted, as in the nodelet. A sensor without any message is named, with the bag's
// topics of the rig's message types that it does not use (a wrong topic is a one-line fix).
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "mvis/common/status.h"
#include "mvis/estimator/calibration_status.h"
#include "mvis/estimator/estimator.h"
#include "mvis/frontend/tag_frontend.h"
#include "mvis/rig/estimate_log.h"
#include "mvis/rig/rig.h"

namespace mvis {

struct OfflineOptions {
  EstimatorOptions estimator;
  TagFrontendOptions frontend;
  // Threads detecting tags in images while the bag is read (0: one per core of the machine);
  // the result does not depend on it.
  int image_threads = 0;
  // Called now and then with the share of the bag done [0, 1] and the bag time covered [s].
  std::function<void(double share, double bag_seconds)> progress;
  // Batch (estimator.batch, mvis_offline --batch): the calibration the states start from and
  // the seed trajectory (the online pass's result; the priors stay `initial`'s), the batch
  // solve's iterations and its progress (iteration, cost).
  const Rig* batch_start = nullptr;
  std::vector<EstimatorState> batch_seed;
  int batch_iterations = 100;
  std::function<void(int iteration, double cost)> batch_progress;
  // What counts as converged (calibration_status.h).
  StatusTargets status_targets;
};

// A quantity's status changed, at `bag_s` [s of bag time].
struct StatusEvent {
  double bag_s = 0.0;
  QuantityState state;
};

// One kind of problem met in the bag (the messages alike but for their numbers).
struct OfflineWarning {
  std::string example;   // the first message of its kind
  long count = 0;        // how often
  double first_s = 0.0;  // when first [s of bag time]
};

struct OfflineResult {
  Rig calibration;                         // with standard deviations
  std::vector<EstimatorState> trajectory;  // every window state
  double bag_seconds = 0.0;                // span of the messages used
  double wall_seconds = 0.0;               // time taken
  std::vector<double> update_ms;           // per estimator update (solve and bookkeeping)
  std::vector<int> solve_iterations;       // per update that solved
  EstimateLog log;                         // calibration after every solve, pose covariances
  std::vector<double> frontend_ms;         // per image (detection)
  std::vector<TagDetectionStages> detection_stages;  // per image, by stage
  long predicted_images = 0;                         // images searched in a predicted region only
  double searched_fraction_sum = 0;                  // over those, the region's share of the image
  std::vector<double> decode_ms;                     // per compressed image (decoding)
  long imu_messages = 0, image_messages = 0, detection_messages = 0, dropped_messages = 0;
  EstimatorCounters counters;
  ResidualStatistics residuals;  // Estimator::residualStatistics at the end
  // Guided calibration (online pass): every status change in order, the statuses at the end,
  // each camera's image coverage.
  std::vector<StatusEvent> status_timeline;
  std::vector<QuantityState> statuses;
  std::vector<CameraCoverage> coverage;
  double sigma_inflation = 1.0;       // Estimator::sigmaInflation at the end
  double time_offset_floor = 0.0;     // Estimator::timeOffsetFloor at the end [s] (NaN: none)
  std::string status;                 // the estimator's last word
  std::vector<std::string> warnings;  // e.g. a sensor without any message in the bag
  // What the last update found unobservable and held (UnobservableCalibration::text()).
  std::vector<std::string> unobservable;
  // Every change of a sensor's calibration declared (EstimatorOptions::detect_changes).
  std::vector<CalibrationChange> changes;
  std::vector<double> change_bag_s;  // when each was declared [s of bag time]
  // Every dropped message and every complaint of the estimator (a gap, a reset, a sensor that
  // left the window) by kind, in the order they first happened.
  std::vector<OfflineWarning> warning_kinds;
  // A batch's solve and residuals (the log then holds its calibration once, at the end, and
  // its pose covariances about a second apart).
  std::optional<BatchSummary> batch;
};

StatusOr<OfflineResult> runOffline(const Rig& initial, const std::string& bag_path,
                                   const OfflineOptions& options);

}  // namespace mvis
