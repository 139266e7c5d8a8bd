// The IMU-intrinsics estimator tests' shared pieces: the VI-Rig with Table-4-sized intrinsics,
// the guess perturbed as Table 4, the options that estimate them, and every calibrated element's
// error against its sigma.
#pragma once

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "estimator_test_util.h"
#include "mvis/common/lie.h"

namespace mvis::test {

// Truth: every inertial sensor rpng with intrinsics of Table 4 size (a gyroscope: Tw only).
inline void withIntrinsics(Rig* rig) {
  for (auto& s : rig->inertial) {
    s.model = ImuModel::kRpng;
    s.intrinsics.Tw << 1.003, -0.002, 0.003, 0, 0.997, 0.002, 0, 0, 1.002;
    if (s.type == InertialType::kGyroscope) continue;
    s.intrinsics.Ta << 0.998, 0.003, -0.002, 0, 1.003, 0.001, 0, 0, 0.997;
    s.intrinsics.Tg << 1e-3, -1e-3, 5e-4, 5e-4, 1e-3, -5e-4, -1e-3, 5e-4, 1e-3;
    s.intrinsics.R_IMUtoACC = lie::expSO3(Eigen::Vector3d(0.003, -0.003, 0.002));
  }
}

// The guess: the truth's intrinsics perturbed as in Table 4 times `scale` (Dw, Da 3e-3 per
// element, Tg 1e-3, R_IMUtoACC (kalibr: R_IMUtoGYRO) 3e-3 rad per axis).
inline void perturbIntrinsics(Rig* rig, std::uint64_t seed, double scale) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  for (auto& s : rig->inertial) {
    // kalibr's lower-triangular matrices as the transposes of upper-triangular ones.
    const bool kalibr = s.model == ImuModel::kKalibr;
    const auto upper = [&](const Eigen::Matrix3d& T) {
      return Eigen::Matrix3d(kalibr ? T.transpose() : T);
    };
    Eigen::Matrix3d Dw = upper(s.intrinsics.Tw).inverse(), Da = upper(s.intrinsics.Ta).inverse();
    for (int c = 0; c < 3; ++c) {
      for (int r = 0; r <= c; ++r) {
        Dw(r, c) += scale * 3e-3 * n(rng);
        Da(r, c) += scale * 3e-3 * n(rng);
      }
    }
    Eigen::Matrix3d Tw = Dw.inverse(), Ta = Da.inverse();
    Tw.triangularView<Eigen::StrictlyLower>().setZero();
    Ta.triangularView<Eigen::StrictlyLower>().setZero();
    s.intrinsics.Tw = upper(Tw);
    if (s.type == InertialType::kGyroscope) continue;
    s.intrinsics.Ta = upper(Ta);
    for (int k = 0; k < 9; ++k) s.intrinsics.Tg(k / 3, k % 3) += scale * 1e-3 * n(rng);
    (kalibr ? s.intrinsics.R_IMUtoGYRO : s.intrinsics.R_IMUtoACC) *=
        lie::expSO3(scale * 3e-3 * Eigen::Vector3d(n(rng), n(rng), n(rng)));
  }
}

inline EstimatorOptions intrinsicsOptions(IntrinsicsLinearization mode, double prior_scale) {
  EstimatorOptions o = deterministic();
  o.pixel_sigma_px = 0.5;
  o.estimate_imu_intrinsics = true;
  o.estimate_gravity_sensitivity = true;
  o.imu_intrinsics_linearization = mode;
  // Priors 4x the perturbations' sizes (at least the defaults).
  o.imu_scale_misalignment_prior = std::max(0.01, 4.0 * prior_scale * 3e-3);
  o.imu_gravity_sensitivity_prior = std::max(0.002, 4.0 * prior_scale * 1e-3);
  o.imu_acc_rotation_prior_rad = std::max(0.01, 4.0 * prior_scale * 3e-3);
  return o;
}

// Every calibrated element's |error| / sigma: cameras' and aux sensors' extrinsics and time
// offsets (per axis), inertial intrinsics (every element with a sigma).
inline std::vector<double> sigmaRatios(const Rig& truth, const Rig& estimate) {
  std::vector<double> out;
  const auto add = [&](const Eigen::MatrixXd& err, const Eigen::MatrixXd& sd) {
    for (int k = 0; k < err.size(); ++k) {
      if (sd(k) > 0.0) out.push_back(std::abs(err(k)) / sd(k));
    }
  };
  for (std::size_t c = 0; c < truth.cameras.size(); ++c) {
    const CameraErrors e = errors(truth.cameras[c], estimate.cameras[c]);
    for (int k = 0; k < 3; ++k) {
      out.push_back(e.rotation_sigma_ratio[k]);
      out.push_back(e.translation_sigma_ratio[k]);
    }
    out.push_back(e.time_offset_sigma_ratio);
  }
  for (std::size_t i = 0; i < truth.inertial.size(); ++i) {
    const InertialSensor &t = truth.inertial[i], &x = estimate.inertial[i];
    if (i > 0) {
      const CameraErrors e = inertialErrors(t, x);
      for (int k = 0; k < 3; ++k) {
        out.push_back(e.rotation_sigma_ratio[k]);
        if (t.type != InertialType::kGyroscope) out.push_back(e.translation_sigma_ratio[k]);
      }
      out.push_back(e.time_offset_sigma_ratio);
    }
    if (!x.std) continue;
    add(x.intrinsics.Tw - t.intrinsics.Tw, x.std->Tw);
    add(x.intrinsics.Tg - t.intrinsics.Tg, x.std->Tg);
    if (t.type == InertialType::kGyroscope) continue;
    add(x.intrinsics.Ta - t.intrinsics.Ta, x.std->Ta);
    add(lie::logSO3(t.intrinsics.R_IMUtoACC.transpose() * x.intrinsics.R_IMUtoACC),
        x.std->R_IMUtoACC);
  }
  return out;
}

}  // namespace mvis::test
