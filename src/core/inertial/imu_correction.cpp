#include "mvis/inertial/imu_correction.h"

#include <Eigen/LU>

namespace mvis {

ImuCorrection::ImuCorrection(const ImuIntrinsics& in) {
  to_accel = in.R_IMUtoACC.transpose() * in.Ta.inverse();
  to_gyro = in.R_IMUtoGYRO.transpose() * in.Tw.inverse();
  gravity = to_gyro * in.Tg;
  identity = to_accel.isIdentity(0.0) && to_gyro.isIdentity(0.0) && gravity.isZero(0.0);
}

ImuMeasurement ImuCorrection::apply(const ImuMeasurement& m, bool gyro_only) const {
  if (identity) return m;
  ImuMeasurement out = m;
  if (gyro_only) {
    out.gyro = to_gyro * m.gyro;
    return out;
  }
  out.accel = to_accel * m.accel;
  out.gyro = to_gyro * m.gyro - gravity * out.accel;
  return out;
}

void ImuCorrection::biases(const Eigen::Vector3d& bias_gyro, const Eigen::Vector3d& bias_accel,
                           Eigen::Vector3d* corrected_gyro,
                           Eigen::Vector3d* corrected_accel) const {
  *corrected_accel = to_accel * bias_accel;
  *corrected_gyro = to_gyro * bias_gyro - gravity * *corrected_accel;
}

}  // namespace mvis
