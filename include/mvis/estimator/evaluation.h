// Comparing an estimate with the truth: trajectory error and calibration tables, for the demo,
// mvis_offline and the tests.
#pragma once

#include <string>
#include <vector>

#include "mvis/estimator/estimator.h"
#include "mvis/rig/rig.h"
#include "mvis/rig/trajectory_io.h"

namespace mvis {

// Root-mean-square position error [m] of the estimated states against a denser true
// trajectory (interpolated at the states' stamps), in the common world frame, without
// alignment; with `align`, after the rigid (SE(3)) alignment of the estimated positions onto the
// true ones (for an estimate in a frame of its own, without a board). States outside the truth's
// time span are skipped; NaN if none is left.
double positionRmse(const std::vector<EstimatorState>& estimate,
                    const std::vector<StampedPose>& truth, bool align = false);

// A lower bound on a time offset's standard deviation [s] from the base IMU's white noise along
// a true trajectory of imu0 (evenly sampled, a z-up world with gravity `gravity_m_s2`), as if
// everything else - the poses the cameras see, biases, gravity, extrinsics - were known. A
// signal s(t) read with white noise of density q and shifted by dt changes by s'(t) dt, so
// the information on dt is the integral of |s'|^2 / q^2: the gyroscope's s = w (rate in {I})
// and the accelerometer's s = f = R^T (a - g) (specific force in {I}, which turns with the
// rig). Finite differences of the trajectory. No estimate can be more certain than this; the
// cameras' own noise only adds. (scripts/mvis_evaluation.py's time_offset_floor is the same
// for result directories.)
double timeOffsetFloor(const std::vector<StampedPose>& truth, const ImuNoise& noise,
                       double gravity_m_s2 = 9.81);

// Errors of one camera's (or inertial sensor's) extrinsic and time offset against the truth, in
// the estimate's tangent (T_true = T_est Exp(delta)).
struct CameraCalibrationError {
  Eigen::Vector3d rotation = Eigen::Vector3d::Zero();     // [rad]
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();  // [m]
  double time_offset = 0.0;                               // [s]
};
CameraCalibrationError cameraError(const Camera& truth, const Camera& estimate);
// Of T_i_b and time_offset (a gyroscope's translation is not calibrated: ignore it).
CameraCalibrationError inertialError(const InertialSensor& truth, const InertialSensor& estimate);

// A table of every camera's and auxiliary inertial sensor's extrinsic rotation, translation (not
// for gyroscopes) and time offset: the initial
// guess's error, the estimate's error and the estimate's 3-sigma bound when `truth` is given;
// otherwise the estimate and its 3-sigma. Cameras whose intrinsics were estimated add rows for
// the focal lengths, the centre and the distortion coefficients: the largest |error| of each
// group and the largest 3 sigma; inertial sensors (imu0 too) whose intrinsics were estimated
// add rows for Dw and Da (largest element error, in 1e-3), Tg and R_IMUtoACC.
std::string calibrationTable(const Rig& initial, const Rig& estimate, const Rig* truth);

}  // namespace mvis
