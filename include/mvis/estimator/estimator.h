// The sliding-window estimator: one facade that takes base-IMU readings and tag frames of any
// number of asynchronous cameras, and returns estimates through a callback (no ROS).
//
// Method (report Sec. 1.3-2.1, solved online with Ceres): window states are base-IMU states
// [q, p, v, b_g, b_a] at base-camera (cam0) times (Eq. 12). Between consecutive states an
// ImuFactor; each camera frame is a TagReprojectionFactor on the state at or before it, its pose
// propagated there with the IMU readings (or, with interpolation kReport, the report's Appendix
// A: kinematic for cam0 frames, pose-based between the two states around other frames). Calibration
// blocks (extrinsic T_C_I, time offset, intrinsics per camera, and the gravity direction in the
// board frame) always exist; switches only hold them constant. When the window is full the oldest
// state is marginalized into a prior (MarginalizationFactor).
//
// The world frame is the board's (aprilgrid.yaml); gravity is estimated in it. Initialization
// waits for `init_frames` consecutive cam0 frames in which the board gives a pose (PnP), fits
// velocities and gravity to those poses and the readings preintegrated between them
// (initialization.h), then solves that window as a batch. Before that, it collects 1.5 s of board
// poses per camera and matches each camera's angular velocity against the gyroscope within +-0.3 s,
// so a time offset far from the configured one (a driver stamping on arrival) is corrected before
// the window starts. Until then `status()` says what it is waiting for.
//
// Without a board (no aprilgrid.yaml, report Eq. 11) every tag's four corners are a landmark
// block, one TagReprojectionFactor per tag and frame (src/core/estimator/landmarks.h). The poses
// before the window come from one tag of unknown side per camera (its centre; rotations from the
// gyroscope), the side from the same fit as gravity, over 4 s; the world frame is gravity-aligned
// at the first state, held by a tight prior on its pose. A tag leaves (is marginalized) with the
// last state that sees it.
//
// Auxiliary inertial sensors (report Sec. 3): every auxiliary IMU has a state [v, b_g, b_a] (or
// [b_g, b_a] with the rigid-velocity model) and every gyroscope a bias state at each window time,
// tied to the base states through the interpolated base pose and its extrinsic T_i_b and time
// offset by an AuxImuFactor or GyroFactor (aux_imu_factor.h, gyro_factor.h). A sensor's states
// start once its readings cover two window states, with velocities from the rigid-body relation
// (Eq. 40) and biases fitted to the window's motion (Eq. 41-43); a sensor whose readings stop
// for `aux_timeout_s` leaves the window with a warning and starts again when they return.
//
// Clocks: IMU readings of imu0 are in the base clock; a frame stamped t_c in camera c's clock
// happened at t_c + t_d,c (Kalibr's timeshift_cam_imu); a reading stamped t_i in inertial sensor
// i's clock happened at t_i + time_offset_i.
#pragma once

#include <Eigen/Core>
#include <array>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "mvis/common/lie.h"
#include "mvis/common/status.h"
#include "mvis/estimator/residual_statistics.h"
#include "mvis/factors/aux_imu_model.h"
#include "mvis/frontend/tag_observation.h"
#include "mvis/inertial/imu_correction.h"
#include "mvis/inertial/imu_readings.h"
#include "mvis/inertial/imu_reintegration.h"
#include "mvis/rig/rig.h"

namespace mvis {

// How a camera frame's pose comes from the window states (see tag_reprojection_factor.h).
enum class FrameInterpolation {
  kImu,     // IMU-propagated from the state before the frame (default)
  kReport,  // the report's Appendix A: kinematic for cam0, pose-based for the others
};

// A batch's calibration covariance (EstimatorOptions::batch_covariance).
enum class BatchCovariance { kModel, kClustered };

// Where the camera factors' robust loss (EstimatorOptions::huber_sigma) acts.
enum class RobustLoss {
  // On each corner's whitened residual (tag_reprojection_factor.h): every corner within
  // huber_sigma counts fully, a wrong one like ~huber_sigma / its error of one (the default).
  kCorner,
  // On a camera factor's whitened squared norm: a frame's corners together (without a board
  // each tag's, at huber_sigma / sqrt(tags in the frame), which weighs a frame the same). A
  // clean frame of N > 4 corners counts like about 3 sqrt(N/2) of them.
  kFrame,
};

struct EstimatorOptions {
  FrameInterpolation interpolation = FrameInterpolation::kImu;
  // kImu: a frame propagated from its state carries the base readings' noise over the
  // propagation (a 9-value block per frame with the preintegration's covariance as its prior,
  // tag_reprojection_factor.h) instead of taking the propagation as exact. It matters for
  // corners far more precise than the VI-Rig's (about 0.05 px): there the time offsets' std came
  // out under what the base IMU's noise allows (evaluation.h's timeOffsetFloor) without it. At
  // 0.15-0.5 px it changed no calibration figure by more than the runs' spread, and it costs about
  // 17% of the run (a block per frame between states), hence off by default.
  bool propagation_noise = false;
  // Inertial readings further apart than this are integrated in steps of at most this [s], the
  // readings in between from the cubic through the four real readings around them (as is every
  // reading interpolated at a state's or frame's time; linear next to a gap or the buffer's
  // end). The midpoint scheme on the readings as they come leaves an error of order dt^2 which
  // does not average out (imu_preintegration.h): on noise-free data a 100 Hz auxiliary IMU moved
  // the cameras' calibration by 0.16 mm. 0: the readings as they come, linear in between.
  double imu_integration_step_s = 0.0025;
  // States kept in the window (>= 3, and >= solve_every + 2: see solve_every).
  int window_size = 5;
  // Without a board: the most tags whose corners the window carries across marginalizations (in
  // its prior, which is dense over them: its cost grows with the cube of their number; each is
  // kept a square of unknown size, 7 values). A tag
  // beyond them is a landmark of the window alone: it leaves with the oldest state that sees it,
  // with every observation of it, and starts again from its next view (as a multi-state
  // constraint on the states and calibration that saw it). 0: every tag carried.
  int carried_tags = 12;
  // Without a board: whether the tags in view beyond the carried ones are used as the window's
  // own (above). Off, they are left out: the window then sees at most carried_tags tags (a tag
  // becomes carried when a carried one leaves), about 2-3x faster with 36 tags in view, at
  // 2-5% larger standard deviations on the simulated rig and 0.09 instead of 0.06 deg from the
  // board's result on the real EuRoC bag (doc/results.md "Speed").
  bool window_own_tags = true;
  // Solve after every n-th cam0 frame (states are still added, predicted by the IMU, and
  // marginalized at every frame): a budget for slow machines. At most window_size - 2, so that
  // a state's last solve before it is marginalized has at least three later states: the leaving
  // factors are linearized where that solve left the state and the next one, and with two later
  // states (window 4, every third frame) the time offsets ended biased on translation-only
  // motion (imu1 +0.18 ms, the cameras +0.06 ms over 12 runs; +0.04 / 0.00 ms with three or
  // more, as in the batch; doc/results.md).
  int solve_every = 3;
  int max_iterations = 10;         // per solve
  double max_solve_time_s = 0.05;  // per solve [s]
  double init_solve_time_s = 1.0;  // for the initial batch [s]
  int threads = 1;                 // Ceres threads
  double pixel_sigma_px = 1.0;     // corner noise [px]
  // Robust loss of the camera factors: Huber at this threshold [sigma units], 0: plain squares,
  // acting per corner or per frame (RobustLoss). The first batch has it per frame either way:
  // its residuals are mostly the rough initial calibration's, which a per-corner loss would
  // take for outliers. On the simulated VI-Rig (doc/results.md) the per-corner loss keeps every
  // clean corner's information (time offsets 0.046-0.047 ms at worst over six 60 s runs, 0.058
  // per frame; camera rotations' RMS error/sigma 0.9-1.0, 0.6 per frame) and with wrong corners
  // and wrong tag ids in the data it stays closer to the truth than per frame (test
  // WrongCornersAreOutweighedByTheRobustLoss); plain squares let those pull the calibration by
  // centimetres.
  double huber_sigma = 3.0;
  RobustLoss robust_loss = RobustLoss::kCorner;
  bool estimate_extrinsics = true;    // camera-IMU T_C_I of every camera
  bool estimate_time_offsets = true;  // timeshift_cam_imu of every camera
  // Camera intrinsics [fu fv pu pv] and distortion coefficients of every camera, with priors
  // from the configuration's intrinsics_std / distortion_coeffs_std keys or these defaults.
  bool estimate_intrinsics = false;
  double intrinsics_focal_prior_px = 10.0;   // fu, fv [px]
  double intrinsics_centre_prior_px = 10.0;  // pu, pv [px]
  double distortion_prior = 0.05;            // every coefficient
  // IMU intrinsics (report Eq. 1-4, imu_reintegration.h) of every inertial sensor whose model
  // is rpng or kalibr, in its own model: Dw, Da and R_IMUtoACC (kalibr: R_IMUtoGYRO), and Tg with
  // estimate_gravity_sensitivity; a gyroscope's Dw only. Sensors with model 'calibrated' keep
  // identity intrinsics. The readings are re-integrated at the current biases and intrinsics in
  // every evaluation (report Sec. 2.2); IntrinsicsLinearization::kFixed is the first-order
  // alternative the report warns against, for comparison. Priors: the configuration's Tw_std,
  // Ta_std, Tg_std, R_IMUtoACC_std (R_IMUtoGYRO_std) where positive, else these.
  bool estimate_imu_intrinsics = false;
  bool estimate_gravity_sensitivity = false;  // Tg (as OpenVINS's calib_imu_g_sensitivity)
  IntrinsicsLinearization imu_intrinsics_linearization = IntrinsicsLinearization::kReintegrate;
  double imu_scale_misalignment_prior = 0.01;    // every element of Dw, Da
  double imu_gravity_sensitivity_prior = 0.002;  // every element of Tg [rad/s per m/s^2]
  double imu_acc_rotation_prior_rad = 0.01;      // R_IMUtoACC, per axis [rad]
  // Per sensor: quantities held at their configured value although their class is estimated,
  // as "<sensor>.<quantity>": cameras extrinsic, time_offset, intrinsics; auxiliary sensors
  // extrinsic, time_offset; every inertial sensor (imu0 too) intrinsics, gravity_sensitivity.
  // E.g. {"cam1.intrinsics", "imu2.time_offset", "imu0.gravity_sensitivity"}.
  std::vector<std::string> hold;
  int init_frames = 10;        // consecutive cam0 frames with a board pose to initialize
  int min_tags = 2;            // tags a frame needs to be used at all (1 without a board)
  double gravity_m_s2 = 9.81;  // magnitude of gravity
  // Prior standard deviations where the configuration has no *_std keys.
  double extrinsic_rotation_prior_rad = 0.1;
  double extrinsic_translation_prior_m = 0.1;
  double time_offset_prior_s = 0.05;
  double bias_gyro_prior = 0.02;  // [rad/s] on the first state
  double bias_accel_prior = 0.2;  // [m/s^2] on the first state
  double velocity_prior = 0.5;    // [m/s] on the first state
  int covariance_every = 30;      // updates (cam0 frames) between calibration covariances
                                  // (0: never)
  // Auxiliary IMUs and gyroscopes.
  AuxImuModel aux_imu_model = AuxImuModel::kVelocityState;  // kRigidVelocity: report App. B
  bool estimate_aux_extrinsics = true;    // T_i_b of every aux IMU (rotation only for gyros)
  bool estimate_aux_time_offsets = true;  // time_offset of every aux IMU and gyroscope
  // Prior standard deviations where the configuration has no *_std keys.
  double aux_rotation_prior_rad = 0.1;
  double aux_translation_prior_m = 0.1;
  double aux_time_offset_prior_s = 0.05;
  double aux_velocity_prior = 0.5;  // [m/s] on an aux IMU's first velocity
  double aux_timeout_s = 0.5;       // readings missing this long: the sensor leaves the window
  double aux_max_gap_s = 0.1;       // longer holes between readings break a sensor's chain
  // Degenerate motion (report Sec. 5.1, Table 2; observability.h). Before every solve, the
  // base IMU's motion over the last observability_horizon_s seconds is asked how much it tells
  // each estimated camera and aux IMU translation and gyroscope rotation and time offset. A
  // direction it tells less than observability_ratio times the prior's information about (an
  // idealized measure, with the states known: hence the large default) is unobservable under the
  // recent motion: it is reported (EstimatorUpdate::unobservable) and held, so that it neither
  // moves nor gains information on linearization noise; what leaves the window adds none along
  // it. It keeps the standard deviation it had and is released when the motion tells it again.
  // 0 turns the check off.
  double observability_ratio = 500.0;
  double observability_horizon_s = 5.0;  // [s]
  // The same asked of the window itself, for directions shared between sensors that no single
  // quantity has (observability_window.cpp): the information that the window's measurements and
  // its marginalization prior hold about every estimated calibration block jointly (the other
  // states unknown), over what the blocks' priors hold; a direction with less than this ratio
  // is held, each sensor's part of it, checked every tenth solve. Its cost is in the counters.
  // Off by default (0): on the simulated yaw-only run with every quantity free it did not make
  // the cameras consistent (measured before the IMU intrinsics' holds kept their variance in the
  // marginalization, which did; doc/results.md), and at 0.01-1 it also holds weak but
  // informative directions (distortion, IMU intrinsics shortly after a restart).
  double window_observability_ratio = 0.0;
  // The same for the IMU intrinsics (report Table 3): a reading component (rate or specific
  // force along an axis) that stays constant over the horizon cannot be told from the bias, and
  // the intrinsics it multiplies are unobservable. The measure is the readings' centered second
  // moments over the horizon (noise taken out), which is what the intrinsics' information is;
  // as it keeps accumulating over a run, a direction only counts as unobservable when the
  // horizon tells less than this many times its prior (handheld motion: 2-45 for Da, ~500 for
  // Dw; constant components: ~0). 0 turns it off.
  double imu_intrinsics_observability_ratio = 1.0;
  // Faults (doc/bad_data.md). A hole in the base IMU's readings longer than this, a jump of
  // its clock back by more than 1 s (a bag restarted) or forward, and a failure found by the
  // checks below start the window over from the trusted calibration: the last one the checks
  // passed, with its covariance as prior (src/core/estimator/trusted_calibration.h), or the
  // configured one before any. What the rig did during a longer hole cannot be known; shorter
  // holes are integrated with inflated noise (imu_preintegration.h). Measured (small rig, 40 s,
  // test_faults): holes of 25-35 ms integrated leave the calibration as without them; 40-80 ms
  // moved a camera's position by 0.8-2.1 mm (up to 7.5 sigma): the inflated noise is not an
  // honest model that long (the auxiliary sensors' factors read the base motion inside the hole
  // too), so those start over. [s]
  double imu_max_gap_s = 0.03;
  // After every solve, each extrinsic's and time offset's step from the trusted calibration
  // whitened by the trusted covariance: a component beyond this [sigma] is a failure, as is a
  // newest state moving faster than 50 m/s (or, with a board, 1 km from it). With every
  // covariance, the step whitened by what the data since the trusted calibration can explain
  // (its covariance minus the new one): beyond 8 a failure. Both in sigmas scaled by how much
  // the calibration moves on this data (Estimator::sigmaInflation). Intrinsics beyond 8 are said
  // as inconsistent, not a failure (trusted_calibration.h). 0: the calibration tests off (the
  // speed and distance bounds stay).
  double failure_step_sigma = 10.0;
  // With a board, a camera frame whose corners' median residual at the current estimate is over
  // 3 times its camera's recent frames' (and over 2 sigma), or once a calibration is trusted
  // over this [pixel_sigma_px], is dropped before it enters (its clock or the camera moved, or
  // a wrong detection; with a camera clock drifting by 0.5% for 3 s, 19 frames were dropped and
  // the innovation test caught the rest, test_faults); once trusted, a single corner over this
  // in a frame kept is dropped (a wrong detection: on the EuRoC bag yac's detector put a few
  // corners 8-33 px off). 0: no frame or corner is dropped.
  double frame_gate_sigma = 10.0;
  // With a board, whether each camera's frames are tested for a change of its calibration (a
  // knocked mount, a camera whose clock was reset: src/core/estimator/change_detector.h): a
  // likelihood-ratio test of "its extrinsic and time offset stepped to a new value" against
  // "nothing changed", over up to 3 s of its residuals before they enter, at the noise level
  // the data show. A camera found moved is named (Estimator::changes()), set to the value the
  // test found, and re-opened: its priors become the defaults above (the configured *_std were
  // its old mount's), the window's prior lets go of what it knew of the old value, and the
  // failure checks and frame gate take the new value from then on. The other sensors keep
  // theirs.
  bool detect_changes = true;
  // While an inertial sensor's intrinsics are estimated with its gravity sensitivity Tg held
  // (estimate_gravity_sensitivity off, or held by name), a score test over the last
  // held_intrinsics_horizon_s [s] of its factors asks whether the data agree with the held Tg;
  // beyond the chi-square's 1 - held_intrinsics_p quantile the sensor is said to misfit
  // (counter held_intrinsics_misfits; src/core/estimator/inertial_fit.h). 0: not tested.
  double held_intrinsics_horizon_s = 30.0;
  double held_intrinsics_p = 1e-4;
  // Batch over a whole recording (report Eq. 23; mvis_offline --batch): the window keeps every
  // state (nothing is marginalized, window_size and solve_every are not used), and after the
  // first batch nothing is solved while data arrives: new states start where the seed
  // trajectory (Estimator::setSeedTrajectory, e.g. the online pass's) puts them, or are
  // predicted by the IMU where it has none. Estimator::solveBatch then solves every state and
  // the calibration at once. The degeneracy check looks at observability_horizon_s of motion as
  // online: set it to the recording's length to ask the whole recording.
  bool batch = false;
  // A batch's calibration covariance (src/core/estimator/block_covariance.h). kClustered: the
  // inverse information plus what the residuals show beyond their noise model, per group (the
  // corners, each inertial sensor), with errors correlated within a cluster counted as they are:
  // a corner's track over the recording or a second of frames (real corners: a corner's
  // residual stays correlated over hundreds of frames), a second of an inertial sensor's
  // factors. Never below kModel, the inverse information; on the simulator, whose residuals fit
  // their model, 1.0-1.2x it for the cameras (an auxiliary IMU's time offset up to 1.8x in 20 s,
  // 1.14x over 60 s). Online the marginalized prior has no residuals: always the model's. The
  // pose covariances are the model's either way.
  BatchCovariance batch_covariance = BatchCovariance::kClustered;
};

// Checked at creation: a clear message naming the option.
Status validate(const EstimatorOptions& options);
// The same, and the options against the rig (holds naming its sensors, what its sensors'
// models allow).
Status validate(const EstimatorOptions& options, const Rig& rig);

struct EstimatorState {
  TimeNs stamp_ns = 0;  // base clock
  SE3 T_G_I;            // base IMU in the world (board) frame
  Eigen::Vector3d v_G = Eigen::Vector3d::Zero();
  // Biases of the readings corrected by the base IMU's configured intrinsics (b_g', b_a' of
  // imu_correction.h; the raw readings' own when the IMU model is calibrated).
  Eigen::Vector3d bias_gyro = Eigen::Vector3d::Zero();
  Eigen::Vector3d bias_accel = Eigen::Vector3d::Zero();
};

// What IMU-rate odometry starts from after an update (odometry_propagator.h).
struct PropagationAnchor {
  bool valid = false;    // false: no state to propagate (before the first, after a restart)
  EstimatorState state;  // the newest window state (base clock); its biases as reported
  Eigen::Vector3d gravity_G = Eigen::Vector3d::Zero();  // [m/s^2], world (board) frame
  // Raw base reading -> calibrated reading: the configured intrinsics, or the current estimate
  // while they are estimated.
  ImuCorrection correction;
  // The biases of the corrected readings that the integration subtracts.
  Eigen::Vector3d corrected_bias_gyro = Eigen::Vector3d::Zero();
  Eigen::Vector3d corrected_bias_accel = Eigen::Vector3d::Zero();
};

struct SolveSummary {
  int iterations = 0;
  double solve_s = 0.0;  // Ceres time
  double total_s = 0.0;  // including marginalization and bookkeeping
  int states = 0;
  int frames = 0;   // camera frames in the window
  int corners = 0;  // corner observations in the window
  // Without a board: tags that are landmarks in the window, and of them those carried across
  // marginalizations (EstimatorOptions::carried_tags).
  int landmarks = 0, carried_landmarks = 0;
  double cost = 0.0;  // final Ceres cost
  bool usable = false;
};

// A calibrated quantity that the current motion leaves (partly) unobservable.
struct UnobservableCalibration {
  std::string sensor;  // the sensor's name (cam1, imu2, ...)
  std::string base;    // the base IMU's name, whose frame directions_I are in
  // "rotation", "translation", "time offset", or of an inertial sensor's intrinsics
  // "gyroscope scale and misalignment" (Dw), "gravity sensitivity" (Tg) or "accelerometer
  // intrinsics" (Da with R_IMUtoACC).
  std::string quantity;
  // Unit directions in the base IMU frame: of the sensor's position (translation) or rotation
  // axes (rotation); empty for a time offset.
  std::vector<Eigen::Vector3d> directions_I;
  // What the recent motion tells about each direction, over what its prior tells.
  std::vector<double> information_ratio;
  // Intrinsics: per direction the element it mostly moves, as the report names them (dw12 for
  // Dw's row 1, column 2; da33; tg21; theta_x for R_IMUtoACC about x).
  std::vector<std::string> elements;
  // quantity "shared direction" (found in the window's information, several sensors' quantities
  // moving together without changing any measurement; sensor is then their names joined by
  // '+'): each sensor's part in words ("cam0 rotation about (1.00, 0.02, 0.00)", "imu0
  // intrinsics (theta_x)"), and what motion would tell it. Also for intrinsics where the
  // generic words would mislead (what motion would tell them).
  std::vector<std::string> shared;
  std::string advice;
  // In plain words, e.g. "imu1 translation along (0.00, 0.00, 1.00) in imu0: rotate about
  // another axis too".
  std::string text() const;
};

// A sensor's calibration found changed (EstimatorOptions::detect_changes), one entry per quantity
// that moved.
struct CalibrationChange {
  TimeNs stamp_ns = 0;   // when it was declared (base clock)
  TimeNs since_ns = 0;   // the start of the data that show it (base clock)
  std::string sensor;    // cam1, ...
  std::string quantity;  // "rotation", "translation", "time_offset"
  // The change: [deg] for a rotation (the angle), [mm] for a translation (the norm), [ms] for a
  // time offset (signed); and its size over its standard deviation (the Mahalanobis norm of the
  // quantity's step under the data's and the former estimate's covariance).
  double size = 0.0;
  double size_sigma = 0.0;
  // In plain words: "cam1 moved: rotation 1.20 deg (520 sigma), ...".
  std::string text;
};

struct EstimatorUpdate {
  EstimatorState state;  // the newest window state
  // Covariance of [dtheta, dp] of the newest pose (right perturbation) when it was computed
  // with this update (every covariance_every solves), NaN otherwise.
  Eigen::Matrix<double, 6, 6> pose_covariance = Eigen::Matrix<double, 6, 6>::Zero();
  // With it, the covariances of that state's velocity v_G [(m/s)^2, world (board) frame] and of
  // its gyroscope bias [(rad/s)^2]; NaN otherwise.
  Eigen::Matrix3d velocity_covariance = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d gyro_bias_covariance = Eigen::Matrix3d::Zero();
  bool calibration_covariance_updated = false;          // calibration() has new standard deviations
  Eigen::Vector3d gravity_G = Eigen::Vector3d::Zero();  // in the world (board) frame [m/s^2]
  SolveSummary solve;
  // The newest state with what propagating it takes (odometry_propagator.h).
  PropagationAnchor anchor;
  // What the latest observability check found (observability_ratio); empty when all is.
  std::vector<UnobservableCalibration> unobservable;
  // Changes of a sensor's calibration declared since the previous update (detect_changes).
  std::vector<CalibrationChange> changes;
};

// One sensor's whitened residuals at the end of a batch (Estimator::solveBatch).
struct SensorResiduals {
  std::string sensor;  // its name
  std::string kind;    // "camera", "base IMU", "auxiliary IMU", "gyroscope"
  long factors = 0;    // residual blocks
  long residuals = 0;  // scalar residuals
  // Sum of squared whitened residuals as the factors have them (a camera factor's per-corner
  // loss, which is inside it, included; no other loss): about `residuals` (less the parameters'
  // share) when the noise model fits.
  double chi_square = 0.0;
  double rms = 0.0;  // [px] for a camera (whitened RMS x pixel_sigma_px), else whitened
  // The worst window states by their factors' chi-square per residual (their times, base
  // clock), worst first, at most five.
  std::vector<std::pair<TimeNs, double>> worst;
};

// One corner's residual at the end of a batch.
struct CornerResidual {
  TimeNs stamp_ns = 0;  // the window state its frame is attached to (base clock)
  int camera = 0;
  // The board point [m] (with a board; NaN without: then `corner` is the corner's index 0-3 in
  // its tag's landmark block).
  Eigen::Vector3d p_G = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  int corner = -1;
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();        // detected [px]
  Eigen::Vector2d residual = Eigen::Vector2d::Zero();  // projected - detected [px]
};

// One inertial factor's whitened chi-square at the end of a batch.
struct InertialResidual {
  TimeNs stamp_ns = 0;  // its first window state (base clock)
  int sensor = 0;       // rig.inertial index
  int residuals = 0;
  double chi_square = 0.0;
};

struct BatchSummary {
  SolveSummary solve;
  bool converged = false;  // Ceres's convergence test met (not the iteration limit)
  double initial_cost = 0.0;
  std::vector<SensorResiduals> residuals;  // cameras, base IMU, auxiliary sensors
  // Every corner's residual (before the robust loss) and inertial factor's chi-square, and the
  // pixel sigma the corners were weighed with (EstimatorOptions::pixel_sigma_px).
  std::vector<CornerResidual> corners;
  double pixel_sigma_px = 0.0;
  // The calibration's standard deviations over the inverse information's, smallest and largest
  // over every estimated element (1 with BatchCovariance::kModel).
  double sigma_ratio_min = 1.0, sigma_ratio_max = 1.0;
  // With BatchCovariance::kClustered: the calibration (as Estimator::calibration()) with the
  // model's standard deviations, the inverse information's.
  std::optional<Rig> model_calibration;
  std::vector<InertialResidual> inertial;
};

// Counters of what the estimator dropped, and why.
struct EstimatorCounters {
  long imu_out_of_order = 0;
  long imu_non_finite = 0;
  long imu_gaps = 0;  // intervals longer than 2.5 nominal periods
  long frames_too_few_tags = 0;
  long frames_too_old = 0;    // before the window
  long frames_too_close = 0;  // cam0 frames within 5 ms of the newest state (after a clock move)
  long frames_out_of_order = 0;
  long frames_in_imu_gap = 0;  // their pose would rest on made-up readings
  long resets = 0;
  long clock_corrections = 0;  // time offsets replaced from the gyroscope before initializing
  long solves = 0;
  long aux_dropped = 0;   // aux readings dropped (non-finite, out of order, unknown sensor)
  long aux_dropouts = 0;  // times an auxiliary sensor left the window (readings stopped)
  long aux_starts = 0;    // times an auxiliary sensor's states started in the window
  // Faults (EstimatorOptions::imu_max_gap_s and after).
  long restarts = 0;          // the window started over from the trusted calibration
  long failures = 0;          // failures found by the checks after a solve
  long frames_rejected = 0;   // frames far from where the estimate puts them (frame_gate_sigma)
  long corners_rejected = 0;  // single corners beyond frame_gate_sigma in frames kept
  long inconsistencies = 0;   // intrinsics moved beyond what their covariance allows
  long held_intrinsics_misfits = 0;  // the data disagree with a held Tg (held_intrinsics_p)
  long stamps_implausible = 0;
  long calibration_changes = 0;  // sensors found moved (EstimatorOptions::detect_changes)  //
                                 // frames and aux readings stamped far from the base IMU's time
  // covariances where a time offset's sigma was under 0.9 of Estimator::timeOffsetFloor()
  long time_offsets_under_floor = 0;
  // The degeneracy check of the window's information (window_observability_ratio): its runs and
  // their total time [s].
  long window_checks = 0;
  double window_check_s = 0.0;
  // Every degeneracy check before a solve (the per-quantity checks of the report's Tables 2-3,
  // and the window's above when on): runs and total time [s].
  long degeneracy_checks = 0;
  double degeneracy_check_s = 0.0;
};

class Estimator {
 public:
  using UpdateCallback = std::function<void(const EstimatorUpdate&)>;
  using PropagationCallback = std::function<void(const EstimatorState&)>;

  // Needs a rig with at least one camera and a board (aprilgrid.yaml).
  static StatusOr<std::unique_ptr<Estimator>> create(const Rig& rig,
                                                     const EstimatorOptions& options);
  ~Estimator();
  Estimator(const Estimator&) = delete;
  Estimator& operator=(const Estimator&) = delete;

  // A reading of inertial sensor `sensor` (0: the base IMU, else an auxiliary IMU or gyroscope;
  // a gyroscope's accel is ignored) stamped in its own clock. Errors describe a dropped reading
  // or a change worth a warning (an auxiliary sensor that stopped or came back); a base stamp
  // more than 1 s before the last one (a bag replayed) or more than imu_max_gap_s after it
  // starts the window over from the trusted calibration, and says so.
  Status addImu(std::size_t sensor, const ImuMeasurement& measurement);
  // Tags of one camera frame (camera clock). Errors describe a dropped frame.
  Status addTagFrame(const TagFrame& frame);

  void setUpdateCallback(UpdateCallback callback);
  // Called with every base-IMU reading after the newest window state: that state propagated to
  // the reading's time with the readings since (IMU-rate odometry between solves).
  void setPropagationCallback(PropagationCallback callback);

  // The rig with the current calibration estimate; with standard deviations when a covariance
  // has been computed (computeCovariance, or every `covariance_every` solves). Online, each
  // estimated quantity's (an extrinsic's rotation and translation, a time offset, a camera's
  // focal lengths and centre and its distortion, an IMU's intrinsics) are the covariance's
  // times how much more that quantity has moved between covariances than they allowed (the
  // square root of its steps' mean chi-square per degree of freedom, from one covariance to the
  // next and over the last ten, at least sigmaInflation()): on mvis's simulator about 1, on
  // real data what the data show (the EuRoC bag's halves, whose model sigmas disagree by up to
  // 10 of them, within 2.5). After solveBatch, the batch's.
  Rig calibration() const;
  // Errors: the computation failed, or (the standard deviations updated all the same) the
  // estimate failed the innovation test against the trusted calibration (trusted_calibration.h).
  Status computeCovariance();
  // Every state that has left the window, then the window's.
  std::vector<EstimatorState> trajectory() const;
  // Without a board (no aprilgrid.yaml): the current estimate of the carried tags' corners (at
  // most carried_tags tags; the others are the window's own, placed by its few states alone), by
  // tag id, in the world frame (corner order of tag_observation.h). Empty with a board.
  std::map<int, std::array<Eigen::Vector3d, 4>> landmarks() const;
  // What the estimator is doing, for diagnostics and logs ("initializing: 4 of 10 frames").
  std::string status() const;
  bool initialized() const;
  const EstimatorCounters& counters() const;
  // Residual statistics per sensor (residual_statistics.h): every state that left the window,
  // at its last solve, and the window's states at the current estimate; after solveBatch, every
  // state of the batch.
  ResidualStatistics residualStatistics() const;
  // Drops everything and starts over from the trusted calibration (the latest that the failure
  // checks passed, with its covariance; EstimatorOptions::imu_max_gap_s).
  void reset();
  // Every change of a sensor's calibration found so far, oldest first
  // (EstimatorOptions::detect_changes).
  std::vector<CalibrationChange> changes() const;
  // The last time the window started over from the trusted calibration (a gap or jump of the
  // base IMU's clock, a failure found after a solve, a reset) and why; reason empty if never.
  struct Restart {
    std::string reason;
    TimeNs stamp_ns = 0;  // base clock
  };
  Restart lastRestart() const;
  // How many times more the calibration moves between covariances than its standard deviations
  // allow (the square root of the median chi-square of its steps over their expectation, at
  // least 1; 1 until 10 s of data and three covariances): the failure checks are scaled by it.
  // 1.0 on mvis's simulator, 1.8-3.7 on the real EuRoC bag (test_real_euroc).
  double sigmaInflation() const;
  // The smallest standard deviation any time offset against imu0 can have on the data so far
  // [s]: imu0's white noise along the motion its readings show between the window states, as if
  // everything else were known (evaluation.h's timeOffsetFloor from the readings instead of the
  // truth); NaN before the window. A time offset whose sigma falls well under it is said
  // (EstimatorCounters::time_offsets_under_floor).
  double timeOffsetFloor() const;
  // Inertial sensor i's score statistic for its held gravity sensitivity over the last
  // held_intrinsics_horizon_s, and its degrees of freedom in *dof (0: nothing held and tested,
  // or less than a full horizon of data; EstimatorOptions::held_intrinsics_p).
  double heldIntrinsicsStatistic(std::size_t sensor, int* dof) const;

  // Batch (EstimatorOptions::batch). Before any data: the calibration starts from `start`'s
  // values (the priors stay the configured rig's), applied when the window is made.
  Status setInitialCalibration(const Rig& start);
  // Before any data: where new states start (sorted by time; interpolated, none across holes
  // over 0.2 s).
  void setSeedTrajectory(std::vector<EstimatorState> seed);
  // After the data: solves every state and the calibration together (at most max_iterations,
  // `progress` called after each with the iteration and the cost), then the calibration's
  // standard deviations (calibration()) and pose covariances every second of the trajectory
  // (batchPoseCovariances), and the whitened residuals per sensor.
  StatusOr<BatchSummary> solveBatch(int max_iterations,
                                    const std::function<void(int, double)>& progress);
  // After solveBatch: [dtheta, dp] covariances of window states about a second apart.
  std::vector<std::pair<TimeNs, Eigen::Matrix<double, 6, 6>>> batchPoseCovariances() const;

 private:
  struct Impl;
  explicit Estimator(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace mvis
