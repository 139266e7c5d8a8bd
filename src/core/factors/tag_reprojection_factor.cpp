#include "mvis/factors/tag_reprojection_factor.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <mutex>

#include "../common/tangent_jet.h"
#include "mvis/camera/camera_model.h"
#include "mvis/common/lie.h"
#include "mvis/factors/state_blocks.h"

namespace mvis {
namespace {

// Directions of the camera pose's derivatives: [dtheta_k, dp_k] 0-5; v_k, b_g,k, b_a,k 6-14
// (or dtheta_k+1, dp_k+1 6-11 for pose-based); gravity 15-17; dtheta_e, dp_e 18-23; t_d 24;
// with the IMU intrinsics or the propagation noise the anchor's deltas [dtheta, dp, dv] 25-33.
constexpr int kStageDim = 25, kDeltaJet = 25;
constexpr int kExtrinsicJet = 18, kTimeOffsetJet = 24;

using tangent_jet::expT;
using tangent_jet::logT;
using tangent_jet::Mat3;
using tangent_jet::Vec3;

}  // namespace

TagReprojectionFactor* TagReprojectionFactor::kinematic(DistortionModel model,
                                                        std::vector<CornerObservation> corners,
                                                        double pixel_sigma, double dt_nominal,
                                                        const Eigen::Vector3d& gyro_k) {
  return new TagReprojectionFactor(Interpolation::kKinematic, model, std::move(corners),
                                   pixel_sigma, dt_nominal, 0.0, gyro_k);
}

TagReprojectionFactor* TagReprojectionFactor::poseBased(DistortionModel model,
                                                        std::vector<CornerObservation> corners,
                                                        double pixel_sigma, double dt_nominal,
                                                        double interval) {
  return new TagReprojectionFactor(Interpolation::kPoseBased, model, std::move(corners),
                                   pixel_sigma, dt_nominal, interval, Eigen::Vector3d::Zero());
}

TagReprojectionFactor::ImuAnchor TagReprojectionFactor::makeAnchor(
    const ImuPreintegration& pre, double dt_nominal, const Eigen::Vector3d& gyro,
    const Eigen::Vector3d& accel, const Eigen::Vector3d& angular_acceleration) {
  return makeAnchor(deltasOf(pre), false, dt_nominal, gyro, accel, angular_acceleration);
}

TagReprojectionFactor::ImuAnchor TagReprojectionFactor::makeAnchor(
    const ImuDeltas& deltas, bool with_intrinsics, double dt_nominal, const Eigen::Vector3d& gyro,
    const Eigen::Vector3d& accel, const Eigen::Vector3d& angular_acceleration) {
  ImuAnchor a;
  a.T_a = deltas.duration;
  a.dt_nominal = dt_nominal;
  a.dR = Eigen::Quaterniond(deltas.dR).normalized();
  a.dp = deltas.dp;
  a.dv = deltas.dv;
  a.bias_gyro0 = deltas.x0.head<3>();
  a.bias_accel0 = deltas.x0.segment<3>(3);
  a.J_R_bg = deltas.J.block<3, 3>(0, 0);
  a.J_p_bg = deltas.J.block<3, 3>(3, 0);
  a.J_p_ba = deltas.J.block<3, 3>(3, 3);
  a.J_v_bg = deltas.J.block<3, 3>(6, 0);
  a.J_v_ba = deltas.J.block<3, 3>(6, 3);
  a.gyro = gyro;
  a.accel = accel;
  a.angular_acceleration = angular_acceleration;
  a.with_intrinsics = with_intrinsics;
  if (with_intrinsics) {
    a.J_intrinsics = deltas.J.rightCols<kImuIntrinsicsSize>();
    a.intrinsics0 = deltas.x0.tail<kImuIntrinsicsSize>();
  }
  return a;
}

TagReprojectionFactor* TagReprojectionFactor::imuPropagated(DistortionModel model,
                                                            std::vector<CornerObservation> corners,
                                                            double pixel_sigma,
                                                            const ImuAnchor& anchor) {
  auto* f = new TagReprojectionFactor(Interpolation::kImuPropagated, model, std::move(corners),
                                      pixel_sigma, anchor.dt_nominal, 0.0, anchor.gyro);
  f->anchor_ = anchor;
  if (anchor.with_intrinsics) f->mutable_parameter_block_sizes()->push_back(kImuIntrinsicsSize);
  return f;
}

TagReprojectionFactor::TagReprojectionFactor(Interpolation interpolation, DistortionModel model,
                                             std::vector<CornerObservation> corners,
                                             double pixel_sigma, double dt_nominal, double interval,
                                             const Eigen::Vector3d& gyro_k)
    : interpolation_(interpolation),
      model_(model),
      corners_(std::move(corners)),
      sigma_(pixel_sigma),
      dt_nominal_(dt_nominal),
      interval_(interval),
      gyro_k_(gyro_k) {
  set_num_residuals(2 * static_cast<int>(corners_.size()));
  switch (interpolation) {
    case Interpolation::kKinematic:
      layout_ = {{0, 6, 7}, {6, 9, 9}, {kExtrinsicJet, 6, 7}, {kTimeOffsetJet, 1, 1}};
      break;
    case Interpolation::kPoseBased:
      layout_ = {{0, 6, 7}, {6, 6, 7}, {kExtrinsicJet, 6, 7}, {kTimeOffsetJet, 1, 1}};
      break;
    case Interpolation::kImuPropagated:
      layout_ = {{0, 6, 7}, {6, 9, 9}, {15, 3, 3}, {kExtrinsicJet, 6, 7}, {kTimeOffsetJet, 1, 1}};
      break;
  }
  auto* sizes = mutable_parameter_block_sizes();
  sizes->clear();
  for (const auto& b : layout_) sizes->push_back(b.ambient);
  sizes->push_back(8);
  shared_ = makeSharedCameraPose();
}

struct TagReprojectionFactor::SharedCameraPose {
  std::mutex mutex;         // Ceres may evaluate residual blocks in parallel
  std::vector<double> key;  // the parameter values it was computed at (but a landmark's)
  int dim = 0;
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  Eigen::MatrixXd G;  // the camera pose's tangent per jet direction (see evaluate)
};

std::shared_ptr<TagReprojectionFactor::SharedCameraPose>
TagReprojectionFactor::makeSharedCameraPose() {
  return std::make_shared<SharedCameraPose>();
}

void TagReprojectionFactor::shareCameraPose(std::shared_ptr<SharedCameraPose> shared) {
  if (landmark_block_ >= 0) shared_ = std::move(shared);
}

void TagReprojectionFactor::usePropagationNoise() {
  if (interpolation_ != Interpolation::kImuPropagated || noise_block_ >= 0) return;
  auto* sizes = mutable_parameter_block_sizes();
  noise_block_ = static_cast<int>(sizes->size());
  sizes->push_back(kPropagationNoiseSize);
}

bool TagReprojectionFactor::compressRows(bool with_intrinsics) {
  const int columns = with_intrinsics ? kPoseColumns + kIntrinsicsSize : kPoseColumns;
  if (landmark_block_ >= 0 || compressed_columns_ > 0 ||
      2 * static_cast<int>(corners_.size()) <= columns + 1) {
    return compressed_columns_ > 0;
  }
  compressed_columns_ = columns;
  set_num_residuals(columns + 1);
  return true;
}

void TagReprojectionFactor::useLandmarkBlock() {
  auto* sizes = mutable_parameter_block_sizes();
  landmark_block_ = static_cast<int>(sizes->size());
  sizes->push_back(kTagLandmarkSize);
}

bool TagReprojectionFactor::Evaluate(double const* const* parameters, double* residuals,
                                     double** jacobians) const {
  return interpolation_ == Interpolation::kImuPropagated &&
                 (anchor_.with_intrinsics || noise_block_ >= 0)
             ? evaluate<kStageDim + 9>(parameters, residuals, jacobians)
             : evaluate<kStageDim>(parameters, residuals, jacobians);
}

bool TagReprojectionFactor::cornerResiduals(double const* const* parameters,
                                            double* residuals) const {
  return interpolation_ == Interpolation::kImuPropagated &&
                 (anchor_.with_intrinsics || noise_block_ >= 0)
             ? evaluate<kStageDim + 9>(parameters, residuals, nullptr, true)
             : evaluate<kStageDim>(parameters, residuals, nullptr, true);
}

bool TagReprojectionFactor::cornerLoss(Eigen::Vector2d* r, Eigen::Matrix2d* M) const {
  const double c = corner_loss_;
  const double n = r->norm();
  if (!(c > 0.0) || !(n > c)) return false;
  const double g = std::sqrt(2.0 * c * n - c * c);  // sqrt(rho(n^2))
  const Eigen::Vector2d u = *r / n;
  *r = g * u;
  const Eigen::Matrix2d uu = u * u.transpose();
  *M = (c / g) * uu + (g / n) * (Eigen::Matrix2d::Identity() - uu);
  return true;
}

template <typename StageJet, bool kDeltas>
void TagReprojectionFactor::cameraPose(double const* const* parameters,
                                       const Eigen::Matrix<double, 9, 1>& lin,
                                       Eigen::Matrix<StageJet, 3, 3>* R_CG_out,
                                       Eigen::Matrix<StageJet, 3, 1>* t_CG_out) const {
  const auto perturbRotation = [](const Eigen::Quaterniond& q, int first) {
    return tangent_jet::perturbRotation<StageJet>(q, first);
  };
  const auto perturbVector = [](const double* x, int first) {
    return tangent_jet::perturbVector<StageJet>(x, first);
  };
  const int n_blocks = static_cast<int>(layout_.size());
  const double* pose_k = parameters[0];
  const Mat3<StageJet> R_k = perturbRotation(poseRotation(pose_k), 0);
  const Vec3<StageJet> p_k = perturbVector(pose_k + 4, 3);
  const StageJet t_d =
      tangent_jet::perturbScalar<StageJet>(parameters[n_blocks - 1][0], kTimeOffsetJet);
  const StageJet dt = StageJet(dt_nominal_) + t_d;

  Mat3<StageJet> R;  // R_G_I(t)
  Vec3<StageJet> p;  // p_G_I(t)
  if (interpolation_ == Interpolation::kKinematic) {
    const Vec3<StageJet> v = perturbVector(parameters[1], 6);
    const Vec3<StageJet> b_g = perturbVector(parameters[1] + 3, 9);
    const Vec3<StageJet> w = gyro_k_.cast<StageJet>() - b_g;
    R = R_k * expT<StageJet>(w * dt);
    p = p_k + v * dt;
  } else if (interpolation_ == Interpolation::kPoseBased) {
    const double* pose_k1 = parameters[1];
    const Mat3<StageJet> R_k1 = perturbRotation(poseRotation(pose_k1), 6);
    const Vec3<StageJet> p_k1 = perturbVector(pose_k1 + 4, 9);
    const StageJet s = dt / interval_;
    const Mat3<StageJet> R_rel = R_k.transpose() * R_k1;
    R = R_k * expT<StageJet>(logT(R_rel) * s);
    p = p_k + (p_k1 - p_k) * s;
  } else {
    const ImuAnchor& a = anchor_;
    const Vec3<StageJet> v = perturbVector(parameters[1], 6);
    const Vec3<StageJet> b_g = perturbVector(parameters[1] + 3, 9);
    const Vec3<StageJet> b_a = perturbVector(parameters[1] + 6, 12);
    const Vec3<StageJet> g = perturbVector(parameters[2], 15);
    const Vec3<StageJet> dbg = b_g - a.bias_gyro0.cast<StageJet>();
    const Vec3<StageJet> dba = b_a - a.bias_accel0.cast<StageJet>();
    Mat3<StageJet> dR =
        a.dR.toRotationMatrix().cast<StageJet>() * expT<StageJet>(a.J_R_bg.cast<StageJet>() * dbg);
    Vec3<StageJet> dp =
        a.dp.cast<StageJet>() + a.J_p_bg.cast<StageJet>() * dbg + a.J_p_ba.cast<StageJet>() * dba;
    Vec3<StageJet> dv =
        a.dv.cast<StageJet>() + a.J_v_bg.cast<StageJet>() * dbg + a.J_v_ba.cast<StageJet>() * dba;
    if constexpr (kDeltas) {
      // The intrinsics' first-order change, with its own directions (chained below).
      Vec3<StageJet> e_R, e_p, e_v;
      for (int i = 0; i < 3; ++i) {
        e_R[i] = tangent_jet::perturbScalar<StageJet>(0.0, kDeltaJet + i);
        e_p[i] = tangent_jet::perturbScalar<StageJet>(lin[3 + i], kDeltaJet + 3 + i);
        e_v[i] = tangent_jet::perturbScalar<StageJet>(lin[6 + i], kDeltaJet + 6 + i);
      }
      dR = dR * lie::expSO3(lin.head<3>()).cast<StageJet>() * expT<StageJet>(e_R);
      dp += e_p;
      dv += e_v;
    }
    const StageJet T(a.T_a);
    const Mat3<StageJet> R_a = R_k * dR;
    const Vec3<StageJet> p_a = p_k + v * T + g * (StageJet(0.5) * T * T) + R_k * dp;
    const Vec3<StageJet> v_a = v + g * T + R_k * dv;
    const Vec3<StageJet> w = a.gyro.cast<StageJet>() - b_g;
    const Vec3<StageJet> acc = R_a * (a.accel.cast<StageJet>() - b_a) + g;
    R = R_a * expT<StageJet>(w * dt +
                             a.angular_acceleration.cast<StageJet>() * (StageJet(0.5) * dt * dt));
    p = p_a + v_a * dt + acc * (StageJet(0.5) * dt * dt);
  }
  const double* extrinsic = parameters[n_blocks - 2];
  const Mat3<StageJet> R_CI = perturbRotation(poseRotation(extrinsic), kExtrinsicJet);
  const Vec3<StageJet> p_CI = perturbVector(extrinsic + 4, kExtrinsicJet + 3);
  *R_CG_out = R_CI * R.transpose();
  *t_CG_out = p_CI - *R_CG_out * p;
}

template <int Dim>
void TagReprojectionFactor::imuCameraTangent(double const* const* parameters,
                                             const Eigen::Matrix<double, 9, 1>& lin,
                                             Eigen::Matrix3d* R_CG, Eigen::Vector3d* t_CG,
                                             Eigen::Matrix<double, 6, Dim>* G) const {
  // The IMU-propagated pose of the header, differentiated by hand: per direction the IMU pose's
  // right perturbation dtheta_R and its position's change dp, then the camera pose's tangent
  // omega = -R_CI dtheta_R, v = -R_CG dp + p_CI x omega (extrinsic: omega = R_CI dtheta_e,
  // v = dp_e + p_CI x omega). The same quantities as cameraPose<Jet> computes.
  using Eigen::Matrix3d;
  using Eigen::Vector3d;
  const ImuAnchor& a = anchor_;
  const double* pose_k = parameters[0];
  const Matrix3d R_k = poseRotation(pose_k).toRotationMatrix();
  const Vector3d p_k(pose_k + 4), v(parameters[1]), b_g(parameters[1] + 3), b_a(parameters[1] + 6),
      g(parameters[2]);
  const double dt = dt_nominal_ + parameters[4][0];
  const Vector3d dbg = b_g - a.bias_gyro0, dba = b_a - a.bias_accel0;
  const Vector3d phi_b = a.J_R_bg * dbg;
  const bool deltas = Dim > kStageDim;
  const Matrix3d RL = deltas ? lie::expSO3(lin.head<3>()) : Matrix3d::Identity();
  const Matrix3d dR = a.dR.toRotationMatrix() * lie::expSO3(phi_b) * RL;
  Vector3d dp = a.dp + a.J_p_bg * dbg + a.J_p_ba * dba;
  Vector3d dv = a.dv + a.J_v_bg * dbg + a.J_v_ba * dba;
  if (deltas) {
    dp += lin.segment<3>(3);
    dv += lin.segment<3>(6);
  }
  const double T = a.T_a;
  const Matrix3d R_a = R_k * dR;
  const Vector3d p_a = p_k + v * T + g * (0.5 * T * T) + R_k * dp;
  const Vector3d v_a = v + g * T + R_k * dv;
  const Vector3d w = a.gyro - b_g;
  const Vector3d f = a.accel - b_a;
  const Vector3d acc = R_a * f + g;
  const Vector3d psi = w * dt + a.angular_acceleration * (0.5 * dt * dt);
  const Matrix3d RE = lie::expSO3(psi);
  const Matrix3d R = R_a * RE;
  const double h = 0.5 * dt * dt;
  const Vector3d p = p_a + v_a * dt + acc * h;
  const double* extrinsic = parameters[3];
  const Matrix3d R_CI = poseRotation(extrinsic).toRotationMatrix();
  const Vector3d p_CI(extrinsic + 4);
  *R_CG = R_CI * R.transpose();
  *t_CG = p_CI - *R_CG * p;

  // IMU pose changes [dtheta_R; dp] per direction, then the camera's.
  Eigen::Matrix<double, 6, Dim> imu = Eigen::Matrix<double, 6, Dim>::Zero();
  const Matrix3d RE_t = RE.transpose();
  const Matrix3d Jr_psi = lie::rightJacobianSO3(psi);
  const Matrix3d acc_rot = -h * R_a * lie::hat(f);  // dp per right perturbation of R_a
  // State k's rotation: R_a -> R_a Exp(dR^T d).
  imu.template block<3, 3>(0, 0) = RE_t * dR.transpose();
  imu.template block<3, 3>(3, 0) =
      -R_k * lie::hat(dp) - dt * R_k * lie::hat(dv) + acc_rot * dR.transpose();
  imu.template block<3, 3>(3, 3) = Matrix3d::Identity();             // p_k
  imu.template block<3, 3>(3, 6) = (T + dt) * Matrix3d::Identity();  // v_k
  // b_g: the deltas' rotation dR -> dR Exp(RL^T Jr(phi_b) J_R_bg d), and psi -> psi - dt d.
  const Matrix3d bg_rot = RL.transpose() * lie::rightJacobianSO3(phi_b) * a.J_R_bg;
  imu.template block<3, 3>(0, 9) = RE_t * bg_rot - dt * Jr_psi;
  imu.template block<3, 3>(3, 9) = R_k * (a.J_p_bg + dt * a.J_v_bg) + acc_rot * bg_rot;
  imu.template block<3, 3>(3, 12) = R_k * (a.J_p_ba + dt * a.J_v_ba) - h * R_a;         // b_a
  imu.template block<3, 3>(3, 15) = (0.5 * T * T + T * dt + h) * Matrix3d::Identity();  // g
  imu.template block<3, 1>(0, kTimeOffsetJet) = Jr_psi * (w + a.angular_acceleration * dt);
  imu.template block<3, 1>(3, kTimeOffsetJet) = v_a + acc * dt;
  if constexpr (Dim > kStageDim) {
    imu.template block<3, 3>(0, kDeltaJet) = RE_t;  // e_R: dR -> dR Exp(e_R)
    imu.template block<3, 3>(3, kDeltaJet) = acc_rot;
    imu.template block<3, 3>(3, kDeltaJet + 3) = R_k;       // e_p
    imu.template block<3, 3>(3, kDeltaJet + 6) = dt * R_k;  // e_v
  }
  const Matrix3d p_CI_hat = lie::hat(p_CI);
  G->template topRows<3>() = -R_CI * imu.template topRows<3>();
  G->template bottomRows<3>() =
      -*R_CG * imu.template bottomRows<3>() + p_CI_hat * G->template topRows<3>();
  // The extrinsic's own directions.
  G->template block<3, 3>(0, kExtrinsicJet) = R_CI;
  G->template block<3, 3>(3, kExtrinsicJet) = p_CI_hat * R_CI;
  G->template block<3, 3>(3, kExtrinsicJet + 3) = Matrix3d::Identity();
}

template <int Dim>
void TagReprojectionFactor::cameraPose(double const* const* parameters,
                                       const Eigen::Matrix<double, 9, 1>& lin,
                                       CameraPose<Dim>* out) const {
  using StageJet = ceres::Jet<double, Dim>;
  Mat3<StageJet> R_CG;
  Vec3<StageJet> t_CG;
  cameraPose<StageJet, (Dim > kStageDim)>(parameters, lin, &R_CG, &t_CG);
  for (int i = 0; i < 3; ++i) {
    out->t[i] = t_CG[i].a;
    out->dT.row(i) = t_CG[i].v.transpose();
    for (int j = 0; j < 3; ++j) {
      out->R(i, j) = R_CG(i, j).a;
      out->dR[j].row(i) = R_CG(i, j).v.transpose();
    }
  }
}

template <int Dim>
bool TagReprojectionFactor::evaluate(double const* const* parameters, double* residuals,
                                     double** jacobians, bool per_corner) const {
  // Stage 1: the camera pose, p_C = R_C_G p_G + t_C_G, with derivatives in the directions
  // listed at kStageDim.
  const int n_blocks = static_cast<int>(layout_.size());
  // The anchor deltas' change: with the IMU intrinsics their first-order change
  // J_I (x_I - x_I0), plus the propagation noise.
  Eigen::Matrix<double, 9, 1> lin = Eigen::Matrix<double, 9, 1>::Zero();
  if constexpr (Dim > kStageDim) {
    if (anchor_.with_intrinsics) {
      lin = anchor_.J_intrinsics * (Eigen::Map<const Eigen::Matrix<double, kImuIntrinsicsSize, 1>>(
                                        parameters[n_blocks + 1]) -
                                    anchor_.intrinsics0);
    }
    if (noise_block_ >= 0) {
      lin += Eigen::Map<const Eigen::Matrix<double, kPropagationNoiseSize, 1>>(
          parameters[noise_block_]);
    }
  }
  // Stage 2: the camera pose's change in its own tangent [omega; v] (R_CG -> Exp(omega) R_CG,
  // t_CG -> Exp(omega) t_CG + v) per jet direction: omega from dR R^T (skew), v = dt + t x omega.
  // A corner then moves by dp_C = -[p_C]x omega + v, so that each corner needs only its 2 x 6
  // projection Jacobian in that tangent, and each block the 6 x n map G_b below. IMU-propagated:
  // by hand; kinematic and pose-based: from jets, once per set of parameter values (without a
  // board a frame's tag factors share it). For the cost alone only R_CG, t_CG, on doubles.
  Eigen::Matrix3d R_val;
  Eigen::Vector3d t_val;
  Eigen::Matrix<double, 6, Dim> G;
  if (jacobians == nullptr) {
    // The cost alone (Ceres's candidate steps): no derivatives.
    cameraPose<double, (Dim > kStageDim)>(parameters, lin, &R_val, &t_val);
  } else if (interpolation_ == Interpolation::kImuPropagated) {
    imuCameraTangent<Dim>(parameters, lin, &R_val, &t_val, &G);
  } else if constexpr (Dim == kStageDim) {  // kinematic, pose-based: jets
    std::vector<double> key;
    const std::vector<int32_t>& sizes = parameter_block_sizes();
    for (int b = 0; b < static_cast<int>(sizes.size()); ++b) {
      if (b != landmark_block_) key.insert(key.end(), parameters[b], parameters[b] + sizes[b]);
    }
    std::lock_guard<std::mutex> lock(shared_->mutex);
    if (shared_->key != key || shared_->dim != Dim) {
      CameraPose<Dim> pose;
      cameraPose<Dim>(parameters, lin, &pose);
      R_val = pose.R;
      t_val = pose.t;
      for (int d = 0; d < Dim; ++d) {
        Eigen::Matrix3d dR_d;
        for (int j = 0; j < 3; ++j) dR_d.col(j) = pose.dR[j].col(d);
        const Eigen::Matrix3d W = dR_d * R_val.transpose();
        const Eigen::Vector3d w(0.5 * (W(2, 1) - W(1, 2)), 0.5 * (W(0, 2) - W(2, 0)),
                                0.5 * (W(1, 0) - W(0, 1)));
        G.template block<3, 1>(0, d) = w;
        G.template block<3, 1>(3, d) = pose.dT.col(d) + t_val.cross(w);
      }
      shared_->key = std::move(key);
      shared_->dim = Dim;
      shared_->R = R_val;
      shared_->t = t_val;
      shared_->G = G;
    } else {
      R_val = shared_->R;
      t_val = shared_->t;
      G = shared_->G;
    }
  }

  // The blocks' maps G_b (camera tangent per block tangent), but the camera intrinsics' and the
  // landmark's, which enter per corner.
  struct BlockMap {
    int block, ambient;
    Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kImuIntrinsicsSize> G;
  };
  std::vector<BlockMap> maps;
  if (jacobians != nullptr) {
    for (int b = 0; b < n_blocks; ++b) {
      if (jacobians[b] == nullptr) continue;
      const BlockLayout& l = layout_[b];
      maps.push_back({b, l.ambient, G.middleCols(l.jet_offset, l.columns)});
    }
    if constexpr (Dim > kStageDim) {
      // d(anchor rotation perturbation) / d(its change): Exp(phi + d) = Exp(phi) Exp(Jr(phi) d),
      // chained with the intrinsics' J_I.
      const Eigen::Matrix3d right_jacobian = lie::rightJacobianSO3(lin.head<3>());
      if (anchor_.with_intrinsics && jacobians[n_blocks + 1] != nullptr) {
        maps.push_back(
            {n_blocks + 1, kImuIntrinsicsSize,
             G.template middleCols<3>(kDeltaJet) * right_jacobian *
                     anchor_.J_intrinsics.topRows<3>() +
                 G.template middleCols<6>(kDeltaJet + 3) * anchor_.J_intrinsics.bottomRows<6>()});
      }
      if (noise_block_ >= 0 && jacobians[noise_block_] != nullptr) {
        Eigen::Matrix<double, 6, kPropagationNoiseSize> G_n;
        G_n << G.template middleCols<3>(kDeltaJet) * right_jacobian,
            G.template middleCols<6>(kDeltaJet + 3);
        maps.push_back({noise_block_, kPropagationNoiseSize, G_n});
      }
    }
  }
  double* J_intrinsics = jacobians != nullptr ? jacobians[n_blocks] : nullptr;
  const double* intrinsics = parameters[n_blocks];
  const double inv_sigma = 1.0 / sigma_;
  const double* landmark = landmark_block_ >= 0 ? parameters[landmark_block_] : nullptr;
  double* J_landmark =
      landmark != nullptr && jacobians != nullptr ? jacobians[landmark_block_] : nullptr;
  if (J_landmark != nullptr) {
    std::fill(J_landmark, J_landmark + num_residuals() * kTagLandmarkSize, 0.0);
  }
  // Compressed: the corners' rows [J_6 (J_k) r] (whitened, after the loss), for the normal
  // equations at the end.
  const bool compressed = compressed_columns_ > 0 && !per_corner;
  const int C = compressed_columns_;
  if (compressed && jacobians != nullptr && C == kPoseColumns && J_intrinsics != nullptr) {
    return false;  // compressed without the intrinsics: their Jacobian is not available
  }
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, Eigen::Dynamic, kMaxCompressedRows> A;
  if (compressed && jacobians != nullptr) {
    A.resize(2 * static_cast<Eigen::Index>(corners_.size()), C + 1);
  }
  double squares = 0.0;
  Eigen::Vector2d uv;
  Eigen::Matrix<double, 2, 3> J_pc;
  Eigen::Matrix<double, 2, 8> J_k;
  for (std::size_t c = 0; c < corners_.size(); ++c) {
    const Eigen::Vector3d p_G = landmark != nullptr
                                    ? Eigen::Vector3d(landmark + 3 * corners_[c].landmark)
                                    : corners_[c].p_G;
    const Eigen::Vector3d pc = R_val * p_G + t_val;
    if (!(pc[2] > 1e-6)) return false;  // behind the camera: Ceres rejects the step
    if (jacobians == nullptr) {
      uv = projectPoint<double>(model_, Eigen::Vector4d(intrinsics),
                                Eigen::Vector4d(intrinsics + 4), pc);
    } else {
      projectWithJacobians(model_, intrinsics, pc, &uv, &J_pc, &J_k);
    }
    Eigen::Vector2d r = (uv - corners_[c].uv) * inv_sigma;
    Eigen::Matrix2d M = Eigen::Matrix2d::Identity();
    const bool robust = cornerLoss(&r, &M);
    squares += r.squaredNorm();
    const int row = 2 * static_cast<int>(c);
    if (!compressed) residuals[row] = r[0], residuals[row + 1] = r[1];
    if (jacobians == nullptr) continue;

    Eigen::Matrix<double, 2, kPoseColumns + kIntrinsicsSize> J;  // [J_6 (camera tangent), J_k]
    const Eigen::Matrix<double, 2, 3> J_w =
        robust ? (M * J_pc * inv_sigma).eval() : (J_pc * inv_sigma).eval();
    J.template leftCols<3>() = J_w * lie::hat(pc).transpose();
    J.template middleCols<3>(3) = J_w;
    J.template rightCols<8>() = robust ? (M * J_k * inv_sigma).eval() : (J_k * inv_sigma).eval();
    if (compressed) {
      A.block(row, 0, 2, C) = J.leftCols(C);
      A.block(row, C, 2, 1) = r;
      continue;
    }
    for (const BlockMap& m : maps) {
      Eigen::Map<Eigen::Matrix<double, 2, Eigen::Dynamic, Eigen::RowMajor>> out(
          jacobians[m.block] + m.ambient * row, 2, m.ambient);
      out.leftCols(m.G.cols()) = J.template leftCols<6>().lazyProduct(m.G);
      out.rightCols(m.ambient - m.G.cols()).setZero();
    }
    if (J_intrinsics != nullptr) {
      Eigen::Map<Eigen::Matrix<double, 2, 8, Eigen::RowMajor>>(J_intrinsics + 8 * row) =
          J.template rightCols<8>();
    }
    if (J_landmark != nullptr) {
      const Eigen::Matrix<double, 2, 3> J_p = J_w * R_val;
      for (int i = 0; i < 2; ++i) {
        double* out = J_landmark + kTagLandmarkSize * (row + i) + 3 * corners_[c].landmark;
        for (int j = 0; j < 3; ++j) out[j] = J_p(i, j);
      }
    }
  }
  if (!compressed) return true;
  // Compressed rows (see the header): H = P^T L D L^T P, rows S = D^1/2 L^T P, residuals
  // e = D^-1/2 L^-1 P g (S^T e = g), and one more row holding the rest of the squares.
  std::fill(residuals, residuals + C + 1, 0.0);
  if (jacobians == nullptr) {
    residuals[0] = std::sqrt(squares);
    return true;
  }
  using Square = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxCompressedRows,
                               kMaxCompressedRows>;
  Square N = Square::Zero(C + 1, C + 1);
  N.selfadjointView<Eigen::Lower>().rankUpdate(A.transpose());
  const Square H = N.topLeftCorner(C, C).selfadjointView<Eigen::Lower>();
  const Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxCompressedRows, 1> g =
      N.bottomLeftCorner(1, C).transpose();
  const Eigen::LDLT<Square> ldlt(H);
  Square S = Square::Identity(C, C);
  S = ldlt.transpositionsP() * S;  // P
  Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxCompressedRows, 1> e =
      ldlt.matrixL().solve(S * g);
  S = ldlt.matrixU() * S;  // L^T P
  const auto D = ldlt.vectorD();
  const double floor = 1e-12 * std::max(D.maxCoeff(), 0.0);
  double explained = 0.0;
  for (int k = 0; k < C; ++k) {
    const double d = D[k] > floor ? std::sqrt(D[k]) : 0.0;
    S.row(k) *= d;
    e[k] = d > 0.0 ? e[k] / d : 0.0;
    residuals[k] = e[k];
    explained += e[k] * e[k];
  }
  residuals[C] = std::sqrt(std::max(squares - explained, 0.0));
  for (const BlockMap& m : maps) {
    Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> out(
        jacobians[m.block], C + 1, m.ambient);
    out.setZero();
    out.topLeftCorner(C, m.G.cols()) = S.leftCols(kPoseColumns).lazyProduct(m.G);
  }
  if (J_intrinsics != nullptr) {
    Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, 8, Eigen::RowMajor>> out(J_intrinsics, C + 1,
                                                                              8);
    out.setZero();
    out.topRows(C) = S.rightCols(8);
  }
  return true;
}

}  // namespace mvis
