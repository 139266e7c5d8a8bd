// The change test: does each camera's data still agree with its calibration, or did the camera
// move (a knocked mount, a re-seated lens holder, a camera whose clock was reset)? A saved
// calibration is a starting point, and a camera whose extrinsic or time offset changed must be
// found, named and re-opened rather than fought by the failure checks (which restart to the old
// value) or by the frame gate (which drops the moved camera's frames for good). Private to
// src/core/estimator.
//
// The evidence, per camera c: every frame's whitened corner residuals r at the estimate before
// the frame enters the window (the frame gate's), and their Jacobian J with respect to the
// camera's calibration x = [dtheta, dp of T_C_I (its tangent), t_d], gathered in bins of
// kBinNs. The states are taken as known: with a board each frame fixes the camera's pose alone,
// and before it enters the state it is attached to is the one the IMU predicts from the last
// solve, so a camera that moved shows its misfit in its own residuals and not in the others'.
// Per bin b: H_b = sum J^T J, g_b = sum J^T r, and the bin's own best change d_b = -H_b^+ g_b.
//
// The test (a generalized likelihood ratio for a step in x at a bin boundary, Willsky and Jones
// 1976): for each k = kMinBins..kBins the last k closed bins give the step
//   d = -H^+ g,  H = sum H_b,  g = sum g_b
// with covariance f H^+ (f below), to be compared with the current estimate's covariance P (the
// block's latest standard deviations, scaled by the failure checks' inflation): the statistic
//   T = d^T (f H^+ + P)^-1 d
// is chi-square with 7 degrees of freedom if nothing changed. A change is declared when T
// exceeds kThreshold (p ~ 1e-11, so that 20 windows a second per camera stay quiet for days) and
// the step explains the bins alike: a step leaves every bin after it with the same d_b, so their
// scatter
//   S = sum_b (d_b - d)^T H_b (d_b - d) / f
// is chi-square with 7 (k - 1) degrees of freedom, and a ramp d_b = a + b (t_b - mean t) fits
// them no better than the step: the drop R in their chi-square from the step's to the ramp's
// is chi-square with 7. A change inside the k bins, or a clock that drifts (a fault, for the
// failure checks; it is no change of the rig), is refused by S or R over its 1 - 1e-3 quantile
// (the shorter windows after a change then pass).
//
// The noise level f is measured on the data: the scatter of the bins' steps over the last kBins
// bins against their model (as S with d their mean), per camera, the median over the last
// kNoiseKept such measurements, at least 1. On mvis's simulator it is about 1; on real corners,
// correlated over many frames and from an imperfect lens model, it is larger, and with it the
// step a camera must make to be declared moved.
//
// Owns: per camera its bins and noise measurements. Asks nothing: the frames' residuals,
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
  static constexpr int kDim = 7;  // [dtheta (3), dp (3)] of T_C_I, t_d
  using Vector7 = Eigen::Matrix<double, kDim, 1>;
  using Matrix7 = Eigen::Matrix<double, kDim, kDim>;

  struct Change {
    std::size_t camera = 0;
    TimeNs stamp_ns = 0;     // the frame that completed the evidence (base clock)
    TimeNs since_ns = 0;     // the start of the bins that show it (base clock)
    Vector7 step;            // the camera's new calibration minus the current estimate
    Matrix7 covariance;      // of `step` given the data and the current estimate
    double statistic = 0.0;  // T
    double noise = 1.0;      // f
    // The evidence starts with the camera's first frames since the window (re)started: the
    // change may be older than the window, and its first batch saw the camera as it is now.
    bool from_start = false;
  };

  explicit ChangeDetector(std::size_t cameras);

  // A frame of camera c at base time t: its whitened residuals r and their Jacobian J (rows of
  // r by kDim) at the current estimate. Closes the camera's open bin when t passes its end.
  void addFrame(std::size_t c, TimeNs t, const Eigen::VectorXd& r, const Eigen::MatrixXd& J);
  // Whether camera c's closed bins show a change from the current estimate, whose covariance is
  // P (in the same coordinates); tested once per closed bin (then nullopt until the next one).
  std::optional<Change> test(std::size_t c, const Matrix7& P);
  // Camera c's evidence is forgotten (it was re-opened, or the window started over); its noise
  // measurements stay unless `noise` (they are the camera's, not the estimate's).
  void forget(std::size_t c, bool noise = false);
  void clear();
  // Camera c's current noise level f.
  double noise(std::size_t c) const;

  static constexpr TimeNs kBinNs = 250000000;  // 0.25 s
  static constexpr int kBins = 12;             // 3 s of evidence at most
  // A step is checked on a second of bins at least: over half a second a camera clock drifting
  // by 0.5% (a fault) passed for a step in its time offset.
  static constexpr int kMinBins = 4;
  static constexpr int kMinFramesPerBin = 2;
  static constexpr std::size_t kNoiseKept = 40;
  static constexpr double kThreshold = 70.0;  // chi-square, 7 dof: p ~ 1e-11

 private:
  struct Bin {
    TimeNs start = 0;
    Matrix7 H = Matrix7::Zero();
    Vector7 g = Vector7::Zero();
    int frames = 0;
  };
  struct Camera {
    std::deque<Bin> closed;  // oldest first, at most kBins
    Bin open;
    bool has_open = false;
    bool tested = true;        // the newest closed bin was tested
    std::deque<double> noise;  // the last kNoiseKept measurements
    TimeNs first = -1;         // the first closed bin's start since forget() (-1: none)
  };
  void close(Camera& cam);
  // How much better the last k bins fit a step plus a ramp than one step: the drop in their
  // chi-square (g, Hinv: the k bins' summed gradient and their information's pseudo-inverse).
  static double rampStatistic(const Camera& cam, int k, const Vector7& g, const Matrix7& Hinv);

  std::vector<Camera> cameras_;
};

// H^+ g and H^+ of a Jacobi-scaled H (directions with a scaled eigenvalue under 1e-9 of the
// largest carry nothing: a time offset on a rig that does not move).
ChangeDetector::Matrix7 pseudoInverse(const ChangeDetector::Matrix7& H);

}  // namespace estimator_internal
}  // namespace mvis
