// IMU intrinsics estimated online (report Sec. 2.2 and Table 3): on the VI-Rig with every
// inertial sensor's intrinsics off by the report's Table 4 perturbations, re-integration
// recovers them inside their 3-sigma while the cameras and aux sensors stay calibrated; with the
// intrinsics' linearization fixed and larger errors, the same run ends measurably worse; on
// yaw-only motion the intrinsics Table 3 names unobservable are reported and keep their prior.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "imu_intrinsics_test_util.h"

namespace mvis {
namespace {

using namespace mvis::test;  // NOLINT(google-build-using-namespace): the shared test helpers

// The same in the kalibr model (OpenVINS's and Kalibr's): Tw, Ta lower triangular, the rotation
// on the gyroscope (R_IMUtoGYRO) instead of the accelerometer.
void withKalibrIntrinsics(Rig* rig) {
  withIntrinsics(rig);
  for (auto& s : rig->inertial) {
    s.model = ImuModel::kKalibr;
    s.intrinsics.Tw.transposeInPlace();
    s.intrinsics.Ta.transposeInPlace();
    s.intrinsics.R_IMUtoGYRO = s.intrinsics.R_IMUtoACC;
    s.intrinsics.R_IMUtoACC.setIdentity();
  }
}

// The rotation the model estimates.
const Eigen::Matrix3d& modelRotation(const InertialSensor& s) {
  return s.model == ImuModel::kKalibr ? s.intrinsics.R_IMUtoGYRO : s.intrinsics.R_IMUtoACC;
}

struct IntrinsicsErrors {
  double D = 0.0;         // largest |error| of a Dw or Da element
  double Tg = 0.0;        // largest |error| of a Tg element
  double rotation = 0.0;  // R_IMUtoACC [deg]
  double sigma = 0.0;     // largest |error| / std over the estimated elements
};

IntrinsicsErrors intrinsicsErrors(const InertialSensor& truth, const InertialSensor& est) {
  IntrinsicsErrors e;
  const ImuIntrinsics &t = truth.intrinsics, &x = est.intrinsics;
  const bool gyro = truth.type == InertialType::kGyroscope;
  e.D = (x.Tw.inverse() - t.Tw.inverse()).cwiseAbs().maxCoeff();
  if (!gyro) e.D = std::max(e.D, (x.Ta.inverse() - t.Ta.inverse()).cwiseAbs().maxCoeff());
  e.Tg = (x.Tg - t.Tg).cwiseAbs().maxCoeff();
  const Eigen::Vector3d dtheta = lie::logSO3(modelRotation(truth).transpose() * modelRotation(est));
  e.rotation = dtheta.norm() * 180.0 / M_PI;
  if (!est.std) return e;
  const auto ratio = [](const Eigen::MatrixXd& err, const Eigen::MatrixXd& sd) {
    double worst = 0.0;
    for (int k = 0; k < err.size(); ++k) {
      if (sd(k) > 0.0) worst = std::max(worst, std::abs(err(k)) / sd(k));
    }
    return worst;
  };
  e.sigma = std::max(ratio(x.Tw - t.Tw, est.std->Tw), ratio(x.Tg - t.Tg, est.std->Tg));
  if (!gyro) {
    e.sigma = std::max({e.sigma, ratio(x.Ta - t.Ta, est.std->Ta),
                        ratio(dtheta, truth.model == ImuModel::kKalibr ? est.std->R_IMUtoGYRO
                                                                       : est.std->R_IMUtoACC)});
  }
  return e;
}

// Per inertial sensor, its intrinsics errors in the estimate.
std::vector<IntrinsicsErrors> allErrors(const SimRun& run, const Rig& estimate, const char* what) {
  std::vector<IntrinsicsErrors> out;
  for (std::size_t i = 0; i < run.truth.inertial.size(); ++i) {
    const IntrinsicsErrors g = intrinsicsErrors(run.truth.inertial[i], run.guess.inertial[i]);
    const IntrinsicsErrors e = intrinsicsErrors(run.truth.inertial[i], estimate.inertial[i]);
    std::printf(
        "%s %s: Dw/Da %.5f (from %.5f), Tg %.5f (from %.5f), rotation %.4f deg "
        "(from %.4f), largest error/sigma %.2f\n",
        what, run.truth.inertial[i].name.c_str(), e.D, g.D, e.Tg, g.Tg, e.rotation, g.rotation,
        e.sigma);
    out.push_back(e);
  }
  return out;
}

// The 30 s VI-Rig run with every sensor's true intrinsics set by `truth`, the guess perturbed as
// Table 4, re-integrated: the estimate and each sensor's intrinsics errors.
struct IntrinsicsRun {
  SimRun run;
  Rig estimate;
  std::vector<IntrinsicsErrors> errors;
};
IntrinsicsRun runIntrinsics(void (*truth)(Rig*), const char* what) {
  IntrinsicsRun r;
  r.run = simulate("sim_vi_rig", 30.0, 7, MotionKind::kHandheld, false, truth);
  perturbIntrinsics(&r.run.guess, 7, 1.0);
  const auto estimator =
      runFrom(r.run.guess, r.run, intrinsicsOptions(IntrinsicsLinearization::kReintegrate, 1.0));
  EXPECT_NE(estimator, nullptr);
  if (estimator == nullptr) return r;
  r.estimate = estimator->calibration();
  r.errors = allErrors(r.run, r.estimate, what);
  return r;
}

// Issue 8's main case, shortened to 30 s for CI (the 60 s figures are in scripts/bench and the
// issue's note: every element within 1.2e-3, Tg within 1e-4, R_IMUtoACC within 0.07 deg).
// Measured at 30 s (seed 7): Dw/Da 1.6e-3 / 0.7e-3 / 0.4e-3 (imu0 / imu1 / imu2, from 4-5e-3), Tg
// 1.0-1.1e-4 (from 1.4e-3 and 1.9e-3), R_IMUtoACC 0.03-0.05 deg (from 0.26 and 0.33); with the
// loss per frame (RobustLoss::kFrame) Dw/Da up to 1.8e-3, Tg 1.6e-4, R_IMUtoACC 0.06 deg. Bounds
// 1.5x those; the largest of up to 27 |error| / sigma per sensor under 3.5, its 99% quantile
// for a consistent estimate.
void expectIntrinsicsBounds(const IntrinsicsRun& r) {
  ASSERT_EQ(r.errors.size(), r.run.truth.inertial.size());
  for (std::size_t i = 0; i < r.errors.size(); ++i) {
    const std::string& name = r.run.truth.inertial[i].name;
    EXPECT_LT(r.errors[i].D, 2.7e-3) << name;
    EXPECT_LT(r.errors[i].Tg, 2.5e-4) << name;
    EXPECT_LT(r.errors[i].rotation, 0.1) << name;
    EXPECT_LT(r.errors[i].sigma, 3.5) << name;
  }
}

TEST(Estimator, CalibratesImuIntrinsicsByReintegration) {
  const IntrinsicsRun r = runIntrinsics(withIntrinsics, "re-integrated");
  expectIntrinsicsBounds(r);
  // The spatial calibration as without intrinsics (test_estimator.cpp's bounds for 30 s).
  for (std::size_t c = 0; c < r.run.truth.cameras.size(); ++c) {
    const std::string& name = r.run.truth.cameras[c].name;
    const CameraErrors ce = errors(r.run.truth.cameras[c], r.estimate.cameras[c]);
    EXPECT_LT(ce.rotation_deg, 0.05) << name;
    EXPECT_LT(ce.translation_mm, 2.0) << name;
    EXPECT_LT(ce.time_offset_ms, 0.1) << name;
    EXPECT_LT(ce.rotation_sigma_ratio.maxCoeff(), 3.5) << name;
    EXPECT_LT(ce.translation_sigma_ratio.maxCoeff(), 3.5) << name;
  }
}

// The same in the kalibr model (OpenVINS's default, Kalibr's scale-misalignment), estimated in
// its own parametrization: lower-triangular Dw, Da and the gyroscope's rotation.
TEST(Estimator, CalibratesKalibrModelImuIntrinsics) {
  const IntrinsicsRun r = runIntrinsics(withKalibrIntrinsics, "kalibr model");
  expectIntrinsicsBounds(r);
  for (const auto& s : r.estimate.inertial) {
    EXPECT_EQ(s.model, ImuModel::kKalibr) << s.name;
    EXPECT_EQ(s.intrinsics.Tw(0, 1), 0.0) << s.name;  // lower triangular
  }
  // {I} is the accelerometer's frame in this model: the cameras' rotations against it share the
  // uncertainty of the gyroscope's rotation against the accelerometer, which the motion tells
  // less well than the cameras' against the gyroscope. Measured (seed 7, 30 s): every camera
  // 0.080 deg off at 3.1 sigma (with every IMU's intrinsics free the cameras' rotations are
  // slightly overconfident, as in the rpng case: doc/known_issues.md), imu0's R_IMUtoGYRO
  // 0.076 deg; the cameras' rotations relative to cam0 within 0.002 deg. Bounds: 3.5 sigma (the
  // largest of three axes' 99% quantile), 0.15 deg, relative 0.02 deg.
  const Eigen::Matrix3d R_0 = r.estimate.cameras[0].T_cam_imu.rotation(),
                        R_0_true = r.run.truth.cameras[0].T_cam_imu.rotation();
  for (std::size_t c = 0; c < r.run.truth.cameras.size(); ++c) {
    const std::string& name = r.run.truth.cameras[c].name;
    const CameraErrors ce = errors(r.run.truth.cameras[c], r.estimate.cameras[c]);
    EXPECT_LT(ce.rotation_deg, 0.15) << name;
    EXPECT_LT(ce.rotation_sigma_ratio.maxCoeff(), 3.5) << name;
    EXPECT_LT(ce.translation_mm, 2.0) << name;
    EXPECT_LT(ce.time_offset_ms, 0.1) << name;
    const Eigen::Matrix3d relative = r.estimate.cameras[c].T_cam_imu.rotation() * R_0.transpose();
    const Eigen::Matrix3d relative_true =
        r.run.truth.cameras[c].T_cam_imu.rotation() * R_0_true.transpose();
    const double relative_deg =
        lie::logSO3(relative_true.transpose() * relative).norm() * 180.0 / M_PI;
    std::printf("kalibr model %s: rotation %.4f deg (%.2f sigma), relative to cam0 %.4f deg\n",
                name.c_str(), ce.rotation_deg, ce.rotation_sigma_ratio.maxCoeff(), relative_deg);
    EXPECT_LT(relative_deg, 0.02) << name;
  }
}

// Why re-integration (report Sec. 2.2): with the intrinsics' linearization fixed at the
// configured values, first order has to carry the whole error. At Table 4's sizes that is
// enough (the two modes end within noise of each other: 60 s, seed 7, Dw/Da 0.58e-3 vs
// 0.67e-3; scripts/bench); with errors 10x Table 4's (3% scale), it is not.
TEST(Estimator, FixedIntrinsicsLinearizationEndsWorse) {
  SimRun run = simulate("sim_vi_rig", 30.0, 7, MotionKind::kHandheld, false, withIntrinsics);
  perturbIntrinsics(&run.guess, 7, 10.0);
  double worst[2] = {0.0, 0.0}, sigma[2] = {0.0, 0.0};
  for (int m = 0; m < 2; ++m) {
    const auto mode =
        m == 0 ? IntrinsicsLinearization::kReintegrate : IntrinsicsLinearization::kFixed;
    EstimatorOptions options = intrinsicsOptions(mode, 10.0);
    // The linearization alone: no degeneracy holds (they act on the early, large errors too).
    options.imu_intrinsics_observability_ratio = 0.0;
    const auto estimator = runFrom(run.guess, run, options);
    ASSERT_NE(estimator, nullptr);
    const EstimatorCounters& c = estimator->counters();
    std::printf("%s: restarts %ld failures %ld inconsistencies %ld sigma inflation %.2f\n",
                m == 0 ? "re-integrated" : "fixed", c.restarts, c.failures, c.inconsistencies,
                estimator->sigmaInflation());
    // With the failure checks on: intrinsics are never restarted on, and nothing else fails
    // (both modes: no restart, no inconsistency said; the fixed mode's error is a bias that
    // every step agrees with, which no test on the steps can see).
    EXPECT_EQ(c.restarts, 0);
    for (const auto& e :
         allErrors(run, estimator->calibration(), m == 0 ? "re-integrated" : "fixed")) {
      worst[m] = std::max(worst[m], e.D);
      sigma[m] = std::max(sigma[m], e.sigma);
    }
  }
  // What holds in every build measured (five, differing only in rounding-level details, which
  // this far-off start amplifies): the fixed linearization ends overconfident, re-integration at
  // most half as far. With the model's sigmas 39-45 against 5-19; with the reported ones (scaled
  // by how much each quantity moves, Estimator::calibration) 14.5 against 3.0: the fixed mode's
  // error is a bias that every step agrees with, which the moves cannot show. The errors
  // themselves are not reliably ordered: largest Dw/Da element 2.1-4.7e-3 re-integrated against
  // 5.0-7.3e-3 fixed (from 5e-2), e.g. 3.6e-3 against 5.5e-3 in the last build.
  EXPECT_LT(worst[0], 6e-3);
  EXPECT_GE(worst[1], worst[0]);
  EXPECT_GT(sigma[1], 10.0);
  EXPECT_LT(sigma[0], 0.5 * sigma[1]);
}

// Report Table 3 on yaw-only motion (about world z, which is nearly imu0's x axis): the rates
// about imu0's y and z stay near zero, so Dw's columns 2 and 3 (dw12, dw22, dw13, dw23, dw33)
// are unobservable, and the specific force along x stays near g, so da11 and (with da12, da13)
// the pitch and yaw of R_IMUtoACC, and Tg's first column, are too. The spatial calibration is
// given (known) so that only Table 3 is at play.
TEST(Estimator, YawOnlyMotionLeavesTableThreeIntrinsicsAtTheirPrior) {
  SimRun run = simulate("sim_vi_rig", 20.0, 7, MotionKind::kYawOnly, false, withIntrinsics);
  perturbIntrinsics(&run.guess, 7, 1.0);
  EstimatorOptions options = intrinsicsOptions(IntrinsicsLinearization::kReintegrate, 1.0);
  options.estimate_extrinsics = options.estimate_time_offsets = false;
  options.estimate_aux_extrinsics = options.estimate_aux_time_offsets = false;
  for (std::size_t c = 0; c < run.guess.cameras.size(); ++c) {
    run.guess.cameras[c].T_cam_imu = run.truth.cameras[c].T_cam_imu;
    run.guess.cameras[c].timeshift_cam_imu = run.truth.cameras[c].timeshift_cam_imu;
  }
  for (std::size_t i = 1; i < run.guess.inertial.size(); ++i) {
    run.guess.inertial[i].T_i_b = run.truth.inertial[i].T_i_b;
    run.guess.inertial[i].time_offset = run.truth.inertial[i].time_offset;
  }
  auto created = Estimator::create(run.guess, options);
  ASSERT_TRUE(created.ok());
  Estimator& estimator = *created.value();
  EstimatorUpdate last;
  estimator.setUpdateCallback([&](const EstimatorUpdate& u) { last = u; });
  feed(run, &estimator);
  ASSERT_TRUE(estimator.initialized());
  ASSERT_TRUE(estimator.computeCovariance().ok());
  const Rig estimate = estimator.calibration();
  // Not asserted: the elements the motion still observes, dw11 (the scale about the axis) above
  // all, are near-degenerate here and end wherever rounding takes them: imu0 / imu1 / imu2's
  // largest error/sigma measured 1.3-2.6 / 1.9-2.9 / 0.9-4.3 over one session's builds and
  // process histories (other heap addresses, so another parameter order in Ceres), 2.7 / 3.5 /
  // 5.8 with the loss per corner, and one build reached 8-18 after another test in the same
  // process. Since the gyroscope's Tg is estimated too: 0.94 / 0.93 / 0.89; before
  // its specific force's noise was taken out of its readings' moments, its Tg's first column
  // was not found unobservable and ended 46 sigma off.
  allErrors(run, estimate, "yaw only");

  // Reported, in the report's names.
  std::vector<std::string> imu0, imu2;
  for (const auto& u : last.unobservable) {
    std::printf("  unobservable: %s\n", u.text().c_str());
    if (u.sensor == "imu0") imu0.insert(imu0.end(), u.elements.begin(), u.elements.end());
    if (u.sensor == "imu2") imu2.insert(imu2.end(), u.elements.begin(), u.elements.end());
  }
  for (const char* element :
       {"dw12", "dw22", "dw13", "dw23", "dw33", "da11", "tg11", "tg21", "tg31"}) {
    EXPECT_NE(std::find(imu0.begin(), imu0.end(), element), imu0.end()) << element;
  }
  // The gyroscope's Tg against the specific force along imu0's x axis (nearly its own x).
  for (const char* element : {"tg11", "tg21", "tg31"}) {
    EXPECT_NE(std::find(imu2.begin(), imu2.end(), element), imu2.end()) << element;
  }
  EXPECT_EQ(std::find(imu0.begin(), imu0.end(), "dw11"), imu0.end());  // rates about x vary

  // They keep their prior (0.012 for Dw, 0.004 for Tg; Tw's std is Dw's to first order),
  // while what the motion observes shrank (dw11: 0.0038; 0.0016 with the gyroscope's Tg held,
  // whose unobservable column's prior variance the rest is now conditioned on).
  const InertialCalibrationStd& sd = *estimate.inertial[0].std;
  for (const auto& [r, c] : {std::pair{0, 1}, {0, 2}, {1, 2}, {2, 2}}) {
    EXPECT_NEAR(sd.Tw(r, c), 0.012, 0.0012) << r << c;
  }
  for (int r = 0; r < 3; ++r) EXPECT_NEAR(sd.Tg(r, 0), 0.004, 4e-4) << r;
  EXPECT_LT(sd.Tw(0, 0), 0.4 * 0.012);
  // And they did not move from the guess (held), where the guess was off.
  const Eigen::Matrix3d moved =
      estimate.inertial[0].intrinsics.Tw - run.guess.inertial[0].intrinsics.Tw;
  EXPECT_LT(std::abs(moved(2, 2)), 1e-4);
}

// With the aux extrinsics estimated too: imu1 turns about its y axis, where its rotation about z
// and dw12 move the same rates (R_IMUtoACC estimated, nothing else tells them apart), so dw12 is
// held as well (not with the extrinsics known, above; imu1's rotation, dw12 and R_IMUtoACC had
// ended 3.7-5.0 sigma off together in one of six 60 s runs with everything free).
TEST(Estimator, YawOnlyMotionHoldsWhatAnAuxiliaryRotationTradesWith) {
  SimRun run = simulate("sim_vi_rig", 20.0, 7, MotionKind::kYawOnly, false, withIntrinsics);
  perturbIntrinsics(&run.guess, 7, 1.0);
  const EstimatorOptions options = intrinsicsOptions(IntrinsicsLinearization::kReintegrate, 1.0);
  auto created = Estimator::create(run.guess, options);
  ASSERT_TRUE(created.ok());
  EstimatorUpdate last;
  created.value()->setUpdateCallback([&](const EstimatorUpdate& u) { last = u; });
  feed(run, created.value().get());
  std::vector<std::string> imu1;
  for (const auto& u : last.unobservable) {
    if (u.sensor == "imu1" && u.quantity == "gyroscope scale and misalignment") imu1 = u.elements;
  }
  for (const char* element : {"dw12", "dw11", "dw13", "dw23", "dw33"}) {
    EXPECT_NE(std::find(imu1.begin(), imu1.end(), element), imu1.end()) << element;
  }
  EXPECT_EQ(std::find(imu1.begin(), imu1.end(), "dw22"), imu1.end());  // the scale about y
}

// A cheap MEMS gyroscope's gravity sensitivity: the gyroscope imu2 with Table 4's
// Tw and a Tg of up to 3e-4 rad/s per m/s^2, which its configuration does not know (zero).
void withGyroscopeTg(Rig* rig) {
  withIntrinsics(rig);
  for (auto& s : rig->inertial) {
    if (s.type != InertialType::kGyroscope) continue;
    s.intrinsics.Tg << -0.5e-4, 3e-4, 1e-4, 2e-4, -1e-4, -3e-4, 1.5e-4, 0.5e-4, 2.5e-4;
  }
}

// Every sensor's Tg zero in truth and guess, held at zero for all of them: the held test's null.
void withoutTg(Rig* rig) {
  withIntrinsics(rig);
  for (auto& s : rig->inertial) s.intrinsics.Tg.setZero();
}

struct TgRun {
  Rig estimate;
  std::vector<double> ratios;  // sigmaRatios
  double rms = 0.0, worst = 0.0;
  double gyro_tg = 0.0;  // imu2's largest |Tg error|
  EstimatorCounters counters;
  std::vector<std::pair<double, int>> held;  // per sensor: statistic, degrees of freedom
};

TgRun runTg(const SimRun& run, const EstimatorOptions& options, const char* what) {
  TgRun out;
  const auto estimator = runFrom(run.guess, run, options);
  EXPECT_NE(estimator, nullptr);
  if (estimator == nullptr) return out;
  out.estimate = estimator->calibration();
  out.counters = estimator->counters();
  // No sensor moved: none is declared moved (a gyroscope's gravity sensitivity is no change).
  EXPECT_EQ(out.counters.calibration_changes, 0)
      << what << ": " << (estimator->changes().empty() ? "" : estimator->changes().front().text);
  out.ratios = sigmaRatios(run.truth, out.estimate);
  for (double r : out.ratios) {
    out.rms += r * r;
    out.worst = std::max(out.worst, r);
  }
  out.rms = std::sqrt(out.rms / static_cast<double>(out.ratios.size()));
  out.gyro_tg = (out.estimate.inertial[2].intrinsics.Tg - run.truth.inertial[2].intrinsics.Tg)
                    .cwiseAbs()
                    .maxCoeff();
  std::printf(
      "%s: %zu elements, largest error/sigma %.2f, RMS %.2f; imu2 Tg off by %.2e; "
      "restarts %ld, held Tg refuted %ld times; held Tg statistic:",
      what, out.ratios.size(), out.worst, out.rms, out.gyro_tg, out.counters.restarts,
      out.counters.held_intrinsics_misfits);
  for (std::size_t i = 0; i < run.truth.inertial.size(); ++i) {
    int dof = 0;
    const double stat = estimator->heldIntrinsicsStatistic(i, &dof);
    out.held.emplace_back(stat, dof);
    std::printf(" %s %.1f (%d dof)", run.truth.inertial[i].name.c_str(), stat, dof);
  }
  std::printf("\n");
  allErrors(run, out.estimate, what);
  return out;
}

// Issue 22, item 1. Measured (seed 7, 30 s): 95 elements, largest error/sigma 2.43, RMS 1.10,
// imu2's Tg within 0.94e-4 (at 60 s 0.49e-4; the 6-seed Monte Carlo of doc/results.md: 1.1e-4,
// sigma 0.57e-4: the base IMU's own Tg is estimated too, and only the cameras tell the two
// apart). Bounds: the largest of 95 |error|/sigma under 3.5 (its 97% quantile for a
// consistent estimate), RMS in [0.7, 1.3] (the issue's), Tg 1.5e-4.
// Held at zero instead, the error spreads (imu0's intrinsics 7.5 sigma off) with no step or
// covariance check firing; the held test refutes it: statistic 63 at the end, over the bound of
// 34 (9 degrees of freedom, p = 1e-4) from 24 s on. Under the null (every Tg zero and held) it
// stays at 10.4 or below (7.3-8.9 at the end, about its mean of 9).
TEST(Estimator, CalibratesGyroscopeGravitySensitivity) {
  SimRun run = simulate("sim_vi_rig", 30.0, 7, MotionKind::kHandheld, false, withGyroscopeTg);
  perturbIntrinsics(&run.guess, 7, 1.0);
  run.guess.inertial[2].intrinsics.Tg.setZero();
  const EstimatorOptions options = intrinsicsOptions(IntrinsicsLinearization::kReintegrate, 1.0);
  const TgRun estimated = runTg(run, options, "Tg estimated");
  EXPECT_LT(estimated.worst, 3.5);
  EXPECT_GT(estimated.rms, 0.7);
  EXPECT_LT(estimated.rms, 1.3);
  EXPECT_LT(estimated.gyro_tg, 1.5e-4);

  EstimatorOptions held_options = options;
  held_options.hold.push_back("imu2.gravity_sensitivity");
  const TgRun held = runTg(run, held_options, "imu2's Tg held at zero");
  ASSERT_EQ(held.held.size(), 3u);
  EXPECT_EQ(held.held[2].second, 9);
  EXPECT_GT(held.held[2].first, 33.7);  // chi-square(9)'s quantile at 1 - 1e-4 (the default p)
  EXPECT_GE(held.counters.held_intrinsics_misfits, 1);
  EXPECT_EQ(held.counters.restarts, 0);  // said, not restarted on

  SimRun null_run = simulate("sim_vi_rig", 30.0, 7, MotionKind::kHandheld, false, withoutTg);
  perturbIntrinsics(&null_run.guess, 7, 1.0);
  for (auto& s : null_run.guess.inertial) s.intrinsics.Tg.setZero();
  EstimatorOptions null_options = options;
  null_options.estimate_gravity_sensitivity = false;
  const TgRun null = runTg(null_run, null_options, "every Tg zero and held");
  EXPECT_EQ(null.counters.held_intrinsics_misfits, 0);
  for (const auto& [stat, dof] : null.held) {
    EXPECT_EQ(dof, 9);
    EXPECT_LT(stat, 20.0);  // chi-square(9)'s 98% quantile
  }
}

// A configured (known) gyroscope Tg, intrinsics not estimated: the readings are corrected with
// it once the specific force at the gyroscope is known (aux_sensors.h). Only imu2's Tg differs
// from the identity model; with it configured the gyroscope's calibration is consistent, with
// zero configured instead it is not. Measured (seed 7, 30 s): rotation/time-offset error/sigma
// at most 1.94 configured (0.016 deg, 0.009 ms), with zero its time offset 0.10 ms off, which
// the model's sigmas put at 3.80 and the reported ones (scaled by how much the gyroscope's
// quantities move on this data, Estimator::calibration) at 2.29: the unmodelled Tg shows as
// an estimate that moves more and is further off, over five times as far in time offset.
TEST(Estimator, AppliesAConfiguredGyroscopeGravitySensitivity) {
  const auto onlyGyroTg = [](Rig* rig) {
    rig->inertial[2].model = ImuModel::kRpng;
    rig->inertial[2].intrinsics.Tg << -0.5e-4, 3e-4, 1e-4, 2e-4, -1e-4, -3e-4, 1.5e-4, 0.5e-4,
        2.5e-4;
  };
  const SimRun run = simulate("sim_vi_rig", 30.0, 7, MotionKind::kHandheld, false, onlyGyroTg);
  double worst[2] = {0.0, 0.0}, offset_ms[2] = {0.0, 0.0};
  for (int k = 0; k < 2; ++k) {
    Rig guess = run.guess;
    if (k == 1) guess.inertial[2].intrinsics.Tg.setZero();
    const auto estimator = runFrom(guess, run, deterministic());
    ASSERT_NE(estimator, nullptr);
    const CameraErrors e =
        inertialErrors(run.truth.inertial[2], estimator->calibration().inertial[2]);
    worst[k] = std::max(e.rotation_sigma_ratio.maxCoeff(), e.time_offset_sigma_ratio);
    offset_ms[k] = e.time_offset_ms;
    std::printf(
        "imu2 with %s Tg: rotation %.4f deg, time offset %.4f ms, largest error/sigma "
        "%.2f\n",
        k == 0 ? "its configured" : "zero", e.rotation_deg, e.time_offset_ms, worst[k]);
  }
  EXPECT_LT(worst[0], 3.0);  // consistent
  EXPECT_GT(worst[1], worst[0]);
  EXPECT_GT(offset_ms[1], 5.0 * offset_ms[0]);
}

}  // namespace
}  // namespace mvis
