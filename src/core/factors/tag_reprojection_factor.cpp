#include "mvis/factors/tag_reprojection_factor.h"

#include <ceres/jet.h>
#include <ceres/rotation.h>

#include "mvis/camera/camera_model.h"
#include "mvis/estimator/state_blocks.h"

namespace mvis {
namespace {

constexpr int kStageDim = 19;  // tangent directions of the camera pose (see the header)
using Jet19 = ceres::Jet<double, kStageDim>;
using Jet11 = ceres::Jet<double, 11>;

template <typename T>
using Mat3 = Eigen::Matrix<T, 3, 3>;
template <typename T>
using Vec3 = Eigen::Matrix<T, 3, 1>;

template <typename T>
Mat3<T> expT(const Vec3<T>& w) {
  Mat3<T> R;
  ceres::AngleAxisToRotationMatrix(w.data(), R.data());  // column major, as Eigen
  return R;
}

template <typename T>
Vec3<T> logT(const Mat3<T>& R) {
  Vec3<T> w;
  ceres::RotationMatrixToAngleAxis(R.data(), w.data());
  return w;
}

// Rotation R Exp(delta) with delta the tangent directions first..first+2.
Mat3<Jet19> perturbRotation(const Eigen::Quaterniond& q, int first) {
  Vec3<Jet19> delta;
  for (int i = 0; i < 3; ++i) delta[i] = Jet19(0.0, first + i);
  return q.toRotationMatrix().cast<Jet19>() * expT(delta);
}

Vec3<Jet19> perturbVector(const double* x, int first) {
  Vec3<Jet19> out;
  for (int i = 0; i < 3; ++i) out[i] = Jet19(x[i], first + i);
  return out;
}

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
  auto* sizes = mutable_parameter_block_sizes();
  sizes->clear();
  sizes->push_back(7);
  sizes->push_back(interpolation == Interpolation::kKinematic ? 9 : 7);
  sizes->push_back(7);
  sizes->push_back(1);
  sizes->push_back(8);
}

bool TagReprojectionFactor::Evaluate(double const* const* parameters, double* residuals,
                                     double** jacobians) const {
  // Stage 1: the camera pose, p_C = R_C_G p_G + t_C_G, with derivatives in the 19 directions
  // [dtheta_k, dp_k, (v_k, b_g,k) or (dtheta_k+1, dp_k+1), dtheta_e, dp_e, dt_d].
  const double* pose_k = parameters[0];
  const Eigen::Quaterniond q_k = poseRotation(pose_k);
  const Mat3<Jet19> R_k = perturbRotation(q_k, 0);
  const Vec3<Jet19> p_k = perturbVector(pose_k + 4, 3);
  const Jet19 t_d(parameters[3][0], 18);
  const Jet19 dt = Jet19(dt_nominal_) + t_d;

  Mat3<Jet19> R;  // R_G_I(t)
  Vec3<Jet19> p;  // p_G_I(t)
  if (interpolation_ == Interpolation::kKinematic) {
    const Vec3<Jet19> v = perturbVector(parameters[1], 6);
    const Vec3<Jet19> b_g = perturbVector(parameters[1] + 3, 9);
    const Vec3<Jet19> w = gyro_k_.cast<Jet19>() - b_g;
    R = R_k * expT<Jet19>(w * dt);
    p = p_k + v * dt;
  } else {
    const double* pose_k1 = parameters[1];
    const Eigen::Quaterniond q_k1 = poseRotation(pose_k1);
    const Mat3<Jet19> R_k1 = perturbRotation(q_k1, 6);
    const Vec3<Jet19> p_k1 = perturbVector(pose_k1 + 4, 9);
    const Jet19 s = dt / interval_;
    const Mat3<Jet19> R_rel = R_k.transpose() * R_k1;
    R = R_k * expT<Jet19>(logT(R_rel) * s);
    p = p_k + (p_k1 - p_k) * s;
  }
  const double* extrinsic = parameters[2];
  const Eigen::Quaterniond q_CI = poseRotation(extrinsic);
  const Mat3<Jet19> R_CI = perturbRotation(q_CI, 12);
  const Vec3<Jet19> p_CI = perturbVector(extrinsic + 4, 15);
  const Mat3<Jet19> R_CG = R_CI * R.transpose();
  const Vec3<Jet19> t_CG = p_CI - R_CG * p;

  // Stage 2: each corner.
  const double* intrinsics = parameters[4];
  Eigen::Matrix<Jet11, 4, 1> k, d;
  for (int i = 0; i < 4; ++i) {
    k[i] = Jet11(intrinsics[i], 3 + i);
    d[i] = Jet11(intrinsics[4 + i], 7 + i);
  }
  const double inv_sigma = 1.0 / sigma_;
  for (std::size_t c = 0; c < corners_.size(); ++c) {
    const Vec3<Jet19> pc = R_CG * corners_[c].p_G.cast<Jet19>() + t_CG;
    if (!(pc[2].a > 1e-6)) return false;  // behind the camera: Ceres rejects the step
    Vec3<Jet11> pc11;
    for (int i = 0; i < 3; ++i) pc11[i] = Jet11(pc[i].a, i);
    const Eigen::Matrix<Jet11, 2, 1> uv = projectPoint<Jet11>(model_, k, d, pc11);
    const int row = 2 * static_cast<int>(c);
    for (int i = 0; i < 2; ++i) residuals[row + i] = (uv[i].a - corners_[c].uv[i]) * inv_sigma;
    if (jacobians == nullptr) continue;

    Eigen::Matrix<double, 2, 3> J_pc;
    Eigen::Matrix<double, 3, kStageDim> D;
    for (int i = 0; i < 2; ++i) J_pc.row(i) = uv[i].v.head<3>().transpose() * inv_sigma;
    for (int i = 0; i < 3; ++i) D.row(i) = pc[i].v.transpose();
    const Eigen::Matrix<double, 2, kStageDim> J = J_pc * D;
    for (int i = 0; i < 2; ++i) {
      const int r = row + i;
      if (jacobians[0] != nullptr) {
        double* out = jacobians[0] + 7 * r;
        for (int j = 0; j < 6; ++j) out[j] = J(i, j);
        out[6] = 0.0;
      }
      if (jacobians[1] != nullptr) {
        if (interpolation_ == Interpolation::kKinematic) {
          double* out = jacobians[1] + 9 * r;
          for (int j = 0; j < 6; ++j) out[j] = J(i, 6 + j);
          for (int j = 6; j < 9; ++j) out[j] = 0.0;
        } else {
          double* out = jacobians[1] + 7 * r;
          for (int j = 0; j < 6; ++j) out[j] = J(i, 6 + j);
          out[6] = 0.0;
        }
      }
      if (jacobians[2] != nullptr) {
        double* out = jacobians[2] + 7 * r;
        for (int j = 0; j < 6; ++j) out[j] = J(i, 12 + j);
        out[6] = 0.0;
      }
      if (jacobians[3] != nullptr) jacobians[3][r] = J(i, 18);
      if (jacobians[4] != nullptr) {
        double* out = jacobians[4] + 8 * r;
        for (int j = 0; j < 8; ++j) out[j] = uv[i].v[3 + j] * inv_sigma;
      }
    }
  }
  return true;
}

}  // namespace mvis
