// Guided calibration's bookkeeping (calibration_status.h) on a hand-made sequence of
// calibrations: held quantities, convergence only after the estimate settled, the rig's verdict
// and its hysteresis, a declared change making it improving again, unobservable quantities with
// their words, and the coverage's missing region.
#include <gtest/gtest.h>

#include <cmath>

#include "mvis/estimator/calibration_status.h"
#include "mvis/rig/rig_io.h"

namespace mvis {
namespace {

constexpr TimeNs kSecond = 1000000000;

Rig vi_rig() {
  auto rig = loadRig(std::string(MVIS_SOURCE_DIR) + "/config/sim_vi_rig");
  EXPECT_TRUE(rig.ok()) << rig.status().message();
  return rig.value();
}

// Every camera and auxiliary sensor with standard deviations `scale` times the targets'
// defaults (rotation 0.016 deg, translation 0.5 / 0.65 mm, time offset 0.04 ms).
Rig withSigmas(Rig rig, double scale) {
  const double deg = M_PI / 180.0;
  for (Camera& c : rig.cameras) {
    CameraCalibrationStd s;
    s.rotation.setConstant(scale * 0.016 * deg);
    s.translation.setConstant(scale * 0.5e-3);
    s.timeshift_cam_imu = scale * 0.04e-3;
    c.std = s;
  }
  for (std::size_t i = 1; i < rig.inertial.size(); ++i) {
    InertialCalibrationStd s;
    s.rotation.setConstant(scale * 0.016 * deg);
    s.translation.setConstant(scale * 0.65e-3);
    s.time_offset = scale * 0.04e-3;
    rig.inertial[i].std = s;
  }
  return rig;
}

const QuantityState* find(const std::vector<QuantityState>& states, const std::string& sensor,
                          const std::string& quantity) {
  for (const QuantityState& s : states) {
    if (s.sensor == sensor && s.quantity == quantity) return &s;
  }
  return nullptr;
}

TEST(CalibrationStatus, ListsEveryQuantityAndHoldsWhatTheOptionsHold) {
  EstimatorOptions options;
  options.estimate_time_offsets = false;
  options.hold = {"imu1.extrinsic"};
  CalibrationStatusTracker tracker(vi_rig(), options);
  const auto& s = tracker.states();
  // 3 cameras x 3, imu1 x 3, imu2 (a gyroscope) x 2.
  EXPECT_EQ(s.size(), 14u);
  EXPECT_EQ(find(s, "cam0", "time_offset")->status, QuantityStatus::kHeld);
  EXPECT_EQ(find(s, "cam0", "rotation")->status, QuantityStatus::kImproving);
  EXPECT_EQ(find(s, "imu1", "translation")->status, QuantityStatus::kHeld);
  EXPECT_EQ(find(s, "imu2", "translation"), nullptr);
  EXPECT_EQ(find(s, "cam0", "intrinsics"), nullptr);  // not estimated
}

TEST(CalibrationStatus, ConvergesOnlyOnceSettledAndGoesBackOnAChange) {
  const Rig rig = vi_rig();
  CalibrationStatusTracker tracker(rig, EstimatorOptions());
  // Sigmas under the targets from the start, the estimate still: converged only once 5 s of
  // history show it settled.
  const Rig good = withSigmas(rig, 0.8);
  std::vector<QuantityState> rows = tracker.update(1 * kSecond, good, {});
  EXPECT_EQ(rows.size(), 15u);  // every quantity's first status and the rig's
  EXPECT_FALSE(tracker.ready());
  rows = tracker.update(4 * kSecond, good, {});
  EXPECT_TRUE(rows.empty());
  rows = tracker.update(6 * kSecond + 1, good, {});
  EXPECT_TRUE(tracker.ready());
  EXPECT_EQ(rows.back().sensor, "rig");
  EXPECT_EQ(rows.back().statusText(), "ready");
  EXPECT_EQ(tracker.readySince(), 6 * kSecond + 1);

  // Sigmas breathing a little past the target keep it (hysteresis: up to 1.5x).
  tracker.update(7 * kSecond, withSigmas(rig, 1.3), {});
  EXPECT_TRUE(tracker.ready());

  // A declared change: cam1's prior reset (sigma 20x) and its estimate moved: improving.
  Rig moved = withSigmas(rig, 1.0);
  moved.cameras[1].T_cam_imu.p.x() += 0.005;
  CameraCalibrationStd wide = *moved.cameras[1].std;
  wide.translation *= 20.0;
  moved.cameras[1].std = wide;
  rows = tracker.update(8 * kSecond, moved, {});
  EXPECT_FALSE(tracker.ready());
  const QuantityState* t = find(tracker.states(), "cam1", "translation");
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(t->status, QuantityStatus::kImproving);
  EXPECT_NEAR(t->sigma, 20.0 * 0.5, 1e-9);  // [mm]
  EXPECT_NE(t->advice.find("rotate about imu0's"), std::string::npos) << t->advice;
  EXPECT_EQ(rows.back().statusText(), "improving");
}

TEST(CalibrationStatus, AnEstimateThatStillMovesIsNotConverged) {
  const Rig rig = vi_rig();
  CalibrationStatusTracker tracker(rig, EstimatorOptions());
  Rig r = withSigmas(rig, 0.8);
  for (int k = 0; k <= 10; ++k) {
    // cam0's time offset walks 0.1 ms a second: 2.5 of its 0.032 ms sigmas each second.
    r.cameras[0].timeshift_cam_imu = rig.cameras[0].timeshift_cam_imu + 1e-4 * k;
    tracker.update(k * kSecond, r, {});
  }
  const QuantityState* s = find(tracker.states(), "cam0", "time_offset");
  EXPECT_EQ(s->status, QuantityStatus::kImproving);
  EXPECT_EQ(s->advice, "keep moving as before: the estimate still moves");
  EXPECT_FALSE(tracker.ready());
  EXPECT_EQ(find(tracker.states(), "cam1", "time_offset")->status, QuantityStatus::kConverged);
}

TEST(CalibrationStatus, UnobservableQuantitiesCarryTheirWords) {
  const Rig rig = vi_rig();
  CalibrationStatusTracker tracker(rig, EstimatorOptions());
  UnobservableCalibration d;
  d.sensor = "imu1";
  d.base = "imu0";
  d.quantity = "translation";
  d.directions_I = {Eigen::Vector3d::UnitZ()};
  d.information_ratio = {0.0};
  d.advice = "rotate about another axis too";
  for (int k = 0; k <= 6; ++k) tracker.update(k * kSecond, withSigmas(rig, 0.5), {d});
  const QuantityState* s = find(tracker.states(), "imu1", "translation");
  EXPECT_EQ(s->status, QuantityStatus::kUnobservable);
  EXPECT_EQ(s->advice, d.text());
  EXPECT_FALSE(tracker.ready());
  EXPECT_EQ(find(tracker.states(), "imu1", "rotation")->status, QuantityStatus::kConverged);
}

TEST(CalibrationStatus, IntrinsicsNeedTheImagesCorners) {
  Rig rig = vi_rig();
  EstimatorOptions options;
  options.estimate_intrinsics = true;
  CalibrationStatusTracker tracker(rig, options);
  for (Camera& c : rig.cameras) {
    CameraCalibrationStd s;
    s.rotation.setConstant(1e-5);
    s.translation.setConstant(1e-5);
    s.timeshift_cam_imu = 1e-6;
    s.intrinsics.setConstant(0.1);
    s.distortion_coeffs.setConstant(1e-4);
    c.std = s;
  }
  for (std::size_t i = 1; i < rig.inertial.size(); ++i)
    rig.inertial[i].std = InertialCalibrationStd();
  // cam1 (752x480) sees corners in the middle only; then everywhere but the lower-left corner.
  const auto frame = [&](double u0, double u1, double v0, double v1) {
    TagFrame f;
    f.camera = 1;
    for (double u = u0; u < u1; u += 4.0) {
      for (double v = v0; v < v1; v += 4.0) {
        TagObservation t;
        t.corners_px = {Eigen::Vector2d(u, v), Eigen::Vector2d(u, v), Eigen::Vector2d(u, v),
                        Eigen::Vector2d(u, v)};
        f.tags.push_back(t);
      }
    }
    return f;
  };
  tracker.addFrame(frame(200, 550, 150, 330));
  for (int k = 0; k <= 6; ++k) tracker.update(k * kSecond, rig, {});
  const QuantityState* d = find(tracker.states(), "cam1", "distortion");
  EXPECT_EQ(d->status, QuantityStatus::kImproving);
  EXPECT_EQ(d->advice, "bring the board to the image's upper-left corner of cam1");
  tracker.addFrame(frame(0, 752, 0, 400));      // all but the bottom rows
  tracker.addFrame(frame(100, 752, 400, 480));  // the bottom rows but their left end
  tracker.update(7 * kSecond, rig, {});
  EXPECT_EQ(tracker.coverage()[1].missing(), "the image's lower-left corner");
  EXPECT_NE(d->advice.find("lower-left corner"), std::string::npos) << d->advice;
  tracker.addFrame(frame(0, 100, 400, 480));
  tracker.update(8 * kSecond, rig, {});
  EXPECT_EQ(tracker.coverage()[1].missing(), "");
  EXPECT_EQ(d->status, QuantityStatus::kConverged);
  // The other cameras saw nothing: not converged, named.
  EXPECT_EQ(find(tracker.states(), "cam0", "intrinsics")->status, QuantityStatus::kImproving);
}

}  // namespace
}  // namespace mvis
