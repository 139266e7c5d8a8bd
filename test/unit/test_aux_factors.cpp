// Auxiliary-IMU and gyroscope factors against the simulator's exact motion: the residual at the
// true states and calibration is far below the noise (also when the factor was made with a
// time offset 2 ms off the truth, which the base-pose shift must absorb), a wrong extrinsic or
// time offset shows in the residual, and the Jacobians match central differences through the
// manifolds, for both aux-velocity models; the gyroscope's rotation prior likewise.
#include <ceres/sphere_manifold.h>
#include <gtest/gtest.h>

#include <memory>

#include "factor_test_util.h"
#include "mvis/inertial/imu_preintegration.h"
#include "mvis/factors/state_blocks.h"
#include "mvis/factors/aux_imu_factor.h"
#include "mvis/factors/gyro_factor.h"
#include "mvis/factors/rotation_prior_factor.h"
#include "mvis/sim/imu_simulator.h"
#include "sim_test_util.h"

namespace mvis {
namespace {

using test::handheld;
using test::idealImu;

constexpr double kTrueOffset = 0.004;  // [s], t_imu0 = t_aux + offset
constexpr double kTi = 4.0, kTj = 4.1;

InertialSensor auxSensor(InertialType type, double rate) {
  InertialSensor s = idealImu(rate);
  s.name = "imu1";
  s.type = type;
  s.time_offset = kTrueOffset;
  s.T_i_b = SE3(lie::expQuat(Eigen::Vector3d(0.3, -1.2, 0.4)), Eigen::Vector3d(0.04, 0.06, -0.02));
  if (type == InertialType::kGyroscope) {
    s.noise.accelerometer_noise_density = 0.0;
    s.noise.accelerometer_random_walk = 0.0;
  }
  return s;
}

BaseMotion baseMotion(const SinusoidTrajectory& trajectory, double t) {
  const TrajectoryState s = trajectory.evaluate(t);
  BaseMotion m;
  m.gyro = s.w_I;
  m.accel = s.specificForce();
  m.angular_acceleration = s.dw_I;
  return m;
}

// The sensor's noise-free readings over base times [t_i, t_j] as the estimator takes them: in
// the sensor clock, shifted by the offset guess td0, with interpolated readings at both ends.
std::shared_ptr<ImuPreintegration> preintegrate(const InertialSensor& sensor,
                                                const SinusoidTrajectory& trajectory, double td0_i,
                                                double td0_j, const Eigen::Vector3d& bg,
                                                const Eigen::Vector3d& ba) {
  ImuSimulationOptions o;
  o.noise = false;
  o.biases = false;
  const TrajectoryFunction base = [&](double t) { return trajectory.evaluate(t); };
  const TimeNs a = fromSeconds(kTi - td0_i), b = fromSeconds(kTj - td0_j);
  const auto samples =
      simulateImu(sensor, base, 0, a - fromSeconds(0.05), b + fromSeconds(0.05), o);
  std::vector<ImuMeasurement> m;
  for (const auto& s : samples) {
    m.push_back({s.stamp_ns, s.gyro, s.accel});
    if (sensor.type != InertialType::kGyroscope) continue;
    // A gyroscope's readings carry the specific force at it, as the estimator gives them
    // (aux_sensors.h): here the true one.
    Eigen::Vector3d w_i;
    trueInertialMotion(sensor, base(toSeconds(s.stamp_ns) + sensor.time_offset), &w_i,
                       &m.back().accel);
  }
  auto at = [&](TimeNs t) {
    for (std::size_t k = 1; k < m.size(); ++k) {
      if (m[k].stamp_ns >= t) return interpolateMeasurement(m[k - 1], m[k], t);
    }
    return m.back();
  };
  auto pre = std::make_shared<ImuPreintegration>(sensor.noise, bg, ba);
  pre->add(at(a));
  for (const auto& r : m) {
    if (r.stamp_ns > a && r.stamp_ns < b) pre->add(r);
  }
  pre->add(at(b));
  return pre;
}

std::vector<double> poseBlock(const SE3& T) {
  std::vector<double> b(7);
  se3ToPose(T, b.data());
  return b;
}

// Base blocks at the truth, moved by `k` times a generic offset.
std::vector<std::vector<double>> baseBlocks(const SinusoidTrajectory& trajectory, double k) {
  std::vector<std::vector<double>> out;
  for (double t : {kTi, kTj}) {
    const TrajectoryState s = trajectory.evaluate(t);
    SE3 T = s.T_G_I;
    T.q = (T.q * lie::expQuat(Eigen::Vector3d(0.01, -0.02, 0.015) * k)).normalized();
    T.p += Eigen::Vector3d(0.02, 0.01, -0.03) * k;
    out.push_back(poseBlock(T));
    std::vector<double> sb(9, 0.0);
    Eigen::Map<Eigen::Vector3d>(sb.data()) = s.v_G + Eigen::Vector3d(0.05, -0.02, 0.01) * k;
    Eigen::Map<Eigen::Vector3d>(sb.data() + 3) = Eigen::Vector3d(1e-3, -2e-3, 5e-4) * k;
    Eigen::Map<Eigen::Vector3d>(sb.data() + 6) = Eigen::Vector3d(0.02, 0.01, -0.03) * k;
    out.push_back(sb);
    k = -k;
  }
  return out;
}

// The aux velocity in the world at base time t: v + R (w x p_IA).
Eigen::Vector3d auxVelocity(const InertialSensor& aux, const TrajectoryState& s) {
  const Eigen::Vector3d p_IA = aux.T_i_b.inverse().p;
  return s.v_G + (s.T_G_I.q * s.w_I.cross(p_IA));
}

struct AuxFixture {
  std::unique_ptr<AuxImuFactor> factor;
  std::vector<std::vector<double>> blocks;
  std::vector<const ceres::Manifold*> manifolds;
};

// td0_i, td0_j: the offsets the two aux states were made with.
// `intrinsics`: readings made with Table 4 intrinsics and the factor with its intrinsics block
// (re-integrated) at them, moved by k times a generic offset.
AuxFixture auxFixture(AuxImuModel model, double td0_i, double td0_j, double k, double rate,
                      bool intrinsics = false) {
  static const PoseManifold pose;
  static const ceres::SphereManifold<3> sphere;
  const auto trajectory = handheld();
  InertialSensor aux = auxSensor(InertialType::kImu, rate);
  std::vector<double> block;
  if (intrinsics) {
    aux.intrinsics = test::tableFourIntrinsics();
    block = test::intrinsicsBlock(aux.intrinsics);
    for (int n = 0; n < kImuIntrinsicsSize; ++n) block[n] += 1e-3 * k * std::sin(1.0 + n);
  }
  const Eigen::Vector3d bg = Eigen::Vector3d(2e-4, -1e-4, 3e-4) * k;
  const Eigen::Vector3d ba = Eigen::Vector3d(3e-3, 2e-3, -1e-3) * k;
  AuxFixture f;
  auto pre = preintegrate(aux, trajectory, td0_i, td0_j, bg, ba);
  if (intrinsics) {
    f.factor = std::make_unique<AuxImuFactor>(model, pre, td0_i, td0_j, baseMotion(trajectory, kTi),
                                              baseMotion(trajectory, kTj), ImuIntrinsicsFrame(),
                                              IntrinsicsLinearization::kReintegrate, block.data());
  } else {
    f.factor = std::make_unique<AuxImuFactor>(model, pre, td0_i, td0_j, baseMotion(trajectory, kTi),
                                              baseMotion(trajectory, kTj));
  }
  f.blocks = baseBlocks(trajectory, k);
  for (double t : {kTi, kTj}) {
    std::vector<double> a;
    if (model == AuxImuModel::kVelocityState) {
      // At tau = t - td0, base time t + (true offset - td0).
      const double shift = kTrueOffset - (t == kTi ? td0_i : td0_j);
      const Eigen::Vector3d v =
          auxVelocity(aux, trajectory.evaluate(t + shift)) + Eigen::Vector3d(0.03, 0.01, -0.02) * k;
      a = {v.x(), v.y(), v.z()};
    }
    for (int i = 0; i < 3; ++i) a.push_back(bg[i] * (t == kTi ? 1.0 : -1.0));
    for (int i = 0; i < 3; ++i) a.push_back(ba[i] * (t == kTi ? 1.0 : -1.0));
    f.blocks.push_back(a);
  }
  SE3 T_ext = aux.T_i_b;
  T_ext.q = (T_ext.q * lie::expQuat(Eigen::Vector3d(-0.02, 0.01, 0.03) * k)).normalized();
  T_ext.p += Eigen::Vector3d(0.01, -0.02, 0.005) * k;
  f.blocks.push_back(poseBlock(T_ext));
  f.blocks.push_back({kTrueOffset + 0.001 * k});
  const Eigen::Vector3d g = lie::expSO3(Eigen::Vector3d(0.05, -0.03, 0.0) * k) * kGravity_G;
  f.blocks.push_back({g.x(), g.y(), g.z()});
  f.manifolds = {&pose, nullptr, &pose, nullptr, nullptr, nullptr, &pose, nullptr, &sphere};
  if (intrinsics) {
    f.blocks.push_back(block);
    f.manifolds.push_back(nullptr);
  }
  return f;
}

double maxAbs(const Eigen::VectorXd& r) { return r.cwiseAbs().maxCoeff(); }

TEST(AuxImuFactor, ResidualAtTruthIsFarBelowNoise) {
  for (auto model : {AuxImuModel::kVelocityState, AuxImuModel::kRigidVelocity}) {
    // Made with the true offset, and with offsets 2 and 1 ms off (the shift of base_motion.h).
    for (double off : {0.0, 1.0}) {
      const double td0_i = kTrueOffset - 0.002 * off, td0_j = kTrueOffset + 0.001 * off;
      const AuxFixture f = auxFixture(model, td0_i, td0_j, 0.0, 500.0);
      // Whitened: 1 sigma ~ 1 per entry. Midpoint integration leaves 0.073 at 200 Hz and 0.012
      // at 500 Hz (measured; second order in the period); the rigid-velocity model's
      // first-order velocity shift leaves 0.032 with the offsets off.
      EXPECT_LT(maxAbs(test::evaluateResiduals(*f.factor, f.blocks)), 0.05)
          << static_cast<int>(model) << " " << off;
    }
  }
}

TEST(AuxImuFactor, WrongCalibrationShows) {
  const AuxFixture f =
      auxFixture(AuxImuModel::kVelocityState, kTrueOffset, kTrueOffset, 0.0, 200.0);
  const double at_truth = maxAbs(test::evaluateResiduals(*f.factor, f.blocks));
  // 1 mrad of extrinsic rotation, 1 mm of translation, 1 ms of time offset each move the
  // residual far above its value at the truth.
  const PoseManifold pose;
  for (int k = 0; k < 3; ++k) {
    auto moved = f.blocks;
    if (k < 2) {
      Eigen::Matrix<double, 6, 1> d = Eigen::Matrix<double, 6, 1>::Zero();
      d[k == 0 ? 0 : 4] = 1e-3;
      pose.Plus(f.blocks[6].data(), d.data(), moved[6].data());
    } else {
      moved[7][0] += 1e-3;
    }
    EXPECT_GT(maxAbs(test::evaluateResiduals(*f.factor, moved)), 10.0 * at_truth + 0.5) << k;
  }
}

TEST(AuxImuFactor, JacobiansMatchCentralDifferences) {
  for (auto model : {AuxImuModel::kVelocityState, AuxImuModel::kRigidVelocity}) {
    const AuxFixture f = auxFixture(model, kTrueOffset - 0.002, kTrueOffset + 0.001, 1.0, 100.0);
    const auto analytic = test::analyticTangentJacobians(*f.factor, f.blocks, f.manifolds);
    const auto numeric = test::numericTangentJacobians(*f.factor, f.blocks, f.manifolds, 1e-6);
    // As for ImuFactor: round-off ~1e-16 |r| / h for whitened residuals up to ~1e3.
    EXPECT_LT(test::jacobianMismatch(analytic, numeric), 1e-4) << static_cast<int>(model);
  }
}

struct GyroFixture {
  std::unique_ptr<GyroFactor> factor;
  std::vector<std::vector<double>> blocks;
  std::vector<const ceres::Manifold*> manifolds;
};

// `intrinsics`: as for auxFixture, with the Tw and Tg of Table 4 (the gyroscope's readings
// carry the specific force at it).
GyroFixture gyroFixture(double td0_i, double td0_j, double k, bool intrinsics = false) {
  static const PoseManifold pose;
  static const RotationManifold rotation;
  const auto trajectory = handheld();
  InertialSensor gyro = auxSensor(InertialType::kGyroscope, 200.0);
  std::vector<double> block;
  if (intrinsics) {
    gyro.intrinsics.Tw = test::tableFourIntrinsics().Tw;
    gyro.intrinsics.Tg = test::tableFourIntrinsics().Tg;
    block = test::intrinsicsBlock(gyro.intrinsics);
    for (int n = 0; n < kImuIntrinsicsSize; ++n) block[n] += 1e-3 * k * std::sin(1.0 + n);
  }
  const Eigen::Vector3d bg = Eigen::Vector3d(2e-4, -1e-4, 3e-4) * k;
  GyroFixture f;
  auto pre = preintegrate(gyro, trajectory, td0_i, td0_j, bg, Eigen::Vector3d::Zero());
  if (intrinsics) {
    f.factor = std::make_unique<GyroFactor>(pre, td0_i, td0_j, baseMotion(trajectory, kTi),
                                            baseMotion(trajectory, kTj), ImuIntrinsicsFrame{},
                                            IntrinsicsLinearization::kReintegrate, block.data());
  } else {
    f.factor = std::make_unique<GyroFactor>(pre, td0_i, td0_j, baseMotion(trajectory, kTi),
                                            baseMotion(trajectory, kTj));
  }
  f.blocks = baseBlocks(trajectory, k);
  f.blocks.push_back({bg.x(), bg.y(), bg.z()});
  f.blocks.push_back({-bg.x(), -bg.y(), -bg.z()});
  const Eigen::Quaterniond q =
      (gyro.T_i_b.q * lie::expQuat(Eigen::Vector3d(-0.02, 0.01, 0.03) * k)).normalized();
  f.blocks.push_back({q.x(), q.y(), q.z(), q.w()});
  f.blocks.push_back({kTrueOffset + 0.001 * k});
  f.manifolds = {&pose, nullptr, &pose, nullptr, nullptr, nullptr, &rotation, nullptr};
  if (intrinsics) {
    f.blocks.push_back(block);
    f.manifolds.push_back(nullptr);
  }
  return f;
}

TEST(GyroFactor, ResidualAtTruthIsFarBelowNoise) {
  for (double off : {0.0, 1.0}) {
    const GyroFixture f = gyroFixture(kTrueOffset - 0.002 * off, kTrueOffset + 0.001 * off, 0.0);
    // Measured 0.03 at 200 Hz (midpoint integration).
    EXPECT_LT(maxAbs(test::evaluateResiduals(*f.factor, f.blocks)), 0.1) << off;
    // 1 ms of time offset is visible.
    auto moved = f.blocks;
    moved[7][0] += 1e-3;
    EXPECT_GT(maxAbs(test::evaluateResiduals(*f.factor, moved)), 1.0) << off;
  }
}

TEST(GyroFactor, JacobiansMatchCentralDifferences) {
  const GyroFixture f = gyroFixture(kTrueOffset - 0.002, kTrueOffset + 0.001, 1.0);
  const auto analytic = test::analyticTangentJacobians(*f.factor, f.blocks, f.manifolds);
  const auto numeric = test::numericTangentJacobians(*f.factor, f.blocks, f.manifolds, 1e-6);
  EXPECT_LT(test::jacobianMismatch(analytic, numeric), 1e-4);
}

TEST(AuxImuFactor, WithIntrinsicsJacobiansMatchCentralDifferences) {
  for (auto model : {AuxImuModel::kVelocityState, AuxImuModel::kRigidVelocity}) {
    const AuxFixture f =
        auxFixture(model, kTrueOffset - 0.002, kTrueOffset + 0.001, 1.0, 100.0, true);
    const auto analytic = test::analyticTangentJacobians(*f.factor, f.blocks, f.manifolds);
    const auto numeric = test::numericTangentJacobians(*f.factor, f.blocks, f.manifolds, 1e-6);
    EXPECT_LT(test::jacobianMismatch(analytic, numeric), 1e-4) << static_cast<int>(model);
  }
  // At the true intrinsics, as small as without them (ResidualAtTruthIsFarBelowNoise, 500 Hz).
  const AuxFixture truth =
      auxFixture(AuxImuModel::kVelocityState, kTrueOffset, kTrueOffset, 0.0, 500.0, true);
  EXPECT_LT(maxAbs(test::evaluateResiduals(*truth.factor, truth.blocks)), 0.05);
}

TEST(GyroFactor, WithIntrinsicsJacobiansMatchCentralDifferences) {
  const GyroFixture f = gyroFixture(kTrueOffset - 0.002, kTrueOffset + 0.001, 1.0, true);
  const auto analytic = test::analyticTangentJacobians(*f.factor, f.blocks, f.manifolds);
  const auto numeric = test::numericTangentJacobians(*f.factor, f.blocks, f.manifolds, 1e-6);
  EXPECT_LT(test::jacobianMismatch(analytic, numeric), 1e-4);
  // At the true Dw and Tg, as small as without them (ResidualAtTruthIsFarBelowNoise).
  const GyroFixture truth = gyroFixture(kTrueOffset, kTrueOffset, 0.0, true);
  EXPECT_LT(maxAbs(test::evaluateResiduals(*truth.factor, truth.blocks)), 0.1);
  // Tg as held at zero: the 1e-3-sized gravity sensitivity shows (~30 sigma over 0.1 s).
  auto no_tg = truth.blocks;
  for (int k = 0; k < 9; ++k) no_tg.back()[ImuIntrinsicsLayout::kTg + k] = 0.0;
  EXPECT_GT(maxAbs(test::evaluateResiduals(*truth.factor, no_tg)), 1.0);
}

TEST(RotationPriorFactor, ResidualAndJacobian) {
  const Eigen::Quaterniond mean = lie::expQuat(Eigen::Vector3d(0.3, -0.2, 0.5));
  const RotationPriorFactor factor(mean, Eigen::Vector3d(0.01, 0.02, 0.04));
  const Eigen::Quaterniond q = mean * lie::expQuat(Eigen::Vector3d(0.01, 0.02, -0.04));
  const std::vector<std::vector<double>> blocks = {{q.x(), q.y(), q.z(), q.w()}};
  const Eigen::VectorXd r = test::evaluateResiduals(factor, blocks);
  EXPECT_NEAR(r[0], 1.0, 1e-9);
  EXPECT_NEAR(r[1], 1.0, 1e-9);
  EXPECT_NEAR(r[2], -1.0, 1e-9);
  const RotationManifold rotation;
  const std::vector<const ceres::Manifold*> manifolds = {&rotation};
  EXPECT_LT(test::jacobianMismatch(test::analyticTangentJacobians(factor, blocks, manifolds),
                                   test::numericTangentJacobians(factor, blocks, manifolds, 1e-6)),
            1e-6);
}

}  // namespace
}  // namespace mvis
