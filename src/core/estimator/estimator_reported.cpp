// What the estimator reports as its calibration (Estimator::calibration): the blocks' values
// and standard deviations, online scaled per quantity by how much it moves on the data
// (TrustedCalibration::inflation, trusted_calibration.h).
#include <cmath>

#include "estimator_impl.h"

namespace mvis {

Rig Estimator::Impl::calibrationEstimate() const {
  Rig out = rig;
  calibration.write(&out);
  intrinsics.write(&out);
  return out;
}

Rig Estimator::Impl::reportedCalibration() {
  Rig out = calibrationEstimate();
  if (batch_solved) return out;
  const ceres::Problem* problem = window.problem();
  // 1 for a block not estimated now: its standard deviations are its prior's or held ones.
  const auto factor = [&](const double* x, int part) {
    const bool estimated = x != nullptr && problem->HasParameterBlock(const_cast<double*>(x)) &&
                           !problem->IsParameterBlockConstant(const_cast<double*>(x));
    return estimated ? std::sqrt(trusted.inflation(x, part)) : 1.0;
  };
  for (std::size_t c = 0; c < calibration.cameras(); ++c) {
    auto& sd = out.cameras[c].std;
    if (!sd) continue;
    const estimator_internal::CameraBlocks& cb = calibration.camera(c);
    sd->rotation *= factor(cb.extrinsic, 0);
    sd->translation *= factor(cb.extrinsic, 1);
    sd->timeshift_cam_imu *= factor(cb.time_offset, 0);
    sd->intrinsics *= factor(cb.intrinsics, 0);
    sd->distortion_coeffs *= factor(cb.intrinsics, 1);
  }
  for (std::size_t i = 0; i < calibration.auxiliaries(); ++i) {
    const estimator_internal::AuxCalibration& a = calibration.aux(i);
    auto& sd = out.inertial[a.sensor].std;
    if (!sd) continue;
    sd->rotation *= factor(a.gyro ? a.rotation : a.extrinsic, 0);
    if (!a.gyro) sd->translation *= factor(a.extrinsic, 1);
    sd->time_offset *= factor(a.time_offset, 0);
  }
  for (std::size_t i = 0; i < out.inertial.size(); ++i) {
    auto& sd = out.inertial[i].std;
    const double* x = intrinsics.values(i);
    if (!sd || x == nullptr) continue;
    const double f = factor(x, 0);
    sd->Tw *= f;
    sd->Ta *= f;
    sd->Tg *= f;
    sd->R_IMUtoACC *= f;
    sd->R_IMUtoGYRO *= f;
  }
  return out;
}

}  // namespace mvis
