// Without a board (no aprilgrid.yaml, report Eq. 11): the simulated VI-Rig's tags are unknown
// landmarks. The estimator must calibrate the cameras and auxiliary sensors as with the board,
// find the tags' geometry (up to the world frame, which it chooses: gravity along -z at the
// first state) with the right size, and a trajectory that matches the truth after the one rigid
// transform that maps its tags onto the board.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <iterator>
#include <utility>
#include <vector>

#include "estimator_test_util.h"
#include "mvis/sim/trajectory.h"

namespace mvis {
namespace {

using test::CameraErrors;
using test::deterministic;
using test::errors;
using test::inertialErrors;
using test::SimRun;
using test::simulate;

// An estimator for `run`'s rig without its board (tags as landmarks), detections' noise.
std::unique_ptr<Estimator> withoutBoard(const SimRun& run, int carried_tags = -1,
                                        bool own_tags = true) {
  Rig guess = run.guess;
  guess.target.reset();
  EstimatorOptions options = deterministic();
  options.pixel_sigma_px = 0.5;
  if (carried_tags >= 0) options.carried_tags = carried_tags;
  options.window_own_tags = own_tags;
  auto created = Estimator::create(guess, options);
  EXPECT_TRUE(created.ok()) << created.status().message();
  return created.ok() ? std::move(created).value() : nullptr;
}

// Every camera and auxiliary sensor of `estimate` against the truth, within the bounds of a
// 15 s run without the board (printed with `label`).
void expectCalibratedWithoutBoard(const SimRun& run, const Rig& estimate, const char* label,
                                  double camera_translation_mm = 1.5) {
  for (std::size_t c = 0; c < run.truth.cameras.size(); ++c) {
    const CameraErrors after = errors(run.truth.cameras[c], estimate.cameras[c]);
    std::printf("%s%s: %.4f deg, %.3f mm, %.4f ms; error/sigma rot %.2f pos %.2f dt %.2f\n", label,
                run.truth.cameras[c].name.c_str(), after.rotation_deg, after.translation_mm,
                after.time_offset_ms, after.rotation_sigma_ratio.maxCoeff(),
                after.translation_sigma_ratio.maxCoeff(), after.time_offset_sigma_ratio);
    test::expectCalibrated(after, run.truth.cameras[c].name, 0.05, camera_translation_mm, 0.15);
  }
  for (std::size_t i = 1; i < run.truth.inertial.size(); ++i) {
    const CameraErrors after = inertialErrors(run.truth.inertial[i], estimate.inertial[i]);
    test::expectCalibrated(after, run.truth.inertial[i].name, 0.1, 3.0, 0.15);
  }
}

TEST(EstimatorLandmarks, CalibratesWithTagCornersAsLandmarks) {
  const SimRun run = simulate("sim_vi_rig", 15.0, 3);
  const AprilGrid board = *run.guess.target;
  std::unique_ptr<Estimator> estimator = withoutBoard(run);
  ASSERT_TRUE(estimator);
  Eigen::Vector3d gravity_G = Eigen::Vector3d::Zero();
  estimator->setUpdateCallback([&](const EstimatorUpdate& u) { gravity_G = u.gravity_G; });
  test::feed(run, estimator.get());
  ASSERT_TRUE(estimator->initialized()) << estimator->status();
  ASSERT_TRUE(estimator->computeCovariance().ok());
  const Rig estimate = estimator->calibration();
  // Measured (seed 3, 15 s, 12 tags carried, the first batch's cut states with those 12 alone):
  // 0.012-0.025 deg, 0.50-0.71 mm, 0.028-0.058 ms, at most 1.6 sigma (with every tag in the cut
  // states 0.009-0.017 deg, 0.74-1.02 mm, 0.033-0.059 ms, 1.4 sigma; every tag carried, 12
  // corners each: 0.007-0.012 deg, 0.81-1.02 mm, 0.042-0.069 ms, 1.8 sigma);
  // with the board (test_estimator, 20 s): <= 0.013 deg, 0.44 mm, 0.043 ms. The time offsets'
  // bound is their 3 sigma after 15 s.
  expectCalibratedWithoutBoard(run, estimate, "");

  // The tags still in the window against the board: one rigid transform (no scale) maps them.
  const auto landmarks = estimator->landmarks();
  ASSERT_GE(landmarks.size(), 10u);
  Eigen::Matrix3Xd est(3, 4 * landmarks.size()), ref(3, 4 * landmarks.size());
  double side = 0.0;
  int col = 0;
  for (const auto& [id, corners] : landmarks) {
    for (int k = 0; k < 4; ++k, ++col) {
      est.col(col) = corners[k];
      ref.col(col) = board.corner(id, k);
      side += (corners[k] - corners[(k + 1) % 4]).norm() / (4.0 * landmarks.size());
    }
  }
  const Eigen::Matrix4d T = Eigen::umeyama(est, ref, false);
  const SE3 T_board_G = SE3::fromMatrix(T);
  double corner_rms = 0.0;
  for (int i = 0; i < col; ++i) corner_rms += (T_board_G * est.col(i) - ref.col(i)).squaredNorm();
  corner_rms = std::sqrt(corner_rms / col);
  std::printf("%zu tags: corners %.3f mm RMS off the board, side %.3f mm (true %.3f)\n",
              landmarks.size(), corner_rms * 1e3, side * 1e3, board.tag_size * 1e3);
  // Measured: 0.24 mm RMS over the 12 tags carried at the end (every tag carried, 12 corners
  // each: 0.34 mm over 36), the side 0.002 mm short. The scale comes from the accelerometer alone: a 1% scale
  // error would be 0.9 mm on the side.
  EXPECT_LT(corner_rms, 1e-3);
  EXPECT_NEAR(side, board.tag_size, 2e-4);
  // Gravity, estimated in the world frame (-z at the start), mapped onto the board: the
  // simulator's.
  const Eigen::Vector3d g_board = T_board_G.rotation() * gravity_G;
  std::printf("gravity: %.2f deg off the truth, %.2f deg off -z of the world frame\n",
              std::acos(g_board.normalized().dot(kGravity_G.normalized())) * 180.0 / M_PI,
              std::acos(-gravity_G.normalized().z()) * 180.0 / M_PI);
  EXPECT_LT((g_board.normalized() - kGravity_G.normalized()).norm(), 1e-3);

  // The trajectory in the board frame, after the first 5 s.
  std::vector<EstimatorState> converged, own;
  const auto trajectory = estimator->trajectory();
  for (auto s : trajectory) {
    if (s.stamp_ns - trajectory.front().stamp_ns <= fromSeconds(5.0)) continue;
    own.push_back(s);
    s.T_G_I = T_board_G * s.T_G_I;
    converged.push_back(s);
  }
  const double ate = positionRmse(converged, run.truth_trajectory);
  const double aligned = positionRmse(own, run.truth_trajectory, true);
  std::printf(
      "ATE after 5 s, board frame by the tags' alignment: %.2f mm, best rigid fit %.2f mm\n",
      ate * 1e3, aligned * 1e3);
  // Measured 0.83 mm (0.96 with every tag in the first batch's cut states; every tag carried,
  // 12 corners each, 1.14; with the board, 20 s: about 1 mm). The best rigid fit of the
  // trajectory itself (positionRmse's alignment) cannot do worse than the tags' transform.
  EXPECT_LT(ate, 3e-3);
  EXPECT_LE(aligned, ate);
}

// Feeds `run` to `estimator` and returns the most tags carried in the prior and the most in the
// window over its solves ({-1, -1} when it did not initialize or its covariance failed).
std::pair<int, int> mostTags(const SimRun& run, Estimator* estimator) {
  int most_carried = 0, most_landmarks = 0;
  estimator->setUpdateCallback([&](const EstimatorUpdate& u) {
    most_carried = std::max(most_carried, u.solve.carried_landmarks);
    most_landmarks = std::max(most_landmarks, u.solve.landmarks);
  });
  test::feed(run, estimator);
  if (!estimator->initialized() || !estimator->computeCovariance().ok()) return {-1, -1};
  return {most_carried, most_landmarks};
}

// The prior carries at most carried_tags tags (the rest are the window's own, marginalized with
// every observation of them when the oldest state that sees them leaves): with 4 of the 36, the
// calibration is still found within the bounds of the test above.
TEST(EstimatorLandmarks, CarriesAtMostTheConfiguredTags) {
  const SimRun run = simulate("sim_vi_rig", 15.0, 3);
  std::unique_ptr<Estimator> estimator = withoutBoard(run, 4);
  ASSERT_TRUE(estimator);
  const auto [most_carried, most_landmarks] = mostTags(run, estimator.get());
  ASSERT_GE(most_carried, 0) << estimator->status();
  std::printf("at most %d tags carried of %d in the window\n", most_carried, most_landmarks);
  EXPECT_EQ(most_carried, 4);
  EXPECT_GE(most_landmarks, 30);  // nearly every tag of the board is in view at some point
  // Measured: 0.017-0.026 deg, 1.38-1.56 mm, 0.069-0.093 ms, at most 1.7 sigma (with a 4-state
  // window 0.006-0.032 deg, 0.96-1.34 mm). Over 12 runs of this kind (`scripts/monte_carlo 12
  // --no-board --duration 15 -- --carried-tags 4`) the cameras' translations end 1.21-1.28 mm
  // off on average and at most 1.88 mm (a 4-state window: 1.40-1.48, at most 2.55 mm), so the
  // other tests' 1.5 mm is a seed's luck here. Bound: 2 mm, and 3 sigma per axis.
  expectCalibratedWithoutBoard(run, estimator->calibration(), "carrying 4 tags, ", 2.0);
}

// With window_own_tags off the tags beyond the carried ones are left out: the window never holds
// more than the carried tags, and they alone calibrate the rig.
TEST(EstimatorLandmarks, LeavesOutTheTagsBeyondTheCarriedOnes) {
  const SimRun run = simulate("sim_vi_rig", 15.0, 3);
  std::unique_ptr<Estimator> estimator = withoutBoard(run, 12, false);
  ASSERT_TRUE(estimator);
  const auto [most_carried, most_landmarks] = mostTags(run, estimator.get());
  ASSERT_GE(most_carried, 0) << estimator->status();
  std::printf("own tags left out: at most %d tags carried of %d in the window\n", most_carried,
              most_landmarks);
  EXPECT_EQ(most_carried, 12);
  EXPECT_EQ(most_landmarks, 12);  // with the window's own tags: 36
  // Measured: 0.011-0.025 deg, 0.55-0.76 mm, 0.024-0.077 ms, at most 1.4 sigma (with the own
  // tags, CalibratesWithTagCornersAsLandmarks: 0.012-0.025 deg, 0.50-0.71 mm, 0.028-0.058 ms).
  expectCalibratedWithoutBoard(run, estimator->calibration(), "own tags left out, ");
}

// A rig among scattered tags often sees one at a time: every frame keeps only one of two tags at
// opposite corners of the board (tag 0 if seen, else tag 35), so most frames carry one tag.
TEST(EstimatorLandmarks, StartsAndCalibratesOnOneTagPerFrame) {
  SimRun run = simulate("sim_vi_rig", 20.0, 4);
  run.guess.target.reset();
  int kept = 0;
  for (auto& frame : run.data.frames) {
    std::vector<TagObservation> one;
    for (int id : {0, 35}) {
      for (const auto& tag : frame.tags) {
        if (tag.tag_id == id && one.empty()) one.push_back(tag);
      }
    }
    frame.tags = one;
    kept += one.empty() ? 0 : 1;
  }
  ASSERT_GT(kept, static_cast<int>(run.data.frames.size()) / 2);
  EstimatorOptions options = deterministic();
  options.pixel_sigma_px = 0.5;
  auto estimator = test::runFrom(run.guess, run, options);
  ASSERT_TRUE(estimator);
  EXPECT_EQ(estimator->counters().frames_too_few_tags,
            static_cast<long>(run.data.frames.size()) - kept);
  const Rig estimate = estimator->calibration();
  for (std::size_t c = 0; c < run.truth.cameras.size(); ++c) {
    const CameraErrors after = errors(run.truth.cameras[c], estimate.cameras[c]);
    std::printf(
        "one tag per frame, %s: %.4f deg, %.3f mm, %.4f ms; error/sigma rot %.2f pos %.2f "
        "dt %.2f\n",
        run.truth.cameras[c].name.c_str(), after.rotation_deg, after.translation_mm,
        after.time_offset_ms, after.rotation_sigma_ratio.maxCoeff(),
        after.translation_sigma_ratio.maxCoeff(), after.time_offset_sigma_ratio);
    // Measured (seed 4): 0.03-0.11 deg, 0.6-1.9 mm, 0.03-0.14 ms, at most 2.6 sigma (sigma
    // about 0.04 deg, 1.2 mm, 0.09 ms with one tag's corners per frame): bounds above 3 sigma.
    // With two tags needed per frame (the board's min_tags) it never starts.
    test::expectCalibrated(after, run.truth.cameras[c].name, 0.2, 5.0, 0.5);
  }
}

// The first batch weighs its frames with a loss per frame, for the rough starting calibration's
// residuals, which counts a clean frame of N corners like about 3 sqrt(N/2) of them. What it
// leaves in the prior must be every clean corner's information, as every later frame's: without
// a board each later pose stands on it. On clean data the first pose covariance after the batch
// is then the one plain squares give (the loss per corner at 3 sigma hardly acts on 0.5 px
// noise). Measured: every standard deviation within 0.9% of plain squares' (before the
// batch's clean frames took the loss per corner: 10-24% larger).
TEST(EstimatorLandmarks, FirstBatchLeavesEveryCleanCornersInformation) {
  const SimRun run = simulate("sim_vi_rig", 6.0, 2);
  std::vector<Eigen::Matrix<double, 6, 1>> first_std;
  for (const double huber : {3.0, 0.0}) {
    Rig guess = run.guess;
    guess.target.reset();
    EstimatorOptions options = deterministic();
    options.pixel_sigma_px = 0.5;
    options.huber_sigma = huber;
    auto created = Estimator::create(guess, options);
    ASSERT_TRUE(created.ok()) << created.status().message();
    std::unique_ptr<Estimator> estimator = std::move(created).value();
    Eigen::Matrix<double, 6, 1> std_dev = Eigen::Matrix<double, 6, 1>::Zero();
    estimator->setUpdateCallback([&](const EstimatorUpdate& u) {
      if (std_dev.isZero() && u.pose_covariance.allFinite()) {
        std_dev = u.pose_covariance.diagonal().cwiseSqrt();
      }
    });
    test::feed(run, estimator.get());
    ASSERT_TRUE(estimator->initialized()) << estimator->status();
    ASSERT_FALSE(std_dev.isZero());
    first_std.push_back(std_dev);
  }
  const Eigen::Matrix<double, 6, 1> ratio = first_std[0].cwiseQuotient(first_std[1]);
  std::printf("first pose std with the loss / plain squares: %.4f %.4f %.4f | %.4f %.4f %.4f\n",
              ratio(0), ratio(1), ratio(2), ratio(3), ratio(4), ratio(5));
  EXPECT_LT((ratio.array() - 1.0).abs().maxCoeff(), 0.05);
}

// Without a board the first state is the world frame: every pose's error and covariance are
// relative to it. The pose NEES stays near its 3 degrees of freedom. Seed 1 is the run whose
// position NEES was 11 when the auxiliary sensors took part in the first batch with their
// configured calibration held (doc/results.md, "Without the board").
TEST(EstimatorLandmarks, PoseCovarianceIsHonestWithoutTheBoard) {
  const SimRun run = simulate("sim_vi_rig", 30.0, 1);
  std::unique_ptr<Estimator> estimator = withoutBoard(run);
  ASSERT_TRUE(estimator);
  std::vector<std::pair<EstimatorState, Eigen::Matrix<double, 6, 6>>> poses;
  estimator->setUpdateCallback([&](const EstimatorUpdate& u) {
    if (u.pose_covariance.allFinite()) poses.emplace_back(u.state, u.pose_covariance);
  });
  test::feed(run, estimator.get());
  ASSERT_TRUE(estimator->initialized()) << estimator->status();
  const EstimatorState first = estimator->trajectory().front();
  // The truth in the estimate's world frame, through the first state (which the gauge holds).
  const SE3 T_est_true = first.T_G_I * test::truthAt(run.truth_trajectory, first.stamp_ns).inverse();
  double nees_rotation = 0.0, nees_position = 0.0;
  for (const auto& [state, covariance] : poses) {
    const SE3 truth = T_est_true * test::truthAt(run.truth_trajectory, state.stamp_ns);
    const Eigen::Vector3d dtheta = lie::logQuat(state.T_G_I.q.conjugate() * truth.q);
    const Eigen::Vector3d dp = truth.p - state.T_G_I.p;
    nees_rotation += dtheta.dot(covariance.topLeftCorner<3, 3>().ldlt().solve(dtheta));
    nees_position += dp.dot(covariance.bottomRightCorner<3, 3>().ldlt().solve(dp));
  }
  nees_rotation /= static_cast<double>(poses.size());
  nees_position /= static_cast<double>(poses.size());
  std::printf("pose NEES over %zu poses: orientation %.2f, position %.2f\n", poses.size(),
              nees_rotation, nees_position);
  ASSERT_GE(poses.size(), 15u);
  // The bound per run, [1.5, 6] for 3 degrees of freedom, on the side that matters: an
  // overconfident covariance. Measured 1.36 and 4.08 over 25 poses (1.90 and 3.65 before the
  // first batch's frames took the loss per corner; with the auxiliary sensors in the first batch
  // 7.35 and 12.93). One run's poses share most of their error (what the first states left
  // relative to the tags): over 24 runs of 60 s a consistent estimator's per-run NEES spreads
  // over about 1.0-5.5 (10-90%, doc/results.md), so only the upper side is asserted.
  EXPECT_LT(nees_rotation, 6.0);
  EXPECT_LT(nees_position, 6.0);
}

}  // namespace
}  // namespace mvis
