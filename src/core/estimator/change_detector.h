// The change test: does each sensor's data still agree with its calibration, or did the sensor
// move (a knocked mount, a re-seated lens holder, a camera whose clock was reset)? A saved
// calibration is a starting point, and a camera whose extrinsic or time offset changed must be
// found, named and re-opened rather than fought by the failure checks (which restart to the old
// value) or by the frame gate (which drops the moved camera's frames for good). Private to
// src/core/estimator.
//
// The evidence, per sensor (a slot: the cameras, then the auxiliary IMUs and gyroscopes): each
// camera frame's whitened corner residuals r at the estimate before the frame enters the window
// (the frame gate's), and their Jacobian J with respect to the camera's calibration
// x = [dtheta, dp of T_C_I (its tangent), t_d]; each auxiliary factor's whitened residuals when
// it is made (its newer states as the readings predict them) and their Jacobian in
// [dtheta, dp of T_i_b, t_d] (a gyroscope's dp columns zero); gathered in bins of kBinNs. The
// states are taken as known: with a board each frame fixes the camera's pose alone, and before
// it enters, the state it is attached to is the one the IMU predicts from the last solve, so a
// camera that moved shows its misfit in its own residuals and not in the others'; an auxiliary
// sensor that turned shows it in its rotation increments against the base IMU's.
// Per bin b: H_b = sum J^T J, g_b = sum J^T r, and the bin's own best change d_b = -H_b^+ g_b.
//
// The test (a generalized likelihood ratio for a step in x at a bin boundary, Willsky and Jones
// 1976): for each k = kMinBins..kBins the last k closed bins give the step
//   d = -H^+ g,  H = sum H_b,  g = sum g_b
// with covariance f H^+ (f below), to be compared with the current estimate's covariance P (the
// block's latest standard deviations, scaled by the failure checks' inflation): the statistic
//   T = d^T (f H^+ + P)^-1 d
// is chi-square with 7 degrees of freedom if nothing changed. A change is declared when T
// exceeds kThreshold (p ~ 2e-12, so that ~40 windows a second per sensor stay quiet for weeks) and
// the step explains the bins alike: a step leaves every bin after it with the same d_b, so their
// scatter
//   S = sum_b (d_b - d)^T H_b (d_b - d) / f
// is chi-square with 7 (k - 1) degrees of freedom, and a ramp d_b = a + b (t_b - mean t) fits
// them no better than the step: the drop R in their chi-square from the step's to the ramp's
// is chi-square with 7. A change inside the k bins, or a clock that drifts (a fault, for the
// failure checks; it is no change of the rig), is refused by S over its 1 - 1e-3 quantile or R
// over its 1 - 1e-2 quantile (a step's window refused that way is tested again with the next
// bin; the shorter windows after a change then pass). A ramp slow against the bins' noise passes
// for a step once its size dwarfs its growth within a window (test_change_detector): a clock
// that keeps drifting is then followed by steps, unless the failure checks restart on it first
// (they do on the fault suite's 0.5% for 3 s).
//
// An auxiliary sensor's biases are nuisance parameters: unknown and constant over a window (over
// a quarter of a second a rate error proportional to the rig's turning looks much like a bias,
// over seconds it does not), they are eliminated from the k bins' information together, in T
// as in S and R below. So is its time offset: a mount that moved does not change the sensor's
// clock, and a clock that drifts or jumps is a fault, the failure checks' (tested, an auxiliary
// IMU's clock drifting by 0.5% passed for a step within a second: its time offset shows only
// through the angular acceleration, weakly).
//
// The noise level f is measured on the data: the scatter of the bins' steps over the last kBins
// bins against their model (as S with d their mean), per camera, the median over the last
// kNoiseKept such measurements, at least 1. On mvis's simulator it is about 1; on real corners,
// correlated over many frames and from an imperfect lens model, it is larger, and with it the
// step a camera must make to be declared moved.
//
// Owns: per sensor its bins and noise measurements. Asks nothing: the frames' residuals,
// Jacobians and the reference covariance are handed in.
#pragma once

#include <Eigen/Core>
#include <deque>
#include <optional>
#include <vector>

#include "mvis/common/time.h"

namespace mvis {
namespace estimator_internal {

class ChangeDetector {
 public:
  static constexpr int kDim = 7;  // [dtheta (3), dp (3)] of the extrinsic, t_d
  // Nuisance parameters, constant over a test's window and unknown: an auxiliary sensor's
  // gyroscope and accelerometer biases and its time offset (zero columns for a camera).
  static constexpr int kNuisance = 7;
  static constexpr int kAll = kDim + kNuisance;
  using Vector7 = Eigen::Matrix<double, kDim, 1>;
  using Matrix7 = Eigen::Matrix<double, kDim, kDim>;
  using VectorA = Eigen::Matrix<double, kAll, 1>;
  using MatrixA = Eigen::Matrix<double, kAll, kAll>;

  struct Change {
    std::size_t slot = 0;    // the sensor (cameras first, then the auxiliary sensors)
    TimeNs stamp_ns = 0;     // the frame that completed the evidence (base clock)
    TimeNs since_ns = 0;     // the start of the bins that show it (base clock)
    Vector7 step;            // the camera's new calibration minus the current estimate
    Matrix7 covariance;      // of `step` given the data and the current estimate
    double statistic = 0.0;  // T
    double noise = 1.0;      // f
    // The evidence starts with the sensor's first data since the window (re)started: the
    // change may be older than the window, and its first batch saw the sensor as it is now.
    bool from_start = false;
  };

  explicit ChangeDetector(std::size_t slots);

  // Data of sensor `slot` at base time t (a camera frame, an auxiliary sensor's readings): its
  // whitened residuals r and their Jacobian J (rows of r by kDim, or by kAll with the nuisance
  // parameters' columns after) at the current estimate. Closes the sensor's open bin when t
  // passes its end.
  void add(std::size_t slot, TimeNs t, const Eigen::VectorXd& r, const Eigen::MatrixXd& J);
  // Whether the sensor's closed bins show a change from the current estimate, whose covariance
  // is P (in the same coordinates); tested once per closed bin (then nullopt until the next).
  std::optional<Change> test(std::size_t slot, const Matrix7& P);
  // The step its closed bins since base time `since` show (at least one bin), and its covariance
  // f H^+ (the data's alone); false when it has none.
  bool step(std::size_t slot, TimeNs since, Vector7* d, Matrix7* covariance) const;
  // Whether the sensor's newest bins, fewer than kMinBins, already show a change (T alone over
  // kThreshold, no step tests): a failure of its calibration may wait for the test.
  bool suggests(std::size_t slot, const Matrix7& P) const;
  // The sensor's evidence is forgotten (it was re-opened, or the window started over); its
  // noise measurements stay unless `noise` (they are the sensor's, not the estimate's).
  void forget(std::size_t slot, bool noise = false);
  void clear();
  // The sensor's current noise level f.
  double noise(std::size_t slot) const;

  static constexpr TimeNs kBinNs = 250000000;  // 0.25 s
  static constexpr int kBins = 12;             // 3 s of evidence at most
  // A step is checked on 1.25 s of bins at least: over half a second a camera clock drifting by
  // 0.5% (a fault) passed for a step in its time offset, over a second its ramp's R was 24.0
  // against 24.3 once.
  static constexpr int kMinBins = 5;
  static constexpr int kMinFramesPerBin = 2;
  static constexpr std::size_t kNoiseKept = 40;
  static constexpr double kThreshold = 70.0;  // chi-square, 7 dof: p ~ 2e-12

 private:
  struct Bin {
    TimeNs start = 0;
    MatrixA H = MatrixA::Zero();  // with the nuisance parameters
    VectorA g = VectorA::Zero();
    int frames = 0;
  };
  struct Slot {
    std::deque<Bin> closed;  // oldest first, at most kBins
    Bin open;
    bool has_open = false;
    bool tested = true;        // the newest closed bin was tested
    std::deque<double> noise;  // the last kNoiseKept measurements
    TimeNs first = -1;         // the first closed bin's start since forget() (-1: none)
  };
  void close(Slot& cam);
  // How much the last k bins' chi-square drops with one step (and common nuisance parameters).
  static double oneStep(const Slot& cam, int k);
  // How much further it drops with a step of their own per bin: S (times f).
  static double scatter(const Slot& cam, int k);
  // How much better the last k bins fit a step plus a ramp than one step: the drop R (times f)
  // in their chi-square.
  static double rampStatistic(const Slot& cam, int k);

  std::vector<Slot> slots_;
};

// (H, g) with the nuisance parameters eliminated (Schur complement): the calibration's
// information and gradient whatever they are.
void eliminateNuisance(const ChangeDetector::MatrixA& H, const ChangeDetector::VectorA& g,
                       ChangeDetector::Matrix7* H7, ChangeDetector::Vector7* g7);

// The pseudo-inverse of a Jacobi-scaled H (scaled_factorization.h: directions with a scaled
// eigenvalue under 1e-9 carry nothing, a time offset on a rig that does not move).
ChangeDetector::Matrix7 pseudoInverse(const ChangeDetector::Matrix7& H);

}  // namespace estimator_internal
}  // namespace mvis
