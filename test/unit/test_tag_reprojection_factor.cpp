// Tag reprojection factor on the simulated VI-Rig: at the true states it reproduces the true
// corner projections (to the interpolation's approximation error), and its Jacobians match
// central differences through the manifolds for both interpolations.
#include <ceres/sphere_manifold.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <functional>

#include "factor_test_util.h"
#include "mvis/camera/camera_model.h"
#include "mvis/factors/state_blocks.h"
#include "mvis/factors/tag_reprojection_factor.h"
#include "mvis/rig/rig_io.h"
#include "mvis/sim/imu_simulator.h"
#include "mvis/sim/rig_simulator.h"
#include "sim_test_util.h"

namespace mvis {
namespace {

struct Scene {
  Rig rig;
  SinusoidTrajectory trajectory = makeBoardTrajectory(Rig{}, MotionOptions{});
};

Scene makeScene(double timeshift_s) {
  Scene s;
  auto rig = loadRig(std::string(MVIS_SOURCE_DIR) + "/config/sim_vi_rig");
  EXPECT_TRUE(rig.ok()) << rig.status().message();
  s.rig = rig.value();
  for (auto& cam : s.rig.cameras) cam.timeshift_cam_imu = timeshift_s;
  s.trajectory = makeBoardTrajectory(s.rig, MotionOptions{});
  return s;
}

// True corner projections of camera c at camera-clock time t_c [s] (trajectory time base 0).
std::vector<CornerObservation> observe(const Scene& s, int c, double t_c) {
  const Camera& cam = s.rig.cameras[c];
  const TrajectoryState st = s.trajectory.evaluate(t_c + cam.timeshift_cam_imu);
  const SE3 T_C_G = cam.T_cam_imu * st.T_G_I.inverse();
  std::vector<CornerObservation> out;
  for (int id = 0; id < s.rig.target->numTags(); ++id) {
    for (int k = 0; k < 4; ++k) {
      CornerObservation o;
      o.p_G = s.rig.target->corner(id, k);
      if (!projectToPixel(cam, T_C_G * o.p_G, &o.uv)) continue;
      if (o.uv.x() < 0 || o.uv.y() < 0 || o.uv.x() > cam.resolution[0] - 1 ||
          o.uv.y() > cam.resolution[1] - 1) {
        continue;
      }
      out.push_back(o);
    }
  }
  return out;
}

std::vector<double> poseBlock(const SE3& T) {
  std::vector<double> b(7);
  se3ToPose(T, b.data());
  return b;
}

std::vector<double> intrinsicsBlock(const Camera& cam) {
  return {cam.intrinsics[0],        cam.intrinsics[1],        cam.intrinsics[2],
          cam.intrinsics[3],        cam.distortion_coeffs[0], cam.distortion_coeffs[1],
          cam.distortion_coeffs[2], cam.distortion_coeffs[3]};
}

double maxPixelError(const ceres::CostFunction& f, const std::vector<std::vector<double>>& blocks,
                     double sigma) {
  return test::evaluateResiduals(f, blocks).cwiseAbs().maxCoeff() * sigma;
}

TEST(TagReprojectionFactor, KinematicAtTruthReproducesProjections) {
  const Scene s = makeScene(0.004);
  const double t_c = 3.0, t_k = t_c + 0.004 - 0.003;  // the state 3 ms before the frame
  const auto corners = observe(s, 0, t_c);
  ASSERT_GT(corners.size(), 40u);
  const TrajectoryState sk = s.trajectory.evaluate(t_k);
  const double sigma = 0.5;
  std::unique_ptr<TagReprojectionFactor> f(TagReprojectionFactor::kinematic(
      s.rig.cameras[0].distortion_model, corners, sigma, t_c - t_k, sk.w_I));
  std::vector<double> sb(9, 0.0);
  Eigen::Map<Eigen::Vector3d>(sb.data()) = sk.v_G;
  const std::vector<std::vector<double>> blocks = {poseBlock(sk.T_G_I),
                                                   sb,
                                                   poseBlock(s.rig.cameras[0].T_cam_imu),
                                                   {0.004},
                                                   intrinsicsBlock(s.rig.cameras[0])};
  // Constant w and v over 3 ms: ~1/2 |a| dt^2 ~ 5 um at ~1 m, a few thousandths of a pixel.
  EXPECT_LT(maxPixelError(*f, blocks, sigma), 0.01);
}

TEST(TagReprojectionFactor, PoseBasedAtTruthReproducesProjections) {
  const Scene s = makeScene(-0.006);
  const double t_k = 5.0, interval = 1.0 / 30.0;
  const double t_c = t_k + 0.4 * interval + 0.006;  // base time t_k + 0.4 interval
  const auto corners = observe(s, 1, t_c);
  ASSERT_GT(corners.size(), 30u);
  const TrajectoryState sk = s.trajectory.evaluate(t_k),
                        sk1 = s.trajectory.evaluate(t_k + interval);
  const double sigma = 0.5;
  std::unique_ptr<TagReprojectionFactor> f(TagReprojectionFactor::poseBased(
      s.rig.cameras[1].distortion_model, corners, sigma, t_c - t_k, interval));
  const std::vector<std::vector<double>> blocks = {poseBlock(sk.T_G_I),
                                                   poseBlock(sk1.T_G_I),
                                                   poseBlock(s.rig.cameras[1].T_cam_imu),
                                                   {-0.006},
                                                   intrinsicsBlock(s.rig.cameras[1])};
  // Linear interpolation over 33 ms: ~|a| T^2 / 8 ~ 0.1 mm at ~1 m and 600 px focal length,
  // under 0.1 px; a wrong time-offset sign would move corners by several pixels.
  EXPECT_LT(maxPixelError(*f, blocks, sigma), 0.15);
}

// The IMU-propagated factor of camera c for a frame at camera time t_c, anchored at base time
// t_a (3 ms before the frame's true base time, as after a time-offset change), from state t_k.
// With `landmark_tag`, only that tag's corners, as landmark states (its block last).
std::unique_ptr<TagReprojectionFactor> imuPropagatedFactor(const Scene& s, int c, double t_k,
                                                           double t_c, double t_a,
                                                           const Eigen::Vector3d& bias_gyro,
                                                           const Eigen::Vector3d& bias_accel,
                                                           int landmark_tag = -1) {
  InertialSensor imu = s.rig.inertial[0];
  const TrajectoryFunction base = [&](double t) { return s.trajectory.evaluate(t); };
  ImuSimulationOptions noise_free;
  noise_free.noise = false;
  noise_free.biases = false;
  ImuPreintegration pre(imu.noise, bias_gyro, bias_accel);
  const TimeNs a = fromSeconds(t_k), b = fromSeconds(t_a);
  for (const auto& r : simulateImu(imu, base, 0, a, b, noise_free)) {
    pre.add({r.stamp_ns, r.gyro, r.accel});
  }
  // simulateImu samples at 500 Hz from t_k; end exactly at t_a.
  Eigen::Vector3d w, f;
  trueInertialMotion(imu, s.trajectory.evaluate(t_a), &w, &f);
  if (pre.endNs() != b) pre.add({b, w, f});
  const TagReprojectionFactor::ImuAnchor anchor =
      TagReprojectionFactor::makeAnchor(pre, t_c - t_a, w, f, s.trajectory.evaluate(t_a).dw_I);
  std::vector<CornerObservation> corners = observe(s, c, t_c);
  if (landmark_tag >= 0) {
    std::vector<CornerObservation> tag;
    for (auto& o : corners) {
      for (int k = 0; k < 4; ++k) {
        if ((o.p_G - s.rig.target->corner(landmark_tag, k)).norm() > 1e-12) continue;
        o.landmark = k;
        tag.push_back(o);
      }
    }
    corners = tag;
  }
  std::unique_ptr<TagReprojectionFactor> factor(TagReprojectionFactor::imuPropagated(
      s.rig.cameras[c].distortion_model, std::move(corners), 0.5, anchor));
  if (landmark_tag >= 0) factor->useLandmarkBlock();
  return factor;
}

std::vector<double> speedBiasBlock(const TrajectoryState& st);

// The IMU-propagated factor's blocks at the truth of state t_k for camera c, time offset t_d,
// then `extra` (the IMU intrinsics or a landmark block).
std::vector<std::vector<double>> trueImuPropagatedBlocks(const Scene& s, int c, double t_k,
                                                         double t_d, std::vector<double> extra) {
  const TrajectoryState sk = s.trajectory.evaluate(t_k);
  std::vector<std::vector<double>> blocks = {poseBlock(sk.T_G_I),
                                             speedBiasBlock(sk),
                                             {kGravity_G.x(), kGravity_G.y(), kGravity_G.z()},
                                             poseBlock(s.rig.cameras[c].T_cam_imu),
                                             {t_d},
                                             intrinsicsBlock(s.rig.cameras[c])};
  if (!extra.empty()) blocks.push_back(std::move(extra));
  return blocks;
}

std::vector<double> speedBiasBlock(const TrajectoryState& st) {
  std::vector<double> sb(9, 0.0);
  Eigen::Map<Eigen::Vector3d>(sb.data()) = st.v_G;
  return sb;
}

// Camera 2's IMU-propagated factor's blocks at the state of t_k, with speed, biases, gravity
// and time offset off the truth: where Jacobians are checked.
std::vector<std::vector<double>> offTruthImuPropagatedBlocks(const Scene& s, double t_k) {
  const TrajectoryState sk = s.trajectory.evaluate(t_k);
  const Eigen::Vector3d g = lie::expSO3(Eigen::Vector3d(0.03, -0.02, 0.0)) * kGravity_G;
  return {poseBlock(sk.T_G_I),
          {0.1, -0.2, 0.05, 0.01, -0.02, 0.015, 0.1, 0.2, -0.1},
          {g.x(), g.y(), g.z()},
          poseBlock(s.rig.cameras[2].T_cam_imu),
          {0.012},
          intrinsicsBlock(s.rig.cameras[2])};
}

TEST(TagReprojectionFactor, ImuPropagatedAtTruthReproducesProjections) {
  const Scene s = makeScene(-0.006);
  const double t_k = 5.0, t_c = t_k + 0.4 / 30.0 + 0.006;
  const double t_a = t_c - 0.006 - 0.003;  // anchored 3 ms early
  auto f =
      imuPropagatedFactor(s, 1, t_k, t_c, t_a, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  ASSERT_GT(f->corners().size(), 30u);
  const auto blocks = trueImuPropagatedBlocks(s, 1, t_k, -0.006, {});
  // Preintegration errs by ~1e-7 m over 13 ms and the second-order step by ~|jerk| dt^3 / 6
  // ~5e-9 m: far under 0.01 px (the pose-based interpolation above: ~0.1 px).
  EXPECT_LT(maxPixelError(*f, blocks, 0.5), 0.01);
}

TEST(TagReprojectionFactor, ImuPropagatedJacobiansMatchCentralDifferences) {
  const Scene s = makeScene(0.01);
  const double t_k = 7.0, t_c = t_k + 0.3 / 30.0 - 0.01, t_a = t_c + 0.01 - 0.004;
  auto f = imuPropagatedFactor(s, 2, t_k, t_c, t_a, Eigen::Vector3d(1e-3, -2e-3, 5e-4),
                               Eigen::Vector3d(0.02, -0.01, 0.03));
  const std::vector<std::vector<double>> blocks = offTruthImuPropagatedBlocks(s, t_k);
  const PoseManifold pose;
  const ceres::SphereManifold<3> sphere;
  const std::vector<const ceres::Manifold*> manifolds = {&pose, nullptr, &sphere,
                                                         &pose, nullptr, nullptr};
  EXPECT_LT(test::jacobianMismatch(test::analyticTangentJacobians(*f, blocks, manifolds),
                                   test::numericTangentJacobians(*f, blocks, manifolds, 1e-6)),
            1e-5);
}

// Gauss-Newton's view of a factor at `blocks`: J^T J, J^T r (tangent Jacobians of every block
// but `skip`) and |r|^2.
struct NormalEquations {
  Eigen::MatrixXd H;
  Eigen::VectorXd g;
  double squares = 0.0;
};

NormalEquations normalEquations(const ceres::CostFunction& f,
                                const std::vector<std::vector<double>>& blocks,
                                const std::vector<const ceres::Manifold*>& manifolds,
                                int skip = -1) {
  Eigen::VectorXd r;
  const std::vector<Eigen::MatrixXd> J =
      test::analyticTangentJacobians(f, blocks, manifolds, &r, skip);
  int n = 0;
  for (const auto& b : J) n += static_cast<int>(b.cols());
  Eigen::MatrixXd stacked(f.num_residuals(), n);
  n = 0;
  for (const auto& b : J) {
    stacked.middleCols(n, b.cols()) = b;
    n += static_cast<int>(b.cols());
  }
  return {stacked.transpose() * stacked, stacked.transpose() * r, r.squaredNorm()};
}

// A compressed factor (15 rows, or 7 without the camera intrinsics: block `intrinsics` left
// out) has the plain one's J^T J, J^T r and cost, with and without Jacobians; the bound is
// rounding relative to the largest entry (an error in a block's map or the residual would be of
// the order of the entries).
void expectCompressedKeepsTheNormalEquations(
    const std::function<std::unique_ptr<TagReprojectionFactor>()>& make,
    const std::vector<std::vector<double>>& blocks,
    const std::vector<const ceres::Manifold*>& manifolds, int intrinsics) {
  const auto plain = make();
  ASSERT_GT(plain->num_residuals(), 3 * TagReprojectionFactor::kMaxCompressedRows);
  for (const bool with_intrinsics : {true, false}) {
    const auto compressed = make();
    ASSERT_TRUE(compressed->compressRows(with_intrinsics));
    EXPECT_EQ(compressed->num_residuals(), with_intrinsics ? 15 : 7);
    const int skip = with_intrinsics ? -1 : intrinsics;
    const NormalEquations a = normalEquations(*plain, blocks, manifolds, skip),
                          b = normalEquations(*compressed, blocks, manifolds, skip);
    ASSERT_GT(a.squares, 1.0);
    const double h = a.H.cwiseAbs().maxCoeff(), g = a.g.cwiseAbs().maxCoeff();
    EXPECT_LT((a.H - b.H).cwiseAbs().maxCoeff(), 1e-10 * h) << with_intrinsics;
    EXPECT_LT((a.g - b.g).cwiseAbs().maxCoeff(), 1e-10 * g) << with_intrinsics;
    EXPECT_NEAR(a.squares, b.squares, 1e-10 * a.squares);
    EXPECT_NEAR(a.squares, test::evaluateResiduals(*compressed, blocks).squaredNorm(),
                1e-12 * a.squares);
  }
  // Without the intrinsics, asking for their Jacobian fails rather than giving a wrong one.
  const auto compressed = make();
  compressed->compressRows(false);
  std::vector<const double*> params;
  std::vector<test::RowMatrix> ambient;
  std::vector<double*> jac;
  for (const auto& b : blocks) {
    params.push_back(b.data());
    ambient.emplace_back(7, static_cast<int>(b.size()));
  }
  for (auto& a : ambient) jac.push_back(a.data());
  Eigen::VectorXd r(7);
  EXPECT_FALSE(compressed->Evaluate(params.data(), r.data(), jac.data()));
}

// The per-corner Huber loss: corners within the threshold keep their residuals, the others
// shrink to |r'|^2 = 2 c n - c^2 along the same direction, and the Jacobians match central
// differences (the threshold between two corners' norms, so that no corner sits on the kink).
TEST(TagReprojectionFactor, CornerLossIsHuberPerCorner) {
  const Scene s = makeScene(0.01);
  const double t_k = 7.0, t_c = t_k + 0.3 / 30.0 - 0.01, t_a = t_c + 0.01 - 0.004;
  const Eigen::Vector3d bg(1e-3, -2e-3, 5e-4), ba(0.02, -0.01, 0.03);
  auto plain = imuPropagatedFactor(s, 2, t_k, t_c, t_a, bg, ba);
  auto robust = imuPropagatedFactor(s, 2, t_k, t_c, t_a, bg, ba);
  const std::vector<std::vector<double>> blocks = offTruthImuPropagatedBlocks(s, t_k);
  const Eigen::VectorXd r = test::evaluateResiduals(*plain, blocks);
  const int n_corners = static_cast<int>(r.size() / 2);
  std::vector<double> norms;
  for (int k = 0; k < n_corners; ++k) norms.push_back(r.segment<2>(2 * k).norm());
  std::sort(norms.begin(), norms.end());
  ASSERT_GT(norms[n_corners / 2] - norms[n_corners / 2 - 1], 1e-4);  // no corner on the kink
  const double c = 0.5 * (norms[n_corners / 2 - 1] + norms[n_corners / 2]);
  robust->useCornerLoss(c);
  const Eigen::VectorXd rr = test::evaluateResiduals(*robust, blocks);
  int shrunk = 0;
  for (int k = 0; k < n_corners; ++k) {
    const Eigen::Vector2d a = r.segment<2>(2 * k), b = rr.segment<2>(2 * k);
    const double n = a.norm();
    if (n <= c) {
      EXPECT_EQ((a - b).norm(), 0.0) << k;
      continue;
    }
    ++shrunk;
    EXPECT_NEAR(b.squaredNorm(), 2.0 * c * n - c * c, 1e-12 * n * n) << k;
    EXPECT_NEAR(a.normalized().dot(b.normalized()), 1.0, 1e-12) << k;
  }
  EXPECT_EQ(shrunk, n_corners - n_corners / 2);
  const PoseManifold pose;
  const ceres::SphereManifold<3> sphere;
  const std::vector<const ceres::Manifold*> manifolds = {&pose, nullptr, &sphere,
                                                         &pose, nullptr, nullptr};
  EXPECT_LT(test::jacobianMismatch(test::analyticTangentJacobians(*robust, blocks, manifolds),
                                   test::numericTangentJacobians(*robust, blocks, manifolds, 1e-6)),
            1e-5);
  // Compressed, with half the corners under the loss.
  expectCompressedKeepsTheNormalEquations(
      [&] {
        auto f = imuPropagatedFactor(s, 2, t_k, t_c, t_a, bg, ba);
        f->useCornerLoss(c);
        return f;
      },
      blocks, manifolds, 5);
}

// The readings' noise over [t_k, t_a] as a block: at zero it changes nothing, a position noise
// is the anchor moved by R_k n_p (the same residuals as state k's position moved by it), and the
// Jacobians, the noise block's included, match central differences away from zero.
TEST(TagReprojectionFactor, ImuPropagatedWithPropagationNoise) {
  const Scene s = makeScene(0.01);
  const double t_k = 7.0, t_c = t_k + 0.3 / 30.0 - 0.01, t_a = t_c + 0.01 - 0.004;
  const Eigen::Vector3d bg(1e-3, -2e-3, 5e-4), ba(0.02, -0.01, 0.03);
  auto plain = imuPropagatedFactor(s, 2, t_k, t_c, t_a, bg, ba);
  auto noisy = imuPropagatedFactor(s, 2, t_k, t_c, t_a, bg, ba);
  noisy->usePropagationNoise();
  ASSERT_EQ(noisy->parameter_block_sizes().size(), 7u);
  ASSERT_EQ(noisy->parameter_block_sizes().back(), kPropagationNoiseSize);
  const TrajectoryState sk = s.trajectory.evaluate(t_k);
  const std::vector<std::vector<double>> blocks = offTruthImuPropagatedBlocks(s, t_k);
  std::vector<std::vector<double>> with_noise = blocks;
  with_noise.push_back(std::vector<double>(kPropagationNoiseSize, 0.0));
  const Eigen::VectorXd r_plain = test::evaluateResiduals(*plain, blocks);
  EXPECT_LT((test::evaluateResiduals(*noisy, with_noise) - r_plain).cwiseAbs().maxCoeff(), 1e-12);
  // n_p = 2 mm: as if p_k had moved by R_k n_p; and it does move the corners (~1 px).
  const Eigen::Vector3d n_p(0.002, -0.001, 0.0015);
  for (int i = 0; i < 3; ++i) with_noise.back()[3 + i] = n_p[i];
  std::vector<std::vector<double>> moved = blocks;
  Eigen::Map<Eigen::Vector3d>(moved[0].data() + 4) += sk.T_G_I.q * n_p;
  const Eigen::VectorXd r_noise = test::evaluateResiduals(*noisy, with_noise);
  EXPECT_LT((r_noise - test::evaluateResiduals(*plain, moved)).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_GT((r_noise - r_plain).cwiseAbs().maxCoeff(), 1.0);  // whitened: 0.5 px
  with_noise.back() = {2e-3, -1e-3, 3e-3, 0.002, -0.001, 0.0015, 0.01, -0.02, 0.005};
  const PoseManifold pose;
  const ceres::SphereManifold<3> sphere;
  const std::vector<const ceres::Manifold*> manifolds = {&pose,   nullptr, &sphere, &pose,
                                                         nullptr, nullptr, nullptr};
  EXPECT_LT(
      test::jacobianMismatch(test::analyticTangentJacobians(*noisy, with_noise, manifolds),
                             test::numericTangentJacobians(*noisy, with_noise, manifolds, 1e-6)),
      1e-5);
}

// Without a board the corners are landmark states (report Eq. 11): at the true corners the
// factor reproduces the projections, and its Jacobians, the landmark block's included, match
// central differences away from the truth.
TEST(TagReprojectionFactor, LandmarkCornersAsStates) {
  const Scene s = makeScene(0.01);
  const double t_k = 7.0, t_c = t_k + 0.3 / 30.0 - 0.01, t_a = t_c + 0.01 - 0.004;
  const int tag = 14;  // near the board's centre: all four corners in view
  auto f = imuPropagatedFactor(s, 2, t_k, t_c, t_a, Eigen::Vector3d::Zero(),
                               Eigen::Vector3d::Zero(), tag);
  ASSERT_EQ(f->corners().size(), 4u);
  ASSERT_EQ(f->parameter_block_sizes().back(), kTagLandmarkSize);
  std::vector<double> landmark(kTagLandmarkSize);
  for (int k = 0; k < 4; ++k) {
    Eigen::Map<Eigen::Vector3d>(landmark.data() + 3 * k) = s.rig.target->corner(tag, k);
  }
  std::vector<std::vector<double>> blocks = trueImuPropagatedBlocks(s, 2, t_k, 0.01, landmark);
  EXPECT_LT(maxPixelError(*f, blocks, 0.5), 0.01);
  // A corner 5 mm off moves its projection by pixels, and only its own.
  blocks[6][3 * 2 + 1] += 0.005;
  const Eigen::VectorXd r = test::evaluateResiduals(*f, blocks) * 0.5;
  EXPECT_GT(std::abs(r[2 * 2]) + std::abs(r[2 * 2 + 1]), 1.0);
  EXPECT_LT(std::max(r.head<4>().cwiseAbs().maxCoeff(), r.tail<2>().cwiseAbs().maxCoeff()), 0.01);
  blocks[1] = {0.1, -0.2, 0.05, 0.01, -0.02, 0.015, 0.1, 0.2, -0.1};
  for (int k = 0; k < kTagLandmarkSize; ++k) blocks[6][k] += 0.01 * std::sin(1.0 + k);
  const PoseManifold pose;
  const ceres::SphereManifold<3> sphere;
  const std::vector<const ceres::Manifold*> manifolds = {&pose,   nullptr, &sphere, &pose,
                                                         nullptr, nullptr, nullptr};
  const auto analytic = test::analyticTangentJacobians(*f, blocks, manifolds);
  EXPECT_LT(
      test::jacobianMismatch(analytic, test::numericTangentJacobians(*f, blocks, manifolds, 1e-6)),
      1e-5);
  // Sharing the frame's camera pose with another tag's factor changes nothing: after the other
  // factor filled it at these values, and after it was filled at other values.
  auto other = imuPropagatedFactor(s, 2, t_k, t_c, t_a, Eigen::Vector3d::Zero(),
                                   Eigen::Vector3d::Zero(), tag + 1);
  const auto shared = TagReprojectionFactor::makeSharedCameraPose();
  f->shareCameraPose(shared);
  other->shareCameraPose(shared);
  test::analyticTangentJacobians(*other, blocks, manifolds);
  EXPECT_EQ(test::jacobianMismatch(test::analyticTangentJacobians(*f, blocks, manifolds), analytic),
            0.0);
  std::vector<std::vector<double>> moved = blocks;
  moved[4][0] += 1e-3;
  test::analyticTangentJacobians(*other, moved, manifolds);
  EXPECT_EQ(test::jacobianMismatch(test::analyticTangentJacobians(*f, blocks, manifolds), analytic),
            0.0);
}

// With the IMU intrinsics (readings made with Table 4 intrinsics): the anchor from the raw
// readings re-integrated at them reproduces the projections, and the Jacobians, the intrinsics
// block's included, match central differences with that block moved off the anchor's point.
TEST(TagReprojectionFactor, ImuPropagatedWithImuIntrinsics) {
  const Scene s = makeScene(0.01);
  const double t_k = 7.0, t_c = t_k + 0.3 / 30.0 - 0.01, t_a = t_c + 0.01 - 0.004;
  InertialSensor imu = s.rig.inertial[0];
  imu.intrinsics = test::tableFourIntrinsics();
  std::vector<ImuMeasurement> readings = test::noiseFreeReadings(imu, s.trajectory, t_k, t_a);
  // The reading at exactly t_a, through the model (report Eq. 1-2).
  Eigen::Vector3d w, f;
  trueInertialMotion(imu, s.trajectory.evaluate(t_a), &w, &f);
  const ImuIntrinsics& in = imu.intrinsics;
  if (readings.back().stamp_ns != fromSeconds(t_a)) {
    readings.push_back({fromSeconds(t_a), in.Tw * w + in.Tg * f, in.Ta * in.R_IMUtoACC * f});
  }
  const std::vector<double> truth = test::intrinsicsBlock(in);
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  const ImuDeltas d = reintegrate(readings, deltaVariables(zero.data(), zero.data(), truth.data()),
                                  ImuIntrinsicsFrame(), true);
  const TagReprojectionFactor::ImuAnchor anchor =
      TagReprojectionFactor::makeAnchor(d, true, t_c - t_a, w, f, s.trajectory.evaluate(t_a).dw_I);
  std::unique_ptr<TagReprojectionFactor> factor(TagReprojectionFactor::imuPropagated(
      s.rig.cameras[2].distortion_model, observe(s, 2, t_c), 0.5, anchor));
  std::vector<std::vector<double>> blocks = trueImuPropagatedBlocks(s, 2, t_k, 0.01, truth);
  // As without intrinsics (ImuPropagatedAtTruthReproducesProjections); intrinsics 2e-3 off
  // per element move the corners by more (the factor does depend on them).
  EXPECT_LT(maxPixelError(*factor, blocks, 0.5), 0.01);
  for (int k = 0; k < kImuIntrinsicsSize; ++k) blocks[6][k] += 2e-3 * std::cos(0.5 + k);
  EXPECT_GT(maxPixelError(*factor, blocks, 0.5), 0.02);
  blocks[1] = {0.1, -0.2, 0.05, 0.01, -0.02, 0.015, 0.1, 0.2, -0.1};
  const PoseManifold pose;
  const ceres::SphereManifold<3> sphere;
  const std::vector<const ceres::Manifold*> manifolds = {&pose,   nullptr, &sphere, &pose,
                                                         nullptr, nullptr, nullptr};
  EXPECT_LT(test::jacobianMismatch(test::analyticTangentJacobians(*factor, blocks, manifolds),
                                   test::numericTangentJacobians(*factor, blocks, manifolds, 1e-6)),
            1e-5);
  // With the propagation noise as well (both move the anchor's deltas).
  std::unique_ptr<TagReprojectionFactor> noisy(TagReprojectionFactor::imuPropagated(
      s.rig.cameras[2].distortion_model, observe(s, 2, t_c), 0.5, anchor));
  noisy->usePropagationNoise();
  blocks.push_back({2e-3, -1e-3, 3e-3, 0.002, -0.001, 0.0015, 0.01, -0.02, 0.005});
  std::vector<const ceres::Manifold*> with_noise = manifolds;
  with_noise.push_back(nullptr);
  EXPECT_LT(test::jacobianMismatch(test::analyticTangentJacobians(*noisy, blocks, with_noise),
                                   test::numericTangentJacobians(*noisy, blocks, with_noise, 1e-6)),
            1e-5);
  // Compressed: the intrinsics' and the noise's maps (the anchor's deltas' directions).
  expectCompressedKeepsTheNormalEquations(
      [&] {
        std::unique_ptr<TagReprojectionFactor> f(TagReprojectionFactor::imuPropagated(
            s.rig.cameras[2].distortion_model, observe(s, 2, t_c), 0.5, anchor));
        f->usePropagationNoise();
        return f;
      },
      blocks, with_noise, 5);
}

void checkJacobians(TagReprojectionFactor::Interpolation mode) {
  const Scene s = makeScene(0.01);
  const int c = mode == TagReprojectionFactor::Interpolation::kKinematic ? 0 : 2;
  const double t_k = 7.0, interval = 1.0 / 30.0, t_c = t_k + 0.3 * interval;
  const auto corners = observe(s, c, t_c);
  ASSERT_GT(corners.size(), 20u);
  const TrajectoryState sk = s.trajectory.evaluate(t_k),
                        sk1 = s.trajectory.evaluate(t_k + interval);
  const Camera& cam = s.rig.cameras[c];
  const auto make = [&] {
    return std::unique_ptr<TagReprojectionFactor>(
        mode == TagReprojectionFactor::Interpolation::kKinematic
            ? TagReprojectionFactor::kinematic(cam.distortion_model, corners, 0.5, t_c - t_k,
                                               sk.w_I)
            : TagReprojectionFactor::poseBased(cam.distortion_model, corners, 0.5, t_c - t_k,
                                               interval));
  };
  std::unique_ptr<TagReprojectionFactor> f = make();
  std::vector<std::vector<double>> blocks;
  std::vector<double> sb = {0.1, -0.2, 0.05, 0.01, -0.02, 0.015, 0.1, 0.2, -0.1};
  if (mode == TagReprojectionFactor::Interpolation::kKinematic) {
    blocks = {poseBlock(sk.T_G_I), sb, poseBlock(cam.T_cam_imu), {0.012}, intrinsicsBlock(cam)};
  } else {
    blocks = {poseBlock(sk.T_G_I),
              poseBlock(sk1.T_G_I),
              poseBlock(cam.T_cam_imu),
              {0.012},
              intrinsicsBlock(cam)};
  }
  const PoseManifold pose;
  const bool kinematic = mode == TagReprojectionFactor::Interpolation::kKinematic;
  const std::vector<const ceres::Manifold*> manifolds = {&pose, kinematic ? nullptr : &pose, &pose,
                                                         nullptr, nullptr};
  const auto analytic = test::analyticTangentJacobians(*f, blocks, manifolds);
  const auto numeric = test::numericTangentJacobians(*f, blocks, manifolds, 1e-6);
  // Residuals in sigma units up to ~1e2 (pixels / 0.5), Jacobians up to ~1e3 per radian:
  // central differences are good to ~1e-7 relative here.
  EXPECT_LT(test::jacobianMismatch(analytic, numeric), 1e-5);
  expectCompressedKeepsTheNormalEquations(make, blocks, manifolds, 4);
}

TEST(TagReprojectionFactor, KinematicJacobiansMatchCentralDifferences) {
  checkJacobians(TagReprojectionFactor::Interpolation::kKinematic);
}

TEST(TagReprojectionFactor, PoseBasedJacobiansMatchCentralDifferences) {
  checkJacobians(TagReprojectionFactor::Interpolation::kPoseBased);
}

}  // namespace
}  // namespace mvis
