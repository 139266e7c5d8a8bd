#include "aux_end.h"

#include "mvis/common/lie.h"
#include "mvis/factors/state_blocks.h"

namespace mvis {
namespace aux_end {

End evaluate(const Inputs& in, bool jacobian) {
  using Matrix3 = Eigen::Matrix3d;
  using Vector3 = Eigen::Vector3d;
  const BaseMotion& m = *in.motion;
  const double delta = in.delta;
  const Matrix3 R_k = poseRotation(in.pose).toRotationMatrix();
  const Vector3 bg(in.speed_bias + 3);
  const Vector3 phi = (m.gyro - bg) * delta + 0.5 * delta * delta * m.angular_acceleration;
  const Matrix3 E_phi = lie::expSO3(phi);
  const Matrix3 Rs = R_k * E_phi;
  End e;
  e.R = Rs * in.R_AI.transpose();
  Vector3 u = Vector3::Zero(), a = Vector3::Zero(), p_IA = Vector3::Zero();
  Vector3 w = Vector3::Zero(), y = Vector3::Zero();
  if (in.position) {
    const Vector3 v_k(in.speed_bias);
    u = m.accel - Vector3(in.speed_bias + 6);
    a = R_k * u + in.g;
    e.p = posePosition(in.pose) + v_k * delta + 0.5 * delta * delta * a - e.R * in.p_AI;
    if (in.velocity_state) {
      e.v = Vector3(in.aux);
    } else {
      p_IA = -(in.R_AI.transpose() * in.p_AI);
      w = in.R_AI.transpose() * (in.aux_gyro - Vector3(in.aux));
      y = w.cross(p_IA);
      e.v = v_k + a * delta + Rs * y;
    }
  }
  if (!jacobian) return e;

  auto& J = e.J;
  J.setZero();
  const Matrix3 I = Matrix3::Identity();
  const Matrix3 Jr = lie::rightJacobianSO3(phi);
  const Vector3 omega = m.gyro - bg + delta * m.angular_acceleration;
  J.block<3, 3>(0, kR) = in.R_AI * E_phi.transpose();
  J.block<3, 3>(0, kBg) = -delta * in.R_AI * Jr;
  J.block<3, 1>(0, kTd) = in.R_AI * Jr * omega;
  J.block<3, 3>(0, kE) = -in.R_AI;
  if (!in.position) return e;

  const Vector3 v_k(in.speed_bias);
  const double half_d2 = 0.5 * delta * delta;
  J.middleRows<3>(3) = e.R * lie::hat(in.p_AI) * J.topRows<3>();
  J.block<3, 3>(3, kR) -= half_d2 * R_k * lie::hat(u);
  J.block<3, 3>(3, kP) += I;
  J.block<3, 3>(3, kV) += delta * I;
  J.block<3, 3>(3, kBa) -= half_d2 * R_k;
  J.block<3, 3>(3, kG) += half_d2 * I;
  J.block<3, 1>(3, kTd) += v_k + delta * a;
  J.block<3, 3>(3, kT) = -e.R;
  if (in.velocity_state) {
    J.block<3, 3>(6, kAux) = I;
    return e;
  }
  const Matrix3 Ry = Rs * lie::hat(y);
  J.block<3, 3>(6, kV) = I;
  J.block<3, 3>(6, kR) = -delta * R_k * lie::hat(u) - Ry * E_phi.transpose();
  J.block<3, 3>(6, kBg) = delta * Ry * Jr;
  J.block<3, 3>(6, kBa) = -delta * R_k;
  J.block<3, 3>(6, kG) = delta * I;
  J.block<3, 1>(6, kTd) = a - Ry * Jr * omega;
  J.block<3, 3>(6, kAux) = Rs * lie::hat(p_IA) * in.R_AI.transpose();
  J.block<3, 3>(6, kE) = Ry;
  J.block<3, 3>(6, kT) = -Rs * lie::hat(w) * in.R_AI.transpose();
  return e;
}

}  // namespace aux_end
}  // namespace mvis
