#include "mvis/inertial/imu_reintegration.h"

#include <ceres/jet.h>

#include <array>

#include "../common/tangent_jet.h"
#include "mvis/common/lie.h"

namespace mvis {
namespace {

using L = ImuIntrinsicsLayout;
using tangent_jet::expT;
using tangent_jet::Mat3;
using tangent_jet::Vec3;

template <typename T>
Mat3<T> upperT(const T* d) {
  Mat3<T> M = Mat3<T>::Zero();
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r <= c; ++r) M(r, c) = d[upperIndex(r, c)];
  }
  return M;
}

// The corrections' matrices at the intrinsics `in`: w = G (w_m - b_g - Tg a), a = M (a_m - b_a)
// (M zero for a gyroscope).
template <typename T>
void correctionMaps(const T* in, const ImuIntrinsicsFrame& frame, Mat3<T>* G, Mat3<T>* M) {
  // kalibr: lower triangular, stored as the transpose's upper entries.
  const auto tri = [&](const T* d) {
    const Mat3<T> U = upperT<T>(d);
    return frame.kalibr ? Mat3<T>(U.transpose()) : U;
  };
  const Vec3<T> theta(in[L::kAccRotation], in[L::kAccRotation + 1], in[L::kAccRotation + 2]);
  const Mat3<T> R = frame.R0.cast<T>() * expT<T>(theta);
  *G = frame.kalibr ? Mat3<T>(R * tri(in + L::kDw)) : tri(in + L::kDw);
  M->setZero();
  if (!frame.gyro_only) *M = frame.kalibr ? tri(in + L::kDa) : Mat3<T>(R * tri(in + L::kDa));
}

// The midpoint scheme of ImuPreintegration::integrate on readings corrected at x.
template <typename T>
void integrate(const std::vector<ImuMeasurement>& samples, const Eigen::Matrix<T, 30, 1>& x,
               const ImuIntrinsicsFrame& frame, Mat3<T>* dR, Vec3<T>* dp, Vec3<T>* dv) {
  const Vec3<T> bg = x.template head<3>();
  const Vec3<T> ba = x.template segment<3>(3);
  const T* in = x.data() + 6;
  Mat3<T> G, M, Tg = Mat3<T>::Zero();
  correctionMaps<T>(in, frame, &G, &M);
  for (int k = 0; k < 9; ++k) Tg(k / 3, k % 3) = in[L::kTg + k];
  const auto correct = [&](const ImuMeasurement& m, Vec3<T>* w, Vec3<T>* a) {
    if (frame.gyro_only) {  // m.accel: the specific force at the gyroscope, given (or zero)
      *a = Vec3<T>::Zero();
      *w = G * (m.gyro.cast<T>() - bg - Tg * m.accel.cast<T>());
      return;
    }
    *a = M * (m.accel.cast<T>() - ba);
    *w = G * (m.gyro.cast<T>() - bg - Tg * *a);
  };
  dR->setIdentity();
  dp->setZero();
  dv->setZero();
  if (samples.empty()) return;
  Vec3<T> w0, a0, w1, a1;
  correct(samples.front(), &w0, &a0);
  for (std::size_t k = 1; k < samples.size(); ++k) {
    correct(samples[k], &w1, &a1);
    const double dt = toSeconds(samples[k].stamp_ns - samples[k - 1].stamp_ns);
    if (dt > 0.0) {
      const Vec3<T> phi = (w0 + w1) * T(0.5 * dt);
      const Mat3<T> R1 = *dR * expT<T>(phi);
      const Vec3<T> a = (*dR * a0 + R1 * a1) * T(0.5);
      *dp += *dv * T(dt) + a * T(0.5 * dt * dt);
      *dv += a * T(dt);
      *dR = R1;
    }
    w0 = w1;
    a0 = a1;
  }
}

// A corrected reading and its derivatives in x (3 x 30 each).
struct CorrectedReading {
  Eigen::Vector3d w, a;
  Eigen::Matrix<double, 3, kDeltaVariables> W, A;
};

// integrate<double>'s corrections, with their derivatives by hand (see reintegrate's comment).
class ReadingCorrection {
 public:
  ReadingCorrection(const Eigen::Matrix<double, 30, 1>& x, const ImuIntrinsicsFrame& frame)
      : frame_(frame), bg_(x.head<3>()), ba_(x.segment<3>(3)) {
    const double* in = x.data() + 6;
    const Eigen::Vector3d theta(in + L::kAccRotation);
    R_ = frame.R0 * expT<double>(theta);  // as integrate, to the last bit
    Jr_theta_ = lie::rightJacobianSO3(theta);
    Uw_ = upperT<double>(in + L::kDw);
    Ua_ = upperT<double>(in + L::kDa);
    // As integrate: kalibr's triangles are the transposes of the stored upper ones.
    Dw_ = frame.kalibr ? Eigen::Matrix3d(Uw_.transpose()) : Uw_;
    Da_ = frame.kalibr ? Eigen::Matrix3d(Ua_.transpose()) : Ua_;
    correctionMaps<double>(in, frame, &G_, &M_);  // as integrate's
    for (int k = 0; k < 9; ++k) Tg_(k / 3, k % 3) = in[L::kTg + k];
  }

  void correct(const ImuMeasurement& m, CorrectedReading* out) const {
    constexpr int kBg = 0, kBa = 3, kDw = 6 + L::kDw, kDa = 6 + L::kDa, kTg = 6 + L::kTg,
                  kTheta = 6 + L::kAccRotation;
    out->A.setZero();
    out->W.setZero();
    Eigen::Vector3d f;  // the specific force Tg multiplies
    if (frame_.gyro_only) {
      out->a.setZero();
      f = m.accel;
    } else {
      const Eigen::Vector3d u = m.accel - ba_;
      out->a = M_ * u;
      f = out->a;
      out->A.middleCols<3>(kBa) = -M_;
      for (int c = 0; c < 3; ++c) {
        for (int r = 0; r <= c; ++r) {
          // rpng a = R U u: R e_r u_c; kalibr a = U^T u: e_c u_r.
          auto col = out->A.col(kDa + upperIndex(r, c));
          if (frame_.kalibr) {
            col[c] = u[r];
          } else {
            col = R_.col(r) * u[c];
          }
        }
      }
      if (!frame_.kalibr) out->A.middleCols<3>(kTheta) = -R_ * lie::hat(Da_ * u) * Jr_theta_;
      out->W = -G_ * Tg_ * out->A;
    }
    const Eigen::Vector3d s = m.gyro - bg_ - Tg_ * f;
    out->w = G_ * s;
    out->W.middleCols<3>(kBg) -= G_;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) out->W.col(kTg + 3 * r + c) -= G_.col(r) * f[c];
    }
    for (int c = 0; c < 3; ++c) {
      for (int r = 0; r <= c; ++r) {
        // rpng w = U s: e_r s_c; kalibr w = R U^T s: R e_c s_r.
        auto col = out->W.col(kDw + upperIndex(r, c));
        if (frame_.kalibr) {
          col += R_.col(c) * s[r];
        } else {
          col[r] += s[c];
        }
      }
    }
    if (frame_.kalibr) out->W.middleCols<3>(kTheta) -= R_ * lie::hat(Dw_ * s) * Jr_theta_;
  }

 private:
  const ImuIntrinsicsFrame& frame_;
  Eigen::Vector3d bg_, ba_;
  Eigen::Matrix3d R_, Jr_theta_, Uw_, Ua_, Dw_, Da_, G_, M_, Tg_;
};

// integrate<double> with the deltas' derivatives in x propagated along (rows [theta; p; v] of
// out->J, theta the right tangent of dR). Per interval, with E = Exp(phi):
//   Theta' = E^T Theta + Jr(phi) dphi/dx
//   d a / dx = 1/2 (dR (A_0 - [a_0]x Theta) + dR' (A_1 - [a_1]x Theta'))
//   P' = P + V dt + 1/2 dt^2 d a / dx,   V' = V + dt d a / dx
// with A_0, A_1 the readings' derivatives (ReadingCorrection).
void integrateWithJacobian(const std::vector<ImuMeasurement>& samples,
                           const Eigen::Matrix<double, 30, 1>& x, const ImuIntrinsicsFrame& frame,
                           ImuDeltas* out) {
  using Jacobian = Eigen::Matrix<double, 3, kDeltaVariables>;
  Eigen::Matrix3d dR = Eigen::Matrix3d::Identity();
  Eigen::Vector3d dp = Eigen::Vector3d::Zero(), dv = Eigen::Vector3d::Zero();
  Jacobian Theta = Jacobian::Zero(), P = Jacobian::Zero(), V = Jacobian::Zero();
  if (!samples.empty()) {
    const ReadingCorrection correction(x, frame);
    CorrectedReading r0, r1;
    correction.correct(samples.front(), &r0);
    for (std::size_t k = 1; k < samples.size(); ++k) {
      correction.correct(samples[k], &r1);
      const double dt = toSeconds(samples[k].stamp_ns - samples[k - 1].stamp_ns);
      if (dt > 0.0) {
        const Eigen::Vector3d phi = (r0.w + r1.w) * (0.5 * dt);
        const Eigen::Matrix3d E = expT<double>(phi);
        const Eigen::Matrix3d R1 = dR * E;
        const Jacobian Theta1 =
            E.transpose() * Theta + lie::rightJacobianSO3(phi) * ((r0.W + r1.W) * (0.5 * dt));
        if (!frame.gyro_only) {
          const Eigen::Vector3d a = (dR * r0.a + R1 * r1.a) * 0.5;
          const Jacobian A =
              0.5 * (dR * (r0.A - lie::hat(r0.a) * Theta) + R1 * (r1.A - lie::hat(r1.a) * Theta1));
          dp += dv * dt + a * (0.5 * dt * dt);
          P += V * dt + A * (0.5 * dt * dt);
          dv += a * dt;
          V += A * dt;
        }
        dR = R1;
        Theta = Theta1;
      }
      std::swap(r0, r1);
    }
  }
  out->dR = dR;
  out->dp = dp;
  out->dv = dv;
  out->J.topRows<3>() = Theta;
  out->J.middleRows<3>(3) = P;
  out->J.bottomRows<3>() = V;
}

}  // namespace

Eigen::Matrix3d upperTriangular(const double* d) { return upperT<double>(d); }

void intrinsicsToBlock(const ImuIntrinsics& in, double* block, bool kalibr) {
  Eigen::Matrix3d Dw = in.Tw.inverse(), Da = in.Ta.inverse();
  if (kalibr) {  // lower triangular: stored as the transposes' upper entries
    Dw.transposeInPlace();
    Da.transposeInPlace();
  }
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r <= c; ++r) {
      block[L::kDw + upperIndex(r, c)] = Dw(r, c);
      block[L::kDa + upperIndex(r, c)] = Da(r, c);
    }
  }
  for (int k = 0; k < 9; ++k) block[L::kTg + k] = in.Tg(k / 3, k % 3);
  for (int k = 0; k < 3; ++k) block[L::kAccRotation + k] = 0.0;
}

ImuIntrinsics intrinsicsFromBlock(const double* block, const Eigen::Matrix3d& R0) {
  ImuIntrinsicsFrame frame;
  frame.R0 = R0;
  return intrinsicsFromBlock(block, frame);
}

ImuIntrinsics intrinsicsFromBlock(const double* block, const ImuIntrinsicsFrame& frame) {
  ImuIntrinsics out;
  out.Tw = upperTriangular(block + L::kDw).inverse();
  out.Ta = upperTriangular(block + L::kDa).inverse();
  // Exact inverses of upper-triangular matrices are upper triangular; clear the rounding.
  out.Tw.triangularView<Eigen::StrictlyLower>().setZero();
  out.Ta.triangularView<Eigen::StrictlyLower>().setZero();
  for (int k = 0; k < 9; ++k) out.Tg(k / 3, k % 3) = block[L::kTg + k];
  const Eigen::Matrix3d R_to_imu = frame.R0 * lie::expSO3(Eigen::Vector3d(block + L::kAccRotation));
  if (frame.kalibr) {
    out.Tw.transposeInPlace();
    out.Ta.transposeInPlace();
    out.R_IMUtoGYRO = R_to_imu.transpose();
  } else {
    out.R_IMUtoACC = R_to_imu.transpose();
  }
  return out;
}

ImuDeltas::Vector30d deltaVariables(const double* bias_gyro, const double* bias_accel,
                                    const double* intrinsics) {
  ImuDeltas::Vector30d x = ImuDeltas::Vector30d::Zero();
  x.head<3>() = Eigen::Vector3d(bias_gyro);
  if (bias_accel != nullptr) x.segment<3>(3) = Eigen::Vector3d(bias_accel);
  if (intrinsics != nullptr) {
    x.tail<kImuIntrinsicsSize>() =
        Eigen::Map<const Eigen::Matrix<double, kImuIntrinsicsSize, 1>>(intrinsics);
  } else {
    static const ImuDeltas::Vector30d identity = [] {
      ImuDeltas::Vector30d v = ImuDeltas::Vector30d::Zero();
      intrinsicsToBlock(ImuIntrinsics(), v.data() + 6);
      return v;
    }();
    x.tail<kImuIntrinsicsSize>() = identity.tail<kImuIntrinsicsSize>();
  }
  return x;
}

ImuDeltas reintegrate(const std::vector<ImuMeasurement>& samples, const ImuDeltas::Vector30d& x,
                      const ImuIntrinsicsFrame& frame, bool jacobians) {
  ImuDeltas out;
  out.x0 = x;
  if (!samples.empty())
    out.duration = toSeconds(samples.back().stamp_ns - samples.front().stamp_ns);
  if (!jacobians) {
    integrate<double>(samples, x, frame, &out.dR, &out.dp, &out.dv);
    return out;
  }
  integrateWithJacobian(samples, x, frame, &out);
  return out;
}

const ImuDeltas& factorDeltas(const ImuPreintegration& pre, bool intrinsics,
                              IntrinsicsLinearization mode, const ImuDeltas& fixed,
                              const ImuDeltas::Vector30d& x, const ImuIntrinsicsFrame& frame,
                              bool jacobians, ImuDeltas* local) {
  if (!intrinsics) {
    *local = deltasOf(pre);
    return *local;
  }
  if (mode == IntrinsicsLinearization::kFixed) return fixed;
  *local = reintegrate(pre.samples(), x, frame, jacobians);
  return *local;
}

ImuDeltas deltasOf(const ImuPreintegration& pre) {
  using P = ImuPreintegration;
  ImuDeltas out;
  out.x0 = deltaVariables(pre.biasGyro().data(), pre.biasAccel().data(), nullptr);
  out.dR = pre.deltaR().toRotationMatrix();
  out.dp = pre.deltaP();
  out.dv = pre.deltaV();
  out.duration = pre.duration();
  const auto& J = pre.jacobian();
  for (int row = 0; row < 3; ++row) {
    out.J.row(row).head<6>() = J.row(P::kRotation + row).segment<6>(P::kBiasGyro);
    out.J.row(3 + row).head<6>() = J.row(P::kPosition + row).segment<6>(P::kBiasGyro);
    out.J.row(6 + row).head<6>() = J.row(P::kVelocity + row).segment<6>(P::kBiasGyro);
  }
  return out;
}

void noiseMapInverses(const double* intrinsics, const ImuIntrinsicsFrame& frame,
                      const Eigen::Matrix<double, 9, 1>& r, Eigen::Matrix<double, 9, 1>* out,
                      Eigen::Matrix<double, 9, kImuIntrinsicsSize>* jacobian,
                      Eigen::Matrix3d* G_inv, Eigen::Matrix3d* M_inv) {
  using Jet = ceres::Jet<double, kImuIntrinsicsSize>;
  std::array<Jet, kImuIntrinsicsSize> in;
  for (int k = 0; k < kImuIntrinsicsSize; ++k) in[k] = Jet(intrinsics[k], k);
  Mat3<Jet> G, M;
  correctionMaps<Jet>(in.data(), frame, &G, &M);
  const Mat3<Jet> Gi = G.inverse();
  const Mat3<Jet> Mi = frame.gyro_only ? Mat3<Jet>(Mat3<Jet>::Identity()) : Mat3<Jet>(M.inverse());
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      (*G_inv)(i, j) = Gi(i, j).a;
      (*M_inv)(i, j) = Mi(i, j).a;
    }
  }
  Vec3<Jet> part[3];
  part[0] = Gi * r.head<3>().cast<Jet>();
  part[1] = Mi * r.segment<3>(3).cast<Jet>();
  part[2] = Mi * r.tail<3>().cast<Jet>();
  for (int b = 0; b < 3; ++b) {
    for (int i = 0; i < 3; ++i) {
      (*out)[3 * b + i] = part[b][i].a;
      if (jacobian != nullptr) jacobian->row(3 * b + i) = part[b][i].v.transpose();
    }
  }
}

}  // namespace mvis
