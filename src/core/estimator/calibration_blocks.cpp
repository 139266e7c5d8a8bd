#include "calibration_blocks.h"

#include <ceres/normal_prior.h>

#include <algorithm>

#include "mvis/factors/pose_prior_factor.h"
#include "mvis/factors/rotation_prior_factor.h"

namespace mvis {
namespace estimator_internal {
namespace {

CalibrationPrior calibrationPrior(double rotation, double translation, double time_offset,
                                  const Eigen::Vector3d* rotation_std,
                                  const Eigen::Vector3d* translation_std, double time_offset_std) {
  CalibrationPrior p{Eigen::Vector3d::Constant(rotation), Eigen::Vector3d::Constant(translation),
                     time_offset_std > 0 ? time_offset_std : time_offset};
  for (int i = 0; i < 3; ++i) {
    if (rotation_std != nullptr && (*rotation_std)[i] > 0) p.rotation[i] = (*rotation_std)[i];
    if (translation_std != nullptr && (*translation_std)[i] > 0) {
      p.translation[i] = (*translation_std)[i];
    }
  }
  return p;
}

// The configured prior of a block, unless the trusted calibration's joint prior covers it; its
// id (null when covered).
ceres::ResidualBlockId addPrior(ceres::Problem* problem, const TrustedCalibration& trusted,
                                ceres::CostFunction* configured, double* block) {
  if (trusted.covers(block)) {
    delete configured;  // the trusted calibration's joint prior stands instead
    return nullptr;
  }
  return problem->AddResidualBlock(configured, nullptr, block);
}

ceres::CostFunction* timeOffsetPrior(double value, double std) {
  return new ceres::NormalPrior(Eigen::Matrix<double, 1, 1>(1.0 / std),
                                Eigen::Matrix<double, 1, 1>(value));
}

}  // namespace

bool heldByOption(const EstimatorOptions& options, const std::string& sensor,
                  const char* quantity) {
  return std::find(options.hold.begin(), options.hold.end(), sensor + "." + quantity) !=
         options.hold.end();
}

void AuxCalibration::extrinsicParts(Eigen::Matrix3d* R_AI, Eigen::Vector3d* p_AI) const {
  if (gyro) {
    *R_AI = poseRotation(rotation).toRotationMatrix();
    p_AI->setZero();
  } else {
    *R_AI = poseRotation(extrinsic).toRotationMatrix();
    *p_AI = posePosition(extrinsic);
  }
}

CalibrationBlocks::CalibrationBlocks(const Rig& rig, const EstimatorOptions& options)
    : rig_(rig), options_(options) {
  for (const auto& cam : rig.cameras) {
    auto blocks = std::make_unique<CameraBlocks>();
    se3ToPose(cam.T_cam_imu, blocks->extrinsic);
    blocks->time_offset[0] = cam.timeshift_cam_imu;
    for (int i = 0; i < 4; ++i) {
      blocks->intrinsics[i] = cam.intrinsics[i];
      blocks->intrinsics[4 + i] = cam.distortion_coeffs[i];
    }
    cameras_.push_back(std::move(blocks));
  }
  for (std::size_t i = 1; i < rig.inertial.size(); ++i) {
    const InertialSensor& sensor = rig.inertial[i];
    auto a = std::make_unique<AuxCalibration>();
    a->sensor = i;
    a->gyro = sensor.type == InertialType::kGyroscope;
    se3ToPose(sensor.T_i_b, a->extrinsic);
    Eigen::Map<Eigen::Quaterniond>{a->rotation} = sensor.T_i_b.q;
    a->time_offset[0] = sensor.time_offset;
    aux_.push_back(std::move(a));
  }
}

void CalibrationBlocks::addTo(ceres::Problem* problem, const TrustedCalibration& trusted) {
  const EstimatorOptions& o = options_;
  fixed_.clear();
  prior_ids_.clear();
  const auto fix = [&](double* block) {
    problem->SetParameterBlockConstant(block);
    fixed_.insert(block);
  };
  problem->AddParameterBlock(gravity_, kGravitySize, &sphere_manifold_);
  for (std::size_t c = 0; c < cameras_.size(); ++c) {
    CameraBlocks& b = *cameras_[c];
    problem->AddParameterBlock(b.extrinsic, kPoseSize, &pose_manifold_);
    problem->AddParameterBlock(b.time_offset, 1);
    problem->AddParameterBlock(b.intrinsics, kIntrinsicsSize);
    const std::string& name = rig_.cameras[c].name;
    const bool intrinsics = o.estimate_intrinsics && !heldByOption(o, name, "intrinsics");
    if (!o.estimate_extrinsics || heldByOption(o, name, "extrinsic")) {
      fix(b.extrinsic);
    }
    if (!o.estimate_time_offsets || heldByOption(o, name, "time_offset")) {
      fix(b.time_offset);
    }
    if (!intrinsics) fix(b.intrinsics);
    // Priors from the configuration's *_std keys, or the options' defaults (also once the camera
    // moved: the *_std keys were its old mount's).
    const auto& sd = rig_.cameras[c].std;
    b.prior = calibrationPrior(o.extrinsic_rotation_prior_rad, o.extrinsic_translation_prior_m,
                               o.time_offset_prior_s, sd && !b.moved ? &sd->rotation : nullptr,
                               sd && !b.moved ? &sd->translation : nullptr,
                               sd && !b.moved ? sd->timeshift_cam_imu : 0.0);
    prior_ids_[b.extrinsic] = addPrior(
        problem, trusted,
        PosePriorFactor::fromStd(poseToSE3(b.extrinsic), b.prior.rotation, b.prior.translation),
        b.extrinsic);
    prior_ids_[b.time_offset] = addPrior(
        problem, trusted, timeOffsetPrior(b.time_offset[0], b.prior.time_offset), b.time_offset);
    // Intrinsics: the configuration's *_std keys where they are positive, else the defaults.
    for (int i = 0; i < kIntrinsicsSize; ++i) {
      const double fallback = i < 2   ? o.intrinsics_focal_prior_px
                              : i < 4 ? o.intrinsics_centre_prior_px
                                      : o.distortion_prior;
      const double given = !sd ? 0.0 : i < 4 ? sd->intrinsics[i] : sd->distortion_coeffs[i - 4];
      b.intrinsics_prior[i] = given > 0.0 ? given : fallback;
    }
    if (intrinsics) {
      using Vector8d = Eigen::Matrix<double, kIntrinsicsSize, 1>;
      addPrior(
          problem, trusted,
          new ceres::NormalPrior(Eigen::MatrixXd(b.intrinsics_prior.cwiseInverse().asDiagonal()),
                                 Vector8d(Eigen::Map<const Vector8d>(b.intrinsics))),
          b.intrinsics);
    }
  }
  for (auto& ap : aux_) {
    AuxCalibration& a = *ap;
    const InertialSensor& config = rig_.inertial[a.sensor];
    if (a.gyro) {
      problem->AddParameterBlock(a.rotation, kRotationSize, &rotation_manifold_);
    } else {
      problem->AddParameterBlock(a.extrinsic, kPoseSize, &pose_manifold_);
    }
    problem->AddParameterBlock(a.time_offset, 1);
    if (!o.estimate_aux_extrinsics || heldByOption(o, config.name, "extrinsic")) {
      fix(a.extrinsicBlock());
    }
    if (!o.estimate_aux_time_offsets || heldByOption(o, config.name, "time_offset")) {
      fix(a.time_offset);
    }
    const auto& sd = a.moved ? std::optional<InertialCalibrationStd>() : config.std;
    a.prior = calibrationPrior(o.aux_rotation_prior_rad, o.aux_translation_prior_m,
                               o.aux_time_offset_prior_s, sd ? &sd->rotation : nullptr,
                               sd ? &sd->translation : nullptr, sd ? sd->time_offset : 0.0);
    prior_ids_[a.extrinsicBlock()] =
        addPrior(problem, trusted, auxExtrinsicPrior(a), a.extrinsicBlock());
    prior_ids_[a.time_offset] = addPrior(
        problem, trusted, timeOffsetPrior(a.time_offset[0], a.prior.time_offset), a.time_offset);
  }
}

void CalibrationBlocks::reopenCamera(std::size_t c, ceres::Problem* problem) {
  CameraBlocks& b = *cameras_[c];
  b.moved = true;
  b.prior = calibrationPrior(options_.extrinsic_rotation_prior_rad,
                             options_.extrinsic_translation_prior_m, options_.time_offset_prior_s,
                             nullptr, nullptr, 0.0);
  // Its standard deviations are the prior's until the next covariance.
  if (camera_std_) {
    (*camera_std_)[c].rotation.setZero();
    (*camera_std_)[c].translation.setZero();
    (*camera_std_)[c].timeshift_cam_imu = 0.0;
  }
  replacePriors(
      problem, b.extrinsic,
      PosePriorFactor::fromStd(poseToSE3(b.extrinsic), b.prior.rotation, b.prior.translation),
      b.time_offset, timeOffsetPrior(b.time_offset[0], b.prior.time_offset));
}

void CalibrationBlocks::reopenAux(std::size_t i, ceres::Problem* problem) {
  AuxCalibration& a = *aux_[i];
  a.moved = true;
  a.prior = calibrationPrior(options_.aux_rotation_prior_rad, options_.aux_translation_prior_m,
                             options_.aux_time_offset_prior_s, nullptr, nullptr, 0.0);
  if (a.std) {
    a.std->rotation.setZero();
    a.std->translation.setZero();
    a.std->time_offset = 0.0;
  }
  replacePriors(problem, a.extrinsicBlock(), auxExtrinsicPrior(a), a.time_offset,
                timeOffsetPrior(a.time_offset[0], a.prior.time_offset));
}

ceres::CostFunction* CalibrationBlocks::auxExtrinsicPrior(const AuxCalibration& a) {
  if (a.gyro) return new RotationPriorFactor(poseRotation(a.rotation), a.prior.rotation);
  return PosePriorFactor::fromStd(poseToSE3(a.extrinsic), a.prior.rotation, a.prior.translation);
}

void CalibrationBlocks::replacePriors(ceres::Problem* problem, double* extrinsic,
                                      ceres::CostFunction* extrinsic_prior, double* time_offset,
                                      ceres::CostFunction* time_offset_prior) {
  if (problem == nullptr) {
    delete extrinsic_prior;
    delete time_offset_prior;
    return;
  }
  for (double* block : {extrinsic, time_offset}) {
    const auto id = prior_ids_.find(block);
    if (id != prior_ids_.end() && id->second != nullptr) problem->RemoveResidualBlock(id->second);
  }
  prior_ids_[extrinsic] = problem->AddResidualBlock(extrinsic_prior, nullptr, extrinsic);
  prior_ids_[time_offset] = problem->AddResidualBlock(time_offset_prior, nullptr, time_offset);
}

Camera CalibrationBlocks::currentCamera(std::size_t c) const {
  Camera current = rig_.cameras[c];
  const CameraBlocks& cb = *cameras_[c];
  current.intrinsics = Eigen::Vector4d(cb.intrinsics);
  current.distortion_coeffs = Eigen::Vector4d(cb.intrinsics + 4);
  return current;
}

std::vector<double*> CalibrationBlocks::batchHeldBlocks(bool trusted) {
  std::vector<double*> out;
  if (trusted) {
    for (auto& cb : cameras_) {
      out.push_back(cb->extrinsic);
      out.push_back(cb->time_offset);
    }
  }
  for (auto& a : aux_) {
    out.push_back(a->extrinsicBlock());
    out.push_back(a->time_offset);
  }
  for (auto& cb : cameras_) out.push_back(cb->intrinsics);
  return out;
}

void CalibrationBlocks::covarianceBlocks(
    const ceres::Problem& problem,
    std::vector<std::pair<const double*, const double*>>* blocks) const {
  for (const auto& cb : cameras_) {
    for (const double* b : {cb->extrinsic, cb->time_offset, cb->intrinsics}) {
      if (!problem.IsParameterBlockConstant(b)) blocks->emplace_back(b, b);
    }
  }
  for (const auto& a : aux_) {
    for (const double* b : {static_cast<const double*>(a->extrinsicBlock()),
                            static_cast<const double*>(a->time_offset)}) {
      if (!problem.IsParameterBlockConstant(b)) blocks->emplace_back(b, b);
    }
  }
}

std::vector<TrustedCalibration::Block> CalibrationBlocks::trustedBlocks(
    const ceres::Problem* problem) {
  std::vector<TrustedCalibration::Block> out;
  const auto add = [&](std::string name, double* x, int ambient, const ceres::Manifold* m,
                       bool intrinsic = false) {
    out.push_back(TrustedCalibration::make(std::move(name), x, ambient, m, problem, intrinsic));
  };
  for (std::size_t c = 0; c < cameras_.size(); ++c) {
    CameraBlocks& cb = *cameras_[c];
    const std::string& name = rig_.cameras[c].name;
    add(name + " extrinsic", cb.extrinsic, kPoseSize, &pose_manifold_);
    add(name + " time offset", cb.time_offset, 1, nullptr);
    add(name + " intrinsics", cb.intrinsics, kIntrinsicsSize, nullptr, true);
  }
  for (auto& a : aux_) {
    const std::string& name = rig_.inertial[a->sensor].name;
    if (a->gyro) {
      add(name + " rotation", a->rotation, kRotationSize, &rotation_manifold_);
    } else {
      add(name + " extrinsic", a->extrinsic, kPoseSize, &pose_manifold_);
    }
    add(name + " time offset", a->time_offset, 1, nullptr);
  }
  return out;
}

void CalibrationBlocks::updateStd(const ceres::Problem& problem, const TangentCovariance& tangent) {
  // A block not estimated now keeps its standard deviations: held whole by the motion, the last
  // computed ones, or before any its prior's (latestStd: the uncertainty it is held at, as the
  // held directions of a partly held block keep theirs); held by the options, 0 (empty here).
  const auto kept = [&](const double* block) {
    return heldWholeByMotion(problem, block) ? latestStd(block) : Eigen::VectorXd();
  };
  std::vector<CameraCalibrationStd> out =
      camera_std_ ? *camera_std_ : std::vector<CameraCalibrationStd>(cameras_.size());
  for (std::size_t c = 0; c < cameras_.size(); ++c) {
    const CameraBlocks& cb = *cameras_[c];
    Eigen::VectorXd sd =
        problem.IsParameterBlockConstant(cb.extrinsic)
            ? kept(cb.extrinsic)
            : Eigen::VectorXd(tangent(cb.extrinsic).diagonal().cwiseMax(0.0).cwiseSqrt());
    if (sd.size() > 0) {
      out[c].rotation = sd.head<3>();
      out[c].translation = sd.tail<3>();
    }
    if (!problem.IsParameterBlockConstant(cb.time_offset)) {
      out[c].timeshift_cam_imu = std::sqrt(std::max(tangent(cb.time_offset)(0, 0), 0.0));
    } else if (const Eigen::VectorXd k = kept(cb.time_offset); k.size() > 0) {
      out[c].timeshift_cam_imu = k[0];
    }
    // In its own tangent: a part held keeps its variance there (tangentCovariance).
    sd = problem.IsParameterBlockConstant(cb.intrinsics)
             ? kept(cb.intrinsics)
             : Eigen::VectorXd(tangent(cb.intrinsics).diagonal().cwiseMax(0.0).cwiseSqrt());
    if (sd.size() > 0) {
      out[c].intrinsics = sd.head<4>();
      out[c].distortion_coeffs = sd.tail<4>();
    }
  }
  camera_std_ = out;
  for (auto& a : aux_) {
    InertialCalibrationStd sd = a->std ? *a->std : InertialCalibrationStd{};
    const double* e = a->extrinsicBlock();
    const Eigen::VectorXd v =
        problem.IsParameterBlockConstant(e)
            ? kept(e)
            : Eigen::VectorXd(tangent(e).diagonal().cwiseMax(0.0).cwiseSqrt());
    if (v.size() > 0) {
      sd.rotation = v.head<3>();
      if (!a->gyro) sd.translation = v.tail<3>();
    }
    if (!problem.IsParameterBlockConstant(a->time_offset)) {
      sd.time_offset = std::sqrt(std::max(tangent(a->time_offset)(0, 0), 0.0));
    } else if (const Eigen::VectorXd k = kept(a->time_offset); k.size() > 0) {
      sd.time_offset = k[0];
    }
    a->std = sd;
  }
}

bool CalibrationBlocks::heldWholeByMotion(const ceres::Problem& problem,
                                          const double* block) const {
  return problem.HasParameterBlock(block) && problem.IsParameterBlockConstant(block) &&
         fixed_.count(block) == 0;
}

Eigen::VectorXd CalibrationBlocks::latestStd(const double* block) const {
  for (std::size_t c = 0; c < cameras_.size(); ++c) {
    const CameraBlocks& cb = *cameras_[c];
    const bool have = camera_std_.has_value();
    if (block == cb.extrinsic) {
      Vector6d sd;
      sd << cb.prior.rotation, cb.prior.translation;
      if (have && (*camera_std_)[c].rotation.allFinite() && (*camera_std_)[c].rotation.norm() > 0) {
        sd << (*camera_std_)[c].rotation, (*camera_std_)[c].translation;
      }
      return sd;
    }
    if (block == cb.time_offset) {
      const double v = have ? (*camera_std_)[c].timeshift_cam_imu : 0.0;
      return Eigen::VectorXd::Constant(1, v > 0 ? v : cb.prior.time_offset);
    }
    if (block == cb.intrinsics) {
      Eigen::VectorXd sd = cb.intrinsics_prior;
      if (have && (*camera_std_)[c].intrinsics.norm() > 0) {
        sd << (*camera_std_)[c].intrinsics, (*camera_std_)[c].distortion_coeffs;
      }
      return sd;
    }
  }
  for (const auto& a : aux_) {
    const bool have = a->std.has_value();
    if (block == a->time_offset) {
      const double v = have ? a->std->time_offset : 0.0;
      return Eigen::VectorXd::Constant(1, v > 0 ? v : a->prior.time_offset);
    }
    if (block == a->rotation && a->gyro) {
      return have && a->std->rotation.norm() > 0 ? Eigen::VectorXd(a->std->rotation)
                                                 : Eigen::VectorXd(a->prior.rotation);
    }
    if (block == a->extrinsic && !a->gyro) {
      Vector6d sd;
      sd << a->prior.rotation, a->prior.translation;
      if (have && a->std->rotation.norm() > 0) sd << a->std->rotation, a->std->translation;
      return sd;
    }
  }
  return Eigen::VectorXd();
}

void CalibrationBlocks::write(Rig* out) const {
  for (std::size_t c = 0; c < cameras_.size(); ++c) {
    const CameraBlocks& cb = *cameras_[c];
    Camera& cam = out->cameras[c];
    cam.T_cam_imu = poseToSE3(cb.extrinsic);
    cam.timeshift_cam_imu = cb.time_offset[0];
    cam.intrinsics = Eigen::Vector4d(cb.intrinsics);
    cam.distortion_coeffs = Eigen::Vector4d(cb.intrinsics + 4);
    if (camera_std_) cam.std = (*camera_std_)[c];
  }
  for (const auto& a : aux_) {
    InertialSensor& s = out->inertial[a->sensor];
    if (a->gyro) {
      s.T_i_b.q = Eigen::Quaterniond(poseRotation(a->rotation)).normalized();
    } else {
      s.T_i_b = poseToSE3(a->extrinsic);
    }
    s.time_offset = a->time_offset[0];
    if (a->std) {
      // Keep what the configuration says of the intrinsics' uncertainty.
      InertialCalibrationStd sd = s.std ? *s.std : InertialCalibrationStd{};
      sd.rotation = a->std->rotation;
      sd.translation = a->std->translation;
      sd.time_offset = a->std->time_offset;
      s.std = sd;
    }
  }
}

void CalibrationBlocks::setValues(const Rig& start) {
  for (std::size_t c = 0; c < cameras_.size(); ++c) {
    CameraBlocks& cb = *cameras_[c];
    const Camera& cam = start.cameras[c];
    se3ToPose(cam.T_cam_imu, cb.extrinsic);
    cb.time_offset[0] = cam.timeshift_cam_imu;
    for (int i = 0; i < 4; ++i) {
      cb.intrinsics[i] = cam.intrinsics[i];
      cb.intrinsics[4 + i] = cam.distortion_coeffs[i];
    }
  }
  for (auto& a : aux_) {
    const InertialSensor& s = start.inertial[a->sensor];
    se3ToPose(s.T_i_b, a->extrinsic);
    Eigen::Map<Eigen::Quaterniond>{a->rotation} = s.T_i_b.q;
    a->time_offset[0] = s.time_offset;
  }
}

}  // namespace estimator_internal
}  // namespace mvis
