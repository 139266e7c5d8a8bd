// The estimator's internals, shared by estimator.cpp (data in, the main loop, buffers),
// estimator_window.cpp (states, factors, solving, marginalization, covariance) and
// estimator_startup.cpp (initialization and clock alignment). Private to src/core/estimator.
#pragma once

#include <ceres/ceres.h>
#include <ceres/normal_prior.h>
#include <ceres/sphere_manifold.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>
#include <limits>
#include <map>
#include <optional>
#include <sstream>

#include "mvis/camera/camera_model.h"
#include "mvis/estimator/estimator.h"
#include "mvis/estimator/initialization.h"
#include "mvis/factors/aux_imu_factor.h"
#include "mvis/factors/gyro_factor.h"
#include "mvis/factors/imu_factor.h"
#include "mvis/factors/marginalization_factor.h"
#include "mvis/factors/pose_prior_factor.h"
#include "mvis/factors/state_blocks.h"
#include "mvis/factors/tag_reprojection_factor.h"
#include "mvis/factors/tangent_prior_factor.h"
#include "mvis/inertial/imu_correction.h"

namespace mvis {

// Window states closer than this to the previous one are not made (the frame is dropped).
constexpr TimeNs kMinStateIntervalNs = 5000000;  // 5 ms
// A camera frame's IMU-propagated pose depends on the IMU intrinsics (as a parameter block of its
// factor) only when it is propagated further than this from its state: over 2 ms a 1% scale
// error at 1 rad/s moves it by 2e-5 rad (~0.01 px), and each such block costs the solver a
// 24-column Jacobian per frame (J^T J was 15% of the run).
constexpr TimeNs kIntrinsicsAnchorSpanNs = 2000000;  // 2 ms
// A frame propagated less than this from its state (cam0's, at their state's time) carries no
// propagation-noise block: its readings' noise is under 1e-5 rad there, and the block would cost
// a parameter block per frame.
constexpr TimeNs kPropagationNoiseSpanNs = 1000000;  // 1 ms
namespace estimator_internal {

using Clock = std::chrono::steady_clock;

struct ResidualRecord {
  ceres::ResidualBlockId id = nullptr;
  const ceres::CostFunction* cost = nullptr;
  const ceres::LossFunction* loss = nullptr;
  std::vector<double*> blocks;
};

// An auxiliary sensor's state at one window time (state_blocks.h: aux_state or gyro bias).
struct AuxState {
  double x[9];  // [v b_g b_a], [b_g b_a] (rigid-velocity model) or [b_g] (gyroscope)
  // The sensor's time offset when this state was made [s]: the state belongs to the sensor-clock
  // time t - td0 of its window state t.
  double td0 = 0.0;
};

// One window state. Its residual records are the factors whose oldest state it is: they are
// marginalized with it.
struct State {
  TimeNs t = 0;
  double pose[kPoseSize];
  double speed_bias[kSpeedBiasSize];
  BaseMotion motion;  // base readings at t (kinematic frame poses, auxiliary factors)
  // Per auxiliary sensor (index sensor - 1): its state at t, or null while it has none.
  std::vector<std::unique_ptr<AuxState>> aux;
  std::vector<ResidualRecord> residuals;
  // Propagation-noise blocks of the frames attached to this state (kPropagationNoiseSize each).
  std::vector<std::unique_ptr<double[]>> propagation_noise;
  int frames = 0, corners = 0;

  EstimatorState toEstimate() const {
    EstimatorState s;
    s.stamp_ns = t;
    s.T_G_I = poseToSE3(pose);
    s.v_G = Eigen::Vector3d(speed_bias);
    s.bias_gyro = Eigen::Vector3d(speed_bias + 3);
    s.bias_accel = Eigen::Vector3d(speed_bias + 6);
    return s;
  }
};

// Prior standard deviations of an extrinsic and time offset: the configuration's *_std values
// where positive, the defaults elsewhere.
struct CalibrationPrior {
  Eigen::Vector3d rotation, translation;
  double time_offset;
};
inline CalibrationPrior calibrationPrior(double rotation, double translation, double time_offset,
                                         const Eigen::Vector3d* rotation_std,
                                         const Eigen::Vector3d* translation_std,
                                         double time_offset_std) {
  CalibrationPrior p{Eigen::Vector3d::Constant(rotation), Eigen::Vector3d::Constant(translation),
                     time_offset_std > 0 ? time_offset_std : time_offset};
  for (int i = 0; i < 3; ++i) {
    if (rotation_std != nullptr && (*rotation_std)[i] > 0) p.rotation[i] = (*rotation_std)[i];
    if (translation_std != nullptr && (*translation_std)[i] > 0) {
      p.translation[i] = (*translation_std)[i];
    }
  }
  return p;
}

struct CameraBlocks {
  double extrinsic[kPoseSize];  // T_C_I
  double time_offset[1];        // [s]
  double intrinsics[kIntrinsicsSize];
  CalibrationPrior prior;  // of the extrinsic and time offset
  // Of [fu fv pu pv k1 k2 k3 k4] (used when the intrinsics are estimated).
  Eigen::Matrix<double, kIntrinsicsSize, 1> intrinsics_prior =
      Eigen::Matrix<double, kIntrinsicsSize, 1>::Zero();
};

// An auxiliary IMU or gyroscope (rig.inertial[sensor], sensor >= 1): calibration blocks,
// readings in its own clock, and what the estimator knows of it between its chains of states.
struct AuxSensor {
  std::size_t sensor = 0;
  bool gyro = false;
  int block_size = 9;              // of its AuxState::x
  double extrinsic[kPoseSize];     // T_i_b (IMUs)
  double rotation[kRotationSize];  // the rotation of T_i_b (gyroscopes)
  double time_offset[1];           // [s], t_imu0 = t_i + time_offset
  std::deque<ImuMeasurement> readings;
  TimeNs last = std::numeric_limits<TimeNs>::min();
  bool stopped = false;                                 // said to have left the window
  Eigen::Vector3d bias_gyro = Eigen::Vector3d::Zero();  // last estimate, for a new chain
  Eigen::Vector3d bias_accel = Eigen::Vector3d::Zero();
  std::optional<InertialCalibrationStd> std;
  CalibrationPrior prior;  // of the extrinsic (or rotation) and time offset

  double* biasGyro(AuxState* s) const { return block_size == 9 ? s->x + 3 : s->x; }
  double* biasAccel(AuxState* s) const { return block_size == 9 ? s->x + 6 : s->x + 3; }
  double* extrinsicBlock() { return gyro ? rotation : extrinsic; }
};

// An inertial sensor's intrinsics block (imu_reintegration.h) while they are estimated.
struct ImuIntrinsicsBlock {
  double x[kImuIntrinsicsSize];
  double initial[kImuIntrinsicsSize];  // the configured values (IntrinsicsLinearization::kFixed)
  ImuIntrinsicsFrame frame;
  Eigen::Matrix<double, kImuIntrinsicsSize, 1> prior_std;
  // Holds the entries that are not estimated (a gyroscope's all but Dw; Tg unless gravity
  // sensitivity is estimated); null when every entry is.
  std::unique_ptr<ceres::Manifold> manifold;
  std::vector<int> free;  // the entries that are estimated: the tangent's directions, in order
  // Latest covariance of the block (ambient; zero rows for the held entries), if computed.
  std::optional<Eigen::Matrix<double, kImuIntrinsicsSize, kImuIntrinsicsSize>> covariance;
};

// Time-weighted moments of one sensor's readings between two window states, for the
// intrinsics' observability (estimator_observability.cpp).
struct ReadingMoments {
  TimeNs t = 0;    // the later state's time
  double T = 0.0;  // [s] covered
  int n = 0;       // readings
  Eigen::Vector3d w = Eigen::Vector3d::Zero(), a = Eigen::Vector3d::Zero();    // int x dt
  Eigen::Matrix3d ww = Eigen::Matrix3d::Zero(), aa = Eigen::Matrix3d::Zero();  // int x x^T dt
  Eigen::Matrix3d wa = Eigen::Matrix3d::Zero();                                // int w a^T dt
};

struct InitFrame {
  TimeNs t = 0;  // base clock
  SE3 T_G_I;     // unused without a board (initialize() makes it)
  TagFrame frame;
  // Without a board: the pose tag's centre in cam0's frame [tag sides].
  Eigen::Vector3d scaled = Eigen::Vector3d::Zero();
};

// Without a board (report Eq. 11): a tag's corners as landmark states, [p_G,0 .. p_G,3] in the
// world frame (TagReprojectionFactor::useLandmarkBlock).
struct TagLandmark {
  double x[kTagLandmarkSize];
};

inline double seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

}  // namespace estimator_internal

using estimator_internal::AuxSensor;
using estimator_internal::AuxState;
using estimator_internal::CameraBlocks;
using estimator_internal::Clock;
using estimator_internal::ImuIntrinsicsBlock;
using estimator_internal::InitFrame;
using estimator_internal::ReadingMoments;
using estimator_internal::ResidualRecord;
using estimator_internal::seconds;
using estimator_internal::State;
using estimator_internal::TagLandmark;

struct Estimator::Impl {
  Rig rig;
  EstimatorOptions options;
  std::vector<std::unique_ptr<CameraBlocks>> cameras;
  double gravity[kGravitySize] = {0.0, 0.0, -9.81};
  std::vector<std::unique_ptr<AuxSensor>> aux;  // index sensor - 1
  PoseManifold pose_manifold;
  RotationManifold rotation_manifold;
  ceres::SphereManifold<3> sphere_manifold;
  // Without a board: the tags' corners as states (estimator_landmarks.cpp), by tag id and by
  // block; per camera the tag its poses are taken on before initialization (-1: none yet).
  std::map<int, std::unique_ptr<TagLandmark>> landmarks;
  std::map<const double*, int> landmark_ids;
  std::vector<int> pose_tag;
  double initial_tag_side = 1.0;  // [m] from the initial alignment
  // The first state's pose defines the world frame without a board: a prior this tight [rad, m].
  static constexpr double kGaugeStd = 1e-6;
  // The camera factors' loss per frame (options.huber_sigma; RobustLoss::kFrame, and the first
  // batch whatever robust_loss says), null for plain squares; without a board, per number of
  // tags in the frame (tagLoss). The loss per corner lives in the factor (useCornerLoss).
  std::unique_ptr<ceres::LossFunction> huber;
  std::map<int, std::unique_ptr<ceres::LossFunction>> tag_losses;
  std::unique_ptr<ceres::Problem> problem;
  std::deque<std::unique_ptr<State>> states;
  // The marginalization prior, if any: its row groups (MarginalizationFactor::splitRows).
  std::vector<ResidualRecord> prior;
  // The prior as made, before its rows were split into `prior`: the next marginalization adds it
  // through the information it keeps (Marginalizer::addPrior).
  std::unique_ptr<MarginalizationFactor> prior_whole;
  std::deque<ImuMeasurement> imu;
  std::deque<TagFrame> base_frames;
  std::vector<std::deque<TagFrame>> other_frames;  // per camera (index 0 unused)
  std::vector<InitFrame> init;
  // Before initialization: board rotations R_G_C per camera (camera-clock stamps), for aligning
  // the clocks with the gyroscope.
  std::vector<std::deque<std::pair<TimeNs, Eigen::Matrix3d>>> board_rotations;
  bool clocks_aligned = false;
  std::vector<EstimatorState> past;
  UpdateCallback callback;
  PropagationCallback propagation_callback;
  std::shared_ptr<ImuPreintegration> propagation;  // from the newest state on
  TimeNs propagation_from = std::numeric_limits<TimeNs>::min();
  EstimatorCounters counters;
  bool initialized = false;
  std::string clock_message;  // what the clock alignment changed, if anything
  std::string status_text = "waiting for data";
  TimeNs last_imu = std::numeric_limits<TimeNs>::min();
  std::vector<TimeNs> last_frame;
  std::optional<std::vector<CameraCalibrationStd>> camera_std;
  int solves_since_covariance = 0;
  int frames_since_solve = 0;
  std::string warning;  // for the caller of the next addImu / addTagFrame
  // The latest observability check: what it found, and per calibration block the tangent
  // directions (orthonormal columns) that what leaves the window must not inform.
  std::vector<UnobservableCalibration> unobservable;
  std::map<const double*, Eigen::MatrixXd> uninformative;
  // What the base IMU's motion between consecutive states tells the calibration (per unit
  // noise density, estimator_observability.cpp), over the last observability_horizon_s.
  struct MotionInformation {
    TimeNs t = 0;                                           // the later state's time
    Eigen::Matrix3d translation = Eigen::Matrix3d::Zero();  // int (hat(a) + hat(w)^2)^T (...) dt
    Eigen::Matrix3d rotation = Eigen::Matrix3d::Zero();     // int hat(w)^T hat(w) dt
    double time_offset = 0.0;                               // int |alpha|^2 dt
  };
  std::deque<MotionInformation> motion_information;
  // Per inertial sensor with estimated intrinsics: its readings' moments over the last
  // observability_horizon_s (report Table 3).
  std::vector<std::deque<ReadingMoments>> reading_moments;
  // Calibration blocks held along their unobservable directions (so they cannot drift on what
  // the window's linearization noise says): the block's own manifold, the subspace manifold in
  // use (null: held whole, constant), the held directions and the variance each keeps.
  struct Hold {
    ceres::Manifold* base = nullptr;
    std::unique_ptr<SubspaceManifold> subspace;
    Eigen::MatrixXd directions;
    Eigen::VectorXd variance;
  };
  std::map<const double*, Hold> holds;
  // Per inertial sensor: its readings corrected by its configured intrinsics (imu_correction.h),
  // or left raw (identity) when they are estimated.
  std::vector<ImuCorrection> imu_corrections;
  // Per inertial sensor: its intrinsics block, or null when they are not estimated
  // (estimator_intrinsics.cpp).
  std::vector<std::unique_ptr<ImuIntrinsicsBlock>> imu_intrinsics;
  // The base IMU's current intrinsics estimate as a correction (identity when not estimated),
  // refreshed after every solve: the values only change there.
  ImuCorrection base_correction;

  Impl(const Rig& r, const EstimatorOptions& o) : rig(r), options(o) {
    initImuIntrinsics();
    for (const auto& cam : rig.cameras) {
      auto blocks = std::make_unique<CameraBlocks>();
      se3ToPose(cam.T_cam_imu, blocks->extrinsic);
      blocks->time_offset[0] = cam.timeshift_cam_imu;
      for (int i = 0; i < 4; ++i) {
        blocks->intrinsics[i] = cam.intrinsics[i];
        blocks->intrinsics[4 + i] = cam.distortion_coeffs[i];
      }
      cameras.push_back(std::move(blocks));
    }
    for (std::size_t i = 1; i < rig.inertial.size(); ++i) {
      const InertialSensor& sensor = rig.inertial[i];
      auto a = std::make_unique<AuxSensor>();
      a->sensor = i;
      a->gyro = sensor.type == InertialType::kGyroscope;
      a->block_size = a->gyro ? 3 : AuxImuFactor::auxBlockSize(options.aux_imu_model);
      se3ToPose(sensor.T_i_b, a->extrinsic);
      Eigen::Map<Eigen::Quaterniond>{a->rotation} = sensor.T_i_b.q;
      a->time_offset[0] = sensor.time_offset;
      aux.push_back(std::move(a));
    }
    other_frames.resize(rig.cameras.size());
    board_rotations.resize(rig.cameras.size());
    pose_tag.assign(rig.cameras.size(), -1);
    if (options.huber_sigma > 0.0) huber = std::make_unique<ceres::HuberLoss>(options.huber_sigma);
    last_frame.assign(rig.cameras.size(), std::numeric_limits<TimeNs>::min());
    newProblem();
  }

  void newProblem();

  TimeNs timeOffsetNs(std::size_t c) const { return fromSeconds(cameras[c]->time_offset[0]); }

  // ---- data in ---------------------------------------------------------------------------
  Status addImu(std::size_t sensor, const ImuMeasurement& m);

  Status addTagFrame(const TagFrame& frame);

  // ---- the main loop ---------------------------------------------------------------------
  void process();

  // The reading at t, interpolated between its neighbours (the nearest one outside the buffer).
  ImuMeasurement readingAt(TimeNs t) const;

  // IMU readings over [a, b] with interpolated readings at both ends.
  std::vector<ImuMeasurement> imuBetween(TimeNs a, TimeNs b) const;
  // The base readings over [a, b] to integrate: resampled at options.imu_integration_step_s.
  std::vector<ImuMeasurement> imuToIntegrate(TimeNs a, TimeNs b) const;
  // A gap for the cubic interpolation of inertial sensor `sensor`'s readings (0: linear only).
  TimeNs integrationIntervalNs(std::size_t sensor) const;

  // `corrected`: the readings corrected by the current intrinsics estimate
  // (propagationReading), for when the deltas are used as they are; else as stored (raw while
  // the intrinsics are estimated: the factors re-integrate them).
  std::shared_ptr<ImuPreintegration> preintegrate(TimeNs a, TimeNs b, const Eigen::Vector3d& bg,
                                                  const Eigen::Vector3d& ba,
                                                  bool corrected = false) const;

  // Whether t falls between two readings further apart than maxImuInterval().
  bool insideImuGap(TimeNs t) const;

  // Readings further apart than this are a gap (2.5 nominal periods).
  double maxImuInterval() const;

  void addRecord(State* owner, ceres::CostFunction* cost, ceres::LossFunction* loss,
                 std::vector<double*> blocks);

  void addStateBlocks(State* s);

  void addCalibrationBlocks();

  // After the first batch: moves the cameras' common position along what the batch's motion
  // left unobservable back to the configured cameras' (estimator_startup.cpp); whether it did.
  bool recentreUnobservedShift(const std::vector<SE3>& configured);
  // The prior of a frame's propagation-noise block, N(0, covariance) ([dtheta, dp, dv]); null
  // when the covariance is not positive definite.
  static ceres::CostFunction* propagationNoisePrior(const Eigen::Matrix<double, 9, 9>& covariance);
  // A frame's camera factors, owned by window state k (or its successor): one over its board
  // corners, or without a board one per tag with the tag's landmark block (and with
  // options.propagation_noise the prior of its propagation-noise block).
  struct FramePiece {
    ceres::CostFunction* cost;
    ceres::LossFunction* loss;
    std::vector<double*> blocks;
  };
  // Without a board, the loss of each of a frame's T tag factors: Huber at huber_sigma /
  // sqrt(T), so that the frame weighs as it would as one factor with the board (the Huber on
  // its whole norm counts a frame of N corners like about 3 sqrt(N/2) of them, see
  // RobustLoss::kFrame): a frame's tags share its errors, whatever holds its corners. Used with
  // RobustLoss::kFrame and in the first batch.
  ceres::LossFunction* tagLoss(int tags) {
    if (!huber) return nullptr;
    auto& loss = tag_losses[tags];
    if (!loss) {
      loss = std::make_unique<ceres::HuberLoss>(options.huber_sigma / std::sqrt(double(tags)));
    }
    return loss.get();
  }
  std::vector<FramePiece> frameFactors(const TagFrame& frame, std::size_t k, State** owner,
                                       int* corners);

  // ---- landmarks, without a board (estimator_landmarks.cpp) -------------------------------
  bool landmarkMode() const { return !rig.target; }
  // The tag's landmark block, made from the frame (camera c, attached to state k) if it has
  // none yet: PnP on the tag at the current tag side, placed with the state's pose propagated
  // to the frame. Null if that fails.
  double* landmarkFor(const TagFrame& frame, const TagObservation& tag, std::size_t k);
  // The mean side of the landmarks' tags [m] (the guess for a new tag's size).
  double meanTagSide() const;
  // The camera's pose on the frame's pose tag (landmark mode, unit side), choosing a new pose
  // tag (the largest in the frame) when it is not seen; a new one restarts that camera's
  // rotation history (and for cam0 the initialization).
  bool poseOnTag(const TagFrame& frame, SE3* T_T_C);
  // Landmarks only the leaving state's records observe: marginalized with it.
  std::vector<double*> leavingLandmarks(const State& oldest) const;
  void removeLandmark(double* block);
  // Angular acceleration at t: slope of a line fitted to the gyroscope readings within 10 ms.
  Eigen::Vector3d angularAcceleration(TimeNs t) const;

  void addFrame(const TagFrame& frame, std::size_t k);

  // The IMU factor between states k and k+1, on readings preintegrated at state k's biases.
  void addImuFactor(std::size_t k, std::shared_ptr<const ImuPreintegration> pre);

  void addState(const TagFrame& frame, TimeNs t);

  // A new window state at base time t with its readings (pose and speed left to the caller).
  std::unique_ptr<State> makeState(TimeNs t) const;

  // ---- IMU intrinsics (estimator_intrinsics.cpp) -----------------------------------------
  // Sets up imu_intrinsics and imu_corrections from the rig and options.
  void initImuIntrinsics();
  // base_correction from the base IMU's current intrinsics block.
  void refreshBaseCorrection();
  // Adds the estimated sensors' blocks with their priors to the problem.
  void addImuIntrinsicsBlocks();
  bool isImuIntrinsics(const double* block) const {
    for (const auto& b : imu_intrinsics) {
      if (b && b->x == block) return true;
    }
    return false;
  }
  // Sensor i's intrinsics block, or null when they are not estimated.
  double* imuIntrinsics(std::size_t i) const {
    return imu_intrinsics[i] ? imu_intrinsics[i]->x : nullptr;
  }
  // A base reading for IMU-rate propagation: corrected by the current intrinsics estimate, and
  // the biases to subtract from it (ImuCorrection's transformed biases). Identity when the base
  // IMU's intrinsics are not estimated (its readings are corrected as they arrive).
  ImuMeasurement propagationReading(const ImuMeasurement& m) const;
  void propagationBiases(const Eigen::Vector3d& bg, const Eigen::Vector3d& ba,
                         Eigen::Vector3d* bg_out, Eigen::Vector3d* ba_out) const;
  // After a covariance computation: every estimated block's covariance.
  void imuIntrinsicsCovariance(const ceres::Covariance& cov);
  // Writes the current intrinsics (and standard deviations) into a rig.
  void writeImuIntrinsics(Rig* out) const;

  // ---- auxiliary sensors (estimator_aux.cpp) ---------------------------------------------
  Status addAuxReading(std::size_t sensor, const ImuMeasurement& m);

  // Gives every auxiliary sensor states at the window states its readings reach.
  void extendAux();
  void extendAux(AuxSensor& a);

  // Starts sensor a's chain at window states k0..k1 (k1 > k0), all covered by its readings.
  void startAuxChain(AuxSensor& a, std::size_t k0, std::size_t k1);

  // Appends sensor a's state at window state k to its chain ending at k - 1.
  void appendAuxState(AuxSensor& a, std::size_t k);

  // Sensor a's readings over [tau_a, tau_b] (its clock), preintegrated at the given biases;
  // null if they do not cover the interval or have a hole longer than aux_max_gap_s.
  std::shared_ptr<ImuPreintegration> preintegrateAux(const AuxSensor& a, TimeNs tau_a, TimeNs tau_b,
                                                     const Eigen::Vector3d& bg,
                                                     const Eigen::Vector3d& ba) const;

  // The factor between the states of sensor a at window states k and k + 1.
  void addAuxFactor(AuxSensor& a, std::size_t k, std::shared_ptr<const ImuPreintegration> pre);

  void addAuxCalibrationBlocks();

  void trimAuxBuffers();

  // Status for the caller: `s`, or the pending warning if s is fine.
  Status withWarning(Status s);

  // Places every waiting frame of the other cameras that falls inside the window.
  void attachOtherFrames();

  // ---- initialization --------------------------------------------------------------------
  // The camera's board pose with its current intrinsics (without a board: poseOnTag).
  bool boardPose(const TagFrame& frame, SE3* T_G_C);
  // Camera c with its current intrinsics.
  Camera currentCamera(std::size_t c) const;

  void addInitFrame(TagFrame frame, TimeNs t);

  // ---- clock alignment -------------------------------------------------------------------
  // A camera's time offset may be far off (a driver stamping on arrival, another clock). Before
  // initializing, each camera's angular velocity from consecutive board poses, rotated into the
  // IMU frame with the extrinsic guess, is matched against the gyroscope over offsets within
  // +-kAlignRange; a clear best match replaces the configured offset.
  static constexpr TimeNs kAlignSpanNs = 1500000000;  // 1.5 s of board poses
  static constexpr double kAlignRange = 0.3;          // [s]
  // Without a board: the first batch's span (it places every tag from the motion).
  static constexpr TimeNs kLandmarkBatchNs = 4000000000;  // 4 s

  void recordBoardRotation(std::size_t c, TimeNs stamp, const SE3& T_G_C);

  // The offset correction of camera c [s], or 0 when the data do not decide it.
  double clockCorrection(std::size_t c) const;

  void alignClocks();

  void initialize();

  // IMU-rate state: the newest window state carried forward with the readings since.
  void propagate(const ImuMeasurement& m);

  // ---- solving and marginalization -------------------------------------------------------
  SolveSummary solve(int iterations, double max_time_s = -1.0);

  SolveSummary windowSummary() const;

  void marginalizeOldest();

  // Finds the calibration directions the recent motion leaves unobservable (observability.h),
  // into `unobservable` and `uninformative`, and holds them (estimator_observability.cpp).
  void checkObservability();

  // Adds the motion between states at a and b (base readings, gyro bias) to motion_information.
  void addMotionInformation(TimeNs a, TimeNs b, const Eigen::Vector3d& bias_gyro);

  // Adds sensor i's readings between window states (the later at t) to reading_moments.
  void addReadingMoments(std::size_t i, TimeNs t, const std::vector<ImuMeasurement>& readings);

  // Holds what `uninformative` names and releases what it no longer does.
  void applyHolds();

  // The block's own manifold, also while it is held.
  const ceres::Manifold* baseManifold(const double* block) const {
    const auto h = holds.find(block);
    return h != holds.end() ? h->second.base : problem->GetManifold(block);
  }

  // Tangent covariance of a calibration block in its own manifold's tangent (held directions
  // with the variance they keep).
  Eigen::MatrixXd tangentCovariance(const ceres::Covariance& cov, const double* block) const;

  // Whether options.hold holds `quantity` of `sensor` at its configured value.
  bool heldByOption(const std::string& sensor, const char* quantity) const {
    return std::find(options.hold.begin(), options.hold.end(), sensor + "." + quantity) !=
           options.hold.end();
  }

  // Whether a calibration block is estimated (not constant, or constant only while held).
  bool estimated(const double* block) const {
    return holds.count(block) > 0 || !problem->IsParameterBlockConstant(block);
  }

  // Latest standard deviations of a calibration block in its own tangent (the prior's before
  // any covariance).
  Eigen::VectorXd latestStd(const double* block) const;
  // The latest tangent covariance of a calibration block: the full one for IMU intrinsics once
  // computed, else diag(latestStd^2).
  Eigen::MatrixXd latestCovariance(const double* block) const;

  void publish(const SolveSummary& summary, Clock::time_point start);

  // Calibration standard deviations, and the newest pose's covariance.
  Status covariance(Eigen::Matrix<double, 6, 6>* pose_cov);
  // The newest pose's covariance with the held calibration directions free at the uncertainty
  // they kept (replaces *pose_cov).
  Status poseCovarianceWithHeld(Eigen::Matrix<double, 6, 6>* pose_cov);

  void trimBuffers();

  void resetAll();

  Rig calibration() const;
};

}  // namespace mvis
