// The estimator's facade: the parts, wired (each owns its state; see doc/architecture.md), and
// what spans them: the main loop (a cam0 frame makes a window state, frames of the other cameras
// and auxiliary states join it, solve, marginalize, publish), the initialization, IMU-rate
// propagation, covariance and output. Private to estimator.cpp (data in, the loop, solving and
// output) and estimator_startup.cpp (the initialization).
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "aux_sensors.h"
#include "calibration_blocks.h"
#include "camera_frames.h"
#include "change_detector.h"
#include "imu_buffer.h"
#include "imu_intrinsics.h"
#include "inertial_fit.h"
#include "landmarks.h"
#include "mvis/estimator/estimator.h"
#include "mvis/estimator/odometry_propagator.h"
#include "mvis/estimator/residual_statistics.h"
#include "observability_monitor.h"
#include "startup.h"
#include "trusted_calibration.h"
#include "window.h"
#include "window_prior.h"

namespace mvis {

class TagReprojectionFactor;

struct Estimator::Impl {
  using Clock = std::chrono::steady_clock;
  using State = estimator_internal::State;

  // The configuration; every part keeps a reference to these two.
  const Rig rig;
  const EstimatorOptions options;
  EstimatorCounters counters;
  // The parts, in the order they are made (a part's constructor takes those before it).
  estimator_internal::CalibrationBlocks calibration;
  estimator_internal::ImuIntrinsicsBlocks intrinsics;
  estimator_internal::ImuBuffer imu;
  estimator_internal::Window window;
  estimator_internal::WindowPrior prior;
  estimator_internal::ObservabilityMonitor monitor;
  estimator_internal::Landmarks landmarks;
  estimator_internal::AuxSensors aux;
  estimator_internal::CameraFrames frames;
  estimator_internal::Startup startup;
  estimator_internal::TrustedCalibration trusted;
  estimator_internal::InertialFit inertial_fit;
  estimator_internal::ChangeDetector changes;
  std::vector<CalibrationChange> declared_changes;
  std::size_t changes_published = 0;  // of declared_changes, in an update
  // The trusted calibration's joint prior in the problem (after a restart), null if none.
  ceres::ResidualBlockId joint_prior_id = nullptr;
  // Output.
  UpdateCallback callback;
  PropagationCallback propagation_callback;
  // IMU-rate propagation from the newest state (fed only while a propagation callback is set).
  OdometryPropagator odometry;
  bool initialized = false;
  std::string status_text = "waiting for data";
  std::string last_restart;        // why the window last started over ("" if it never did)
  std::string restart_note;        // a restart not yet reported to the caller
  double window_data_s = 0.0;      // seconds of data the window has run on, over every restart
  std::string covariance_failure;  // what the latest covariance found wrong, for process()
  std::string calibration_note;    // its sigmas not to be trusted on this data, unsaid yet
  double said_inflation = 1.0;     // the largest inflation said so far (TrustedCalibration)
  // What imu0's readings between the states made so far tell of a time offset against them
  // (ImuBuffer::timeOffsetInformation summed) [1/s^2], up to the last state's time; kept over
  // restarts (the trusted calibration rests on that data).
  double time_offset_information = 0.0;
  TimeNs information_until = std::numeric_limits<TimeNs>::min();
  bool said_floor = false;     // a time offset's sigma under that floor said
  TimeNs last_restart_ns = 0;  // base clock
  int solves_since_covariance = 0;
  int frames_since_solve = 0;
  // Batch (EstimatorOptions::batch; estimator_batch.cpp): the calibration's starting values, the
  // seed trajectory, and the pose covariances the batch computed.
  std::optional<Rig> start;
  std::vector<EstimatorState> seed;
  std::vector<std::pair<TimeNs, Eigen::Matrix<double, 6, 6>>> batch_pose_covariances;

  Impl(const Rig& r, const EstimatorOptions& o);

  // ---- data in, the main loop (estimator.cpp) ----------------------------------------------
  Status addImu(std::size_t sensor, const ImuMeasurement& m);
  Status addTagFrame(const TagFrame& frame);
  // Takes every cam0 frame the IMU has passed: initialization frame, or a new window state with
  // the other cameras' frames and the auxiliary states, a solve every solve_every frames, the
  // oldest state marginalized, an update published.
  void process();
  // Tests each camera's and auxiliary sensor's recent data for a change of its calibration, and
  // re-opens the sensors found moved (EstimatorOptions::detect_changes); true if the window
  // started over for one (estimator_changes.cpp).
  bool followChanges();
  // A change detector's slot: the sensor's name and calibration blocks.
  struct ChangeSlot {
    std::string name;
    double* extrinsic = nullptr;  // T_C_I, T_i_b, or a gyroscope's rotation
    double* time_offset = nullptr;
    bool camera = false, gyro = false;
    bool tested = true;  // its change test may declare it moved
  };
  ChangeSlot changeSlot(std::size_t slot);
  // The sensor's current estimate's covariance in the change test's coordinates.
  estimator_internal::ChangeDetector::Matrix7 referenceCovariance(const ChangeSlot& s) const;
  // Records the change (declared_changes, the counter) and says it.
  std::string describeChange(const estimator_internal::ChangeDetector::Change& change,
                             const ChangeSlot& s, bool offset_free);
  bool reopen(const estimator_internal::ChangeDetector::Change& change);
  // A camera's change, checked against the other cameras' steps over its span: the camera whose
  // own part (its step less the others' mean) is the largest is the one that moved (states
  // pulled by a moved camera's frames shift the others' evidence alike); false if no camera's
  // own part passes the test. The change is rewritten for that camera.
  bool attribute(estimator_internal::ChangeDetector::Change* change);
  // A failure naming one sensor's extrinsic or time offset waits (at most kDeferFailureNs from
  // its first time) while that sensor's change test gathers the evidence that it moved: true
  // while it waits. The first time of the failure waited for (when it is restarted on), or t.
  bool deferFailure(const std::string& why, TimeNs t);
  TimeNs failure_since(TimeNs t) const {
    return deferred_failure_slot >= 0 ? std::min(t, deferred_failure_ns) : t;
  }
  int deferred_failure_slot = -1;  // the sensor whose failure waits (-1: none)
  // The last restart for a fault (base clock; lowest TimeNs: none): no change is declared for
  // kSettleAfterFaultNs after it.
  TimeNs fault_restart_ns = std::numeric_limits<TimeNs>::min();
  TimeNs deferred_failure_ns = 0;
  // A new window state at base time t, predicted from the newest with the readings, with its
  // IMU factor and the frame's factors.
  void addState(const TagFrame& frame, TimeNs t);
  // A new window state at base time t with its readings (pose and speed left to the caller).
  std::unique_ptr<State> makeState(TimeNs t) const;
  // Adds what imu0's readings tell of a time offset from the last state made to one at t.
  void addTimeOffsetInformation(TimeNs t);
  // Says (once) and counts time offsets whose sigma is under kFloorShare of the floor.
  void checkTimeOffsetFloor(const ceres::Problem& problem,
                            const estimator_internal::TangentCovariance& tangent);
  static constexpr double kFloorShare = 0.9;
  // The IMU factor between states k and k+1, on readings preintegrated at state k's biases.
  void addImuFactor(std::size_t k, std::shared_ptr<const ImuPreintegration> pre);
  // Solves the window (max_time_s <= 0: the option's budget) and refreshes what depends on the
  // solution.
  SolveSummary solve(int iterations, double max_time_s = -1.0);
  // `rows`: the new prior enters the problem (else it is kept as information for the next
  // marginalization only: cutting the first batch to the window state by state).
  void marginalizeOldest(bool rows = true);
  // IMU-rate state: the newest window state carried forward with the readings since (a raw
  // base reading, fed to `odometry`), to the propagation callback.
  void propagate(const ImuMeasurement& raw);
  // The newest window state and what propagating it takes; invalid before the first.
  PropagationAnchor anchor();
  // The base readings from state `from` to `to` preintegrated at its biases, corrected by the
  // current intrinsics estimate (as they are when the intrinsics are not estimated).
  std::shared_ptr<ImuPreintegration> corrected(const State& from, TimeNs to) const;
  void publish(const SolveSummary& summary, Clock::time_point start);
  // A batch's clustered covariance (block_covariance.h): its rows in, and besides the
  // standard deviations out: their smallest and largest ratio to the model's over the
  // calibration's estimated elements, and the calibration with the model's.
  struct Clustered {
    estimator_internal::RowClusters clusters;
    double ratio_min = 1.0, ratio_max = 1.0;
    Rig model;
  };
  // Calibration standard deviations, and the newest pose's covariance; with `clustered` the
  // clustered ones.
  Status covariance(Eigen::Matrix<double, 6, 6>* pose_cov, Clustered* clustered = nullptr,
                    Eigen::Matrix<double, 9, 9>* speed_bias_cov = nullptr);
  // The batch's corner and inertial rows, in groups (the corners, each inertial sensor) and
  // clustered two ways (estimator_batch.cpp, block_covariance.h).
  estimator_internal::RowClusters rowClusters() const;
  void trimBuffers();
  // A new problem: everything in the old one (prior, landmarks) is forgotten.
  void newProblem();
  void resetAll();
  // The window starts over from the trusted calibration (trusted_calibration.h), saying why;
  // after a `failure` of the estimate from one trusted kFailureLookbackNs before it. `for_change`:
  // a sensor found moved (estimator_changes.cpp), not a fault.
  void restart(const std::string& why, TimeNs when, bool failure = false, bool for_change = false);
  // The checks after a solve: why the estimate has gone wrong, or "".
  std::string failure() const;
  // Every calibration block for the trusted calibration, estimated where variable in the
  // window's problem (none with `configured`).
  std::vector<estimator_internal::TrustedCalibration::Block> trustedBlocks(bool configured);
  // Whether a stamp of a sensor (in the base clock) is within reach of the base IMU's newest
  // reading; else the message saying it is not.
  Status plausibleStamp(const std::string& sensor, TimeNs t);
  Rig calibrationEstimate() const;
  // calibrationEstimate() as reported (Estimator::calibration): online, each estimated block's
  // standard deviations times the square root of its inflation (TrustedCalibration::inflation:
  // how much more it moves on this data than its covariance allows); a batch's as computed.
  Rig reportedCalibration();
  bool batch_solved = false;  // the batch's covariance is the calibration's
  // Status for the caller: a restart not yet reported, else `s`, or the auxiliary sensors'
  // pending warning if s is fine.
  Status withWarning(Status s);

  // ---- batch (estimator_batch.cpp) ------------------------------------------------------------
  // The seed trajectory at t into s's pose, velocity and biases; false where it has none.
  bool seedAt(TimeNs t, State* s) const;
  // The calibration blocks to `start`'s values (after the priors were made at the configured).
  void applyStart();
  StatusOr<BatchSummary> solveBatch(int max_iterations,
                                    const std::function<void(int, double)>& progress);

  // ---- residuals (estimator_residuals.cpp) -----------------------------------------------------
  // The whitened residuals per sensor at the current estimate, with every corner's and
  // inertial factor's into `out`.
  void residualSummary(BatchSummary* out);
  // One window state's factors at the current estimate, per sensor k (cameras, then inertial
  // sensors; rig order): the whitened residuals, and for a camera's tag factor the factor
  // (its corners' errors: cornerErrors).
  void visitResiduals(const State& state,
                      const std::function<void(std::size_t k, const std::vector<double>& whitened,
                                               const TagReprojectionFactor* tag)>& visit);
  // A tag factor's whitened residuals as pixel errors (projected - detected), the per-corner
  // loss undone.
  std::vector<Eigen::Vector2d> cornerErrors(const std::vector<double>& whitened) const;
  // Empty statistics naming the rig's sensors.
  ResidualStatistics emptyResidualStatistics() const;
  void addResiduals(const State& state, ResidualStatistics* stats);
  // The residuals of the states that left the window (marginalizeOldest).
  ResidualStatistics left_residuals;

  // ---- initialization (estimator_startup.cpp) ----------------------------------------------
  // The camera's board pose with its current intrinsics (without a board: on its pose tag).
  bool boardPose(const TagFrame& frame, SE3* T_G_C);
  void addInitFrame(TagFrame frame, TimeNs t);
  void initialize();
  // After the first batch: moves the cameras' common position along what the batch's motion
  // left unobservable back to the configured cameras'; whether it did.
  bool recentreUnobservedShift(const std::vector<SE3>& configured);
};

}  // namespace mvis
