// Base-IMU preintegration and its factor, against the simulator's exact trajectory:
// noise-free deltas reproduce the motion, the bias correction matches re-integration, the
// covariance matches closed forms and Monte-Carlo errors, the factor's Jacobians match
// central differences through the manifolds, and its intrinsics fitted to noisy readings at the
// true states are unbiased.
#include <ceres/ceres.h>
#include <ceres/sphere_manifold.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <deque>
#include <memory>

#include "factor_test_util.h"
#include "mvis/inertial/imu_preintegration.h"
#include "mvis/factors/state_blocks.h"
#include "mvis/factors/imu_factor.h"
#include "mvis/sim/imu_simulator.h"
#include "sim_test_util.h"

namespace mvis {
namespace {

using test::handheld;
using test::idealImu;

// Readings of `sensor` over [t_i, t_j] seconds (base clock, t0 = 0), preintegrated.
ImuPreintegration preintegrate(const InertialSensor& sensor, const SinusoidTrajectory& trajectory,
                               double t_i, double t_j, const ImuSimulationOptions& options,
                               const Eigen::Vector3d& bg = Eigen::Vector3d::Zero(),
                               const Eigen::Vector3d& ba = Eigen::Vector3d::Zero()) {
  const TrajectoryFunction base = [&](double t) { return trajectory.evaluate(t); };
  ImuPreintegration pre(sensor.noise, bg, ba);
  for (const auto& s : simulateImu(sensor, base, 0, fromSeconds(t_i), fromSeconds(t_j), options)) {
    pre.add({s.stamp_ns, s.gyro, s.accel});
  }
  return pre;
}

ImuSimulationOptions noiseFree() {
  ImuSimulationOptions o;
  o.noise = false;
  o.biases = false;
  return o;
}

TEST(ImuPreintegration, NoiseFreeDeltasReproduceTheTrajectory) {
  const auto trajectory = handheld();
  for (double rate : {200.0, 500.0}) {
    const ImuPreintegration pre = preintegrate(idealImu(rate), trajectory, 1.0, 1.1, noiseFree());
    ASSERT_NEAR(pre.duration(), 0.1, 1e-12);
    const TrajectoryState si = trajectory.evaluate(1.0), sj = trajectory.evaluate(1.1);
    Eigen::Quaterniond q;
    Eigen::Vector3d p, v;
    pre.predict(si.T_G_I.q, si.T_G_I.p, si.v_G, kGravity_G, &q, &p, &v);
    // The midpoint scheme errs by O(dt^2): measured 7e-6 m/s and 1.4e-6 m at 200 Hz (dt = 5 ms)
    // over 0.1 s, 100x below the noise over 0.1 s (6e-4 m/s); the bounds shrink by
    // (200 / 500)^2 at 500 Hz, which checks the order.
    const double scale = (rate == 200.0) ? 1.0 : 0.16;
    EXPECT_LT(lie::logQuat(sj.T_G_I.q.conjugate() * q).norm(), 2e-6 * scale) << rate;
    EXPECT_LT((v - sj.v_G).norm(), 1e-5 * scale) << rate;
    EXPECT_LT((p - sj.T_G_I.p).norm(), 2e-6 * scale) << rate;
  }
}

// readingIn's cubic reproduces a cubic signal (any spacing) where linear interpolation cannot;
// next to the buffer's ends or a gap it falls back to linear.
TEST(ImuReadings, CubicInterpolationIsExactForACubic) {
  const auto signal = [](double t) {
    return Eigen::Vector3d(1.0 + 2.0 * t - 3.0 * t * t + 40.0 * t * t * t, 0.5 - t * t * t,
                           3.0 * t * t);
  };
  std::deque<ImuMeasurement> buffer;
  for (const double t : {0.0, 0.011, 0.019, 0.031, 0.040, 0.052, 0.15, 0.16}) {
    ImuMeasurement m;
    m.stamp_ns = fromSeconds(t);
    m.gyro = signal(t);
    m.accel = 2.0 * signal(t);
    buffer.push_back(m);
  }
  const TimeNs max_interval = fromSeconds(0.025);
  for (const double t : {0.015, 0.025, 0.035}) {  // four regular readings around t
    const ImuMeasurement cubic = readingIn(buffer, fromSeconds(t), max_interval);
    const ImuMeasurement linear = readingIn(buffer, fromSeconds(t));
    EXPECT_LT((cubic.gyro - signal(t)).norm(), 1e-12) << t;
    EXPECT_LT((cubic.accel - 2.0 * signal(t)).norm(), 1e-12) << t;
    EXPECT_GT((linear.gyro - signal(t)).norm(), 3e-5) << t;
  }
  // The first interval (no reading before it) and the gap after 0.052 s: linear.
  for (const double t : {0.005, 0.045, 0.1}) {
    const TimeNs tn = fromSeconds(t);
    auto it = std::upper_bound(buffer.begin(), buffer.end(), tn,
                               [](TimeNs s, const ImuMeasurement& m) { return s < m.stamp_ns; });
    const ImuMeasurement linear = interpolateMeasurement(*(it - 1), *it, tn);
    const ImuMeasurement got = readingIn(buffer, tn, max_interval);
    EXPECT_EQ((got.gyro - linear.gyro).norm(), 0.0) << t;
    EXPECT_EQ(got.span_ns, linear.span_ns) << t;
  }
}

// readingsBetween in steps: every real reading inside, steps no longer than asked, none inside a
// gap (whose noise model counts its span once).
TEST(ImuReadings, StepsKeepEveryReadingAndSkipGaps) {
  std::deque<ImuMeasurement> buffer;
  for (int k = 0; k <= 30; ++k) {
    ImuMeasurement m;
    m.stamp_ns = fromSeconds(0.01 * k + (k > 20 ? 0.09 : 0.0));  // a 0.1 s hole after 0.2 s
    m.gyro = Eigen::Vector3d::Constant(0.1 * k);
    if (!buffer.empty()) m.span_ns = m.stamp_ns - buffer.back().stamp_ns;
    buffer.push_back(m);
  }
  const TimeNs a = fromSeconds(0.0333), b = fromSeconds(0.3333);
  const TimeNs step = fromSeconds(0.0025), max_interval = fromSeconds(0.025);
  const auto out = readingsBetween(buffer, a, b, step, max_interval);
  EXPECT_EQ(out.front().stamp_ns, a);
  EXPECT_EQ(out.back().stamp_ns, b);
  std::size_t real = 0;
  for (std::size_t i = 1; i < out.size(); ++i) {
    const TimeNs dt = out[i].stamp_ns - out[i - 1].stamp_ns;
    EXPECT_GT(dt, 0);
    const bool gap = out[i - 1].stamp_ns >= fromSeconds(0.2) && out[i].stamp_ns <= fromSeconds(0.3);
    if (gap) {
      EXPECT_EQ(dt, fromSeconds(0.1));
    } else {
      EXPECT_LE(dt, step) << i;
    }
  }
  for (const auto& m : buffer) {
    if (m.stamp_ns <= a || m.stamp_ns >= b) continue;
    ++real;
    EXPECT_TRUE(std::any_of(out.begin(), out.end(), [&](const ImuMeasurement& o) {
      return o.stamp_ns == m.stamp_ns && o.gyro == m.gyro && o.span_ns == m.span_ns;
    })) << m.stamp_ns;
  }
  EXPECT_EQ(real, 21u);  // 0.04 .. 0.2 s and 0.3 .. 0.33 s
}

// Slow readings (100 Hz) integrated in 2.5 ms steps on the cubic through them: the midpoint
// scheme's O(dt^2) error over 0.1 s of hand-held motion falls to the step's.
// Measured: position 5.5e-6 -> 3.4e-7 m, velocity 2.9e-5 -> 1.8e-6 m/s, (10 / 2.5)^2 = 16x.
TEST(ImuPreintegration, SlowReadingsInStepsReproduceTheTrajectory) {
  const auto trajectory = handheld();
  const TrajectoryFunction base = [&](double t) { return trajectory.evaluate(t); };
  std::deque<ImuMeasurement> buffer;
  for (const auto& s :
       simulateImu(idealImu(100.0), base, 0, fromSeconds(0.9), fromSeconds(1.2), noiseFree())) {
    buffer.push_back({s.stamp_ns, s.gyro, s.accel});
  }
  const TrajectoryState si = trajectory.evaluate(1.0), sj = trajectory.evaluate(1.1);
  double error_p[2], error_v[2];
  for (const int stepped : {0, 1}) {
    ImuPreintegration pre(idealImu(100.0).noise, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
    for (const auto& m : readingsBetween(buffer, fromSeconds(1.0), fromSeconds(1.1),
                                         stepped ? fromSeconds(0.0025) : 0, fromSeconds(0.025))) {
      pre.add(m);
    }
    Eigen::Quaterniond q;
    Eigen::Vector3d p, v;
    pre.predict(si.T_G_I.q, si.T_G_I.p, si.v_G, kGravity_G, &q, &p, &v);
    error_p[stepped] = (p - sj.T_G_I.p).norm();
    error_v[stepped] = (v - sj.v_G).norm();
    std::printf("%s: position %.2e m, velocity %.2e m/s\n", stepped ? "in steps" : "as they come",
                error_p[stepped], error_v[stepped]);
  }
  EXPECT_LT(error_p[1], error_p[0] / 10.0);
  EXPECT_LT(error_v[1], error_v[0] / 10.0);
}

TEST(ImuPreintegration, BiasCorrectionMatchesReintegration) {
  const auto trajectory = handheld();
  ImuPreintegration pre = preintegrate(idealImu(500.0), trajectory, 2.0, 2.2, noiseFree());
  const Eigen::Vector3d bg(2e-3, -1e-3, 1.5e-3), ba(2e-2, 1e-2, -3e-2);
  const Eigen::Quaterniond R1 = pre.correctedDeltaR(bg);
  const Eigen::Vector3d p1 = pre.correctedDeltaP(bg, ba), v1 = pre.correctedDeltaV(bg, ba);
  const Eigen::Quaterniond R0 = pre.deltaR();
  const Eigen::Vector3d p0 = pre.deltaP(), v0 = pre.deltaV();
  pre.repropagate(bg, ba);
  // First order: what remains is second order in the bias change, under 1% of the change.
  const double dR_change = lie::logQuat(R0.conjugate() * pre.deltaR()).norm();
  EXPECT_GT(dR_change, 1e-4);
  EXPECT_LT(lie::logQuat(R1.conjugate() * pre.deltaR()).norm(), 0.01 * dR_change);
  EXPECT_LT((p1 - pre.deltaP()).norm(), 0.01 * (p0 - pre.deltaP()).norm());
  EXPECT_LT((v1 - pre.deltaV()).norm(), 0.01 * (v0 - pre.deltaV()).norm());
}

TEST(ImuPreintegration, StationaryCovarianceMatchesClosedForm) {
  // At rest, level: w = 0, a = g. Rotation error is a random walk sigma_g^2 T; velocity error
  // sigma_a^2 T plus, across gravity, g^2 sigma_g^2 T^3 / 3 from the tilt error.
  ImuNoise noise{2e-3, 0.0, 1.7e-4, 0.0};
  ImuPreintegration pre(noise, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  const double rate = 200.0, T = 1.0, g = 9.81;
  for (int k = 0; k <= static_cast<int>(rate * T); ++k) {
    pre.add({fromSeconds(k / rate), Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, g)});
  }
  const auto& P = pre.covariance();
  const double sg2 = noise.gyroscope_noise_density * noise.gyroscope_noise_density;
  const double sa2 = noise.accelerometer_noise_density * noise.accelerometer_noise_density;
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(P(i, i), sg2 * T, 1e-9 * sg2 * T);
    const double expected = sa2 * T + (i < 2 ? g * g * sg2 * T * T * T / 3.0 : 0.0);
    // The discrete sum of k^2 dt^3 is T^3 / 3 to O(1 / N) = 0.5%.
    EXPECT_NEAR(P(6 + i, 6 + i), expected, 0.02 * expected) << i;
  }
}

TEST(ImuPreintegration, CovarianceMatchesMonteCarloErrors) {
  // Normalized squared error of [dtheta, dp, dv] over noisy runs: chi-square with 9 degrees of
  // freedom if the covariance is right. Mean over 400 runs: 9 +- 0.21 (1 sigma).
  const auto trajectory = handheld();
  InertialSensor sensor = idealImu(500.0);
  sensor.noise.accelerometer_random_walk = 0.0;  // no bias walk: the errors are white noise only
  sensor.noise.gyroscope_random_walk = 0.0;
  const ImuPreintegration truth = preintegrate(sensor, trajectory, 3.0, 3.1, noiseFree());
  double nees_sum = 0.0;
  const int runs = 400;
  for (int run = 0; run < runs; ++run) {
    ImuSimulationOptions options;
    options.biases = false;
    options.seed = 100 + run;
    const ImuPreintegration pre = preintegrate(sensor, trajectory, 3.0, 3.1, options);
    Eigen::Matrix<double, 9, 1> e;
    e << lie::logQuat(pre.deltaR().conjugate() * truth.deltaR()), truth.deltaP() - pre.deltaP(),
        truth.deltaV() - pre.deltaV();
    const Eigen::Matrix<double, 9, 9> P = pre.covariance().topLeftCorner<9, 9>();
    nees_sum += e.dot(P.ldlt().solve(e));
  }
  EXPECT_NEAR(nees_sum / runs, 9.0, 0.9);  // 4 sigma
}

struct ImuFactorFixture {
  std::shared_ptr<ImuPreintegration> pre;
  std::vector<std::vector<double>> blocks;
};

// Blocks at the true states of t_i, t_j (plus `bias` and an offset on the states).
ImuFactorFixture makeFixture(double offset) {
  const auto trajectory = handheld();
  ImuFactorFixture f;
  f.pre = std::make_shared<ImuPreintegration>(
      preintegrate(idealImu(500.0), trajectory, 4.0, 4.1, noiseFree()));
  const TrajectoryState si = trajectory.evaluate(4.0), sj = trajectory.evaluate(4.1);
  auto pose = [&](const TrajectoryState& s, double k) {
    std::vector<double> b(7);
    SE3 T = s.T_G_I;
    T.q = (T.q * lie::expQuat(Eigen::Vector3d(0.01, -0.02, 0.015) * k)).normalized();
    T.p += Eigen::Vector3d(0.02, 0.01, -0.03) * k;
    se3ToPose(T, b.data());
    return b;
  };
  auto speedBias = [&](const TrajectoryState& s, double k) {
    std::vector<double> b(9);
    Eigen::Map<Eigen::Vector3d>(b.data()) = s.v_G + Eigen::Vector3d(0.05, -0.02, 0.01) * k;
    Eigen::Map<Eigen::Vector3d>(b.data() + 3) = Eigen::Vector3d(1e-3, -2e-3, 5e-4) * k;
    Eigen::Map<Eigen::Vector3d>(b.data() + 6) = Eigen::Vector3d(0.02, 0.01, -0.03) * k;
    return b;
  };
  f.blocks = {pose(si, offset),
              speedBias(si, offset),
              pose(sj, -offset),
              speedBias(sj, -offset),
              {kGravity_G.x(), kGravity_G.y(), kGravity_G.z()}};
  // A tilted gravity when offset, so its tangent directions are generic.
  if (offset != 0.0) {
    const Eigen::Vector3d g = lie::expSO3(Eigen::Vector3d(0.05, -0.03, 0.0)) * kGravity_G;
    f.blocks[4] = {g.x(), g.y(), g.z()};
  }
  return f;
}

TEST(ImuFactor, ResidualAtTruthIsFarBelowNoise) {
  const ImuFactorFixture f = makeFixture(0.0);
  const ImuFactor factor(f.pre);
  // Whitened: a 1-sigma error would be ~1 per entry; midpoint integration leaves ~1e-2.
  EXPECT_LT(test::evaluateResiduals(factor, f.blocks).cwiseAbs().maxCoeff(), 0.05);
}

TEST(ImuFactor, JacobiansMatchCentralDifferences) {
  const ImuFactorFixture f = makeFixture(1.0);
  const ImuFactor factor(f.pre);
  const PoseManifold pose;
  const ceres::SphereManifold<3> sphere;
  const std::vector<const ceres::Manifold*> manifolds = {&pose, nullptr, &pose, nullptr, &sphere};
  const auto analytic = test::analyticTangentJacobians(factor, f.blocks, manifolds);
  const auto numeric = test::numericTangentJacobians(factor, f.blocks, manifolds, 1e-6);
  // Central differences with h = 1e-6: truncation ~h^2 |r'''| ~ 1e-9, round-off
  // ~1e-16 |r| / h ~ 1e-7 for whitened residuals up to ~1e3; entries are scaled by max(1, |J|).
  EXPECT_LT(test::jacobianMismatch(analytic, numeric), 1e-4);
}

// With the intrinsics block: readings made with Table 4 intrinsics, the block at them moved by
// a generic offset.
TEST(ImuFactor, WithIntrinsicsJacobiansMatchCentralDifferences) {
  const auto trajectory = handheld();
  InertialSensor sensor = idealImu(500.0);
  sensor.intrinsics = test::tableFourIntrinsics();
  ImuFactorFixture f = makeFixture(1.0);
  f.pre = std::make_shared<ImuPreintegration>(preintegrate(sensor, trajectory, 4.0, 4.1,
                                                           noiseFree(), Eigen::Vector3d(1e-3, 0, 0),
                                                           Eigen::Vector3d(0, 0.02, 0)));
  std::vector<double> block = test::intrinsicsBlock(sensor.intrinsics);
  for (int k = 0; k < kImuIntrinsicsSize; ++k) block[k] += 1e-3 * std::sin(1.0 + k);
  f.blocks.push_back(block);
  const PoseManifold pose;
  const ceres::SphereManifold<3> sphere;
  const std::vector<const ceres::Manifold*> manifolds = {&pose,   nullptr, &pose,
                                                         nullptr, &sphere, nullptr};
  ImuIntrinsicsFrame frame;
  frame.R0 = lie::expSO3(Eigen::Vector3d(0.02, 0.01, -0.03));
  for (auto mode : {IntrinsicsLinearization::kReintegrate, IntrinsicsLinearization::kFixed}) {
    // kFixed made at another point, so that its first-order correction is exercised.
    std::vector<double> made_at = block;
    made_at[0] += 2e-3;
    const ImuFactor factor(f.pre, frame, mode, made_at.data());
    const auto analytic = test::analyticTangentJacobians(factor, f.blocks, manifolds);
    const auto numeric = test::numericTangentJacobians(factor, f.blocks, manifolds, 1e-6);
    EXPECT_LT(test::jacobianMismatch(analytic, numeric), 1e-4) << static_cast<int>(mode);
  }
}

TEST(ImuFactor, WithTrueIntrinsicsResidualIsFarBelowNoise) {
  const auto trajectory = handheld();
  InertialSensor sensor = idealImu(500.0);
  sensor.intrinsics = test::tableFourIntrinsics();
  ImuFactorFixture f = makeFixture(0.0);
  f.pre =
      std::make_shared<ImuPreintegration>(preintegrate(sensor, trajectory, 4.0, 4.1, noiseFree()));
  const std::vector<double> truth = test::intrinsicsBlock(sensor.intrinsics);
  f.blocks.push_back(truth);
  const ImuFactor factor(f.pre, ImuIntrinsicsFrame(), IntrinsicsLinearization::kReintegrate,
                         truth.data());
  // As for calibrated readings (ResidualAtTruthIsFarBelowNoise); the same readings taken as
  // calibrated are off by many sigma.
  EXPECT_LT(test::evaluateResiduals(factor, f.blocks).cwiseAbs().maxCoeff(), 0.05);
  f.blocks.pop_back();
  EXPECT_GT(test::evaluateResiduals(ImuFactor(f.pre), f.blocks).cwiseAbs().maxCoeff(), 3.0);
}


// With the states held at the truth, the intrinsics fitted to noisy readings by these factors
// alone are unbiased: over 16 seeds the mean error of each scale of Dw and Da stays within 3
// standard errors of the mean (with the whitening fixed at construction instead, the
// accelerometer's x and y scales ended 5.5 and 3.0 standard errors small: imu_factor.h). Four
// times the VI-Rig's noise densities make the bias, which grows with their square, plain; the
// scale along gravity (z) is left out (within 3.4 standard errors either way, a smaller effect).
TEST(ImuFactor, IntrinsicsUnbiasedUnderNoiseAtTheTrueStates) {
  const auto trajectory = handheld();
  const TrajectoryFunction base = [&](double t) { return trajectory.evaluate(t); };
  constexpr int kSeeds = 16, kStep = 15;  // factors over 15 readings: 30 ms at 500 Hz
  const std::vector<int> scales = {upperIndex(0, 0), upperIndex(1, 1), upperIndex(2, 2),
                                   ImuIntrinsicsLayout::kDa + upperIndex(0, 0),
                                   ImuIntrinsicsLayout::kDa + upperIndex(1, 1)};
  Eigen::MatrixXd errors(kSeeds, scales.size());
  for (int seed = 1; seed <= kSeeds; ++seed) {
    InertialSensor sensor = idealImu(500.0);
    sensor.noise.gyroscope_noise_density *= 4.0;
    sensor.noise.accelerometer_noise_density *= 4.0;
    ImuSimulationOptions options;
    options.noise = true;
    options.biases = false;
    options.seed = seed;
    const auto samples = simulateImu(sensor, base, 0, fromSeconds(1.0), fromSeconds(31.0), options);
    const int n = static_cast<int>(samples.size() - 1) / kStep;
    std::vector<std::vector<double>> poses(n + 1, std::vector<double>(7)),
        speed_biases(n + 1, std::vector<double>(9, 0.0));
    std::vector<double> g = {kGravity_G.x(), kGravity_G.y(), kGravity_G.z()};
    std::vector<double> intrinsics = test::intrinsicsBlock(ImuIntrinsics());
    const std::vector<double> identity = intrinsics;
    ceres::Problem problem;
    for (int i = 0; i <= n; ++i) {
      const TrajectoryState s = trajectory.evaluate(toSeconds(samples[i * kStep].stamp_ns));
      se3ToPose(s.T_G_I, poses[i].data());
      Eigen::Map<Eigen::Vector3d>(speed_biases[i].data()) = s.v_G;
    }
    for (int i = 0; i < n; ++i) {
      auto pre = std::make_shared<ImuPreintegration>(sensor.noise, Eigen::Vector3d::Zero(),
                                                     Eigen::Vector3d::Zero());
      for (int k = i * kStep; k <= (i + 1) * kStep; ++k) {
        pre->add({samples[k].stamp_ns, samples[k].gyro, samples[k].accel});
      }
      auto* factor = new ImuFactor(pre, ImuIntrinsicsFrame(),
                                   IntrinsicsLinearization::kReintegrate, identity.data());
      problem.AddResidualBlock(factor, nullptr,
                               {poses[i].data(), speed_biases[i].data(), poses[i + 1].data(),
                                speed_biases[i + 1].data(), g.data(), intrinsics.data()});
    }
    for (int i = 0; i <= n; ++i) {
      problem.SetParameterBlockConstant(poses[i].data());
      problem.SetParameterBlockConstant(speed_biases[i].data());
    }
    problem.SetParameterBlockConstant(g.data());
    ceres::Solver::Options solver;
    solver.linear_solver_type = ceres::DENSE_QR;
    solver.function_tolerance = 1e-12;
    solver.parameter_tolerance = 1e-14;
    ceres::Solver::Summary summary;
    ceres::Solve(solver, &problem, &summary);
    ASSERT_TRUE(summary.IsSolutionUsable()) << summary.BriefReport();
    for (std::size_t k = 0; k < scales.size(); ++k) {
      errors(seed - 1, k) = intrinsics[scales[k]] - identity[scales[k]];
    }
  }
  const Eigen::RowVectorXd mean = errors.colwise().mean();
  for (std::size_t k = 0; k < scales.size(); ++k) {
    const double sd = std::sqrt((errors.col(k).array() - mean[k]).square().sum() / (kSeeds - 1));
    const double standard_error = sd / std::sqrt(double(kSeeds));
    EXPECT_LT(std::abs(mean[k]), 3.0 * standard_error) << "intrinsics element " << scales[k];
  }
}
}  // namespace
}  // namespace mvis
