#include "mvis/factors/imu_factor.h"

#include "mvis/common/lie.h"
#include "mvis/estimator/state_blocks.h"
#include "whitening.h"

namespace mvis {

ImuFactor::ImuFactor(std::shared_ptr<const ImuPreintegration> preintegration)
    : preintegration_(std::move(preintegration)) {}

bool ImuFactor::Evaluate(double const* const* parameters, double* residuals,
                         double** jacobians) const {
  using Matrix3 = Eigen::Matrix3d;
  using Vector3 = Eigen::Vector3d;
  const ImuPreintegration& pre = *preintegration_;
  constexpr int O_R = ImuPreintegration::kRotation, O_P = ImuPreintegration::kPosition,
                O_V = ImuPreintegration::kVelocity, O_BG = ImuPreintegration::kBiasGyro,
                O_BA = ImuPreintegration::kBiasAccel;

  const Eigen::Quaterniond q_i = poseRotation(parameters[0]);
  const Vector3 p_i(parameters[0] + 4);
  const Vector3 v_i(parameters[1]), bg_i(parameters[1] + 3), ba_i(parameters[1] + 6);
  const Eigen::Quaterniond q_j = poseRotation(parameters[2]);
  const Vector3 p_j(parameters[2] + 4);
  const Vector3 v_j(parameters[3]), bg_j(parameters[3] + 3), ba_j(parameters[3] + 6);
  const Vector3 g(parameters[4]);
  const double T = pre.duration();

  const Matrix3 R_i = q_i.toRotationMatrix();
  const Matrix3 R_j = q_j.toRotationMatrix();
  const Matrix3 Rt_i = R_i.transpose();
  const Eigen::Quaterniond dR = pre.correctedDeltaR(bg_i);
  const Matrix3 E = dR.toRotationMatrix().transpose() * Rt_i * R_j;
  const Vector3 e = lie::logSO3(E);
  const Vector3 dp_world = p_j - p_i - v_i * T - 0.5 * g * T * T;
  const Vector3 dv_world = v_j - v_i - g * T;
  const Vector3 a_p = Rt_i * dp_world;
  const Vector3 a_v = Rt_i * dv_world;

  Eigen::Matrix<double, 15, 1> r;
  r.segment<3>(O_R) = e;
  r.segment<3>(O_P) = a_p - pre.correctedDeltaP(bg_i, ba_i);
  r.segment<3>(O_V) = a_v - pre.correctedDeltaV(bg_i, ba_i);
  r.segment<3>(O_BG) = bg_j - bg_i;
  r.segment<3>(O_BA) = ba_j - ba_i;

  // Square-root information: L^T with L L^T = P^-1.
  const Eigen::Matrix<double, 15, 15> sqrt_info = sqrtInformation<15>(pre.covariance());
  Eigen::Map<Eigen::Matrix<double, 15, 1>>{residuals} = sqrt_info * r;
  if (jacobians == nullptr) return true;

  const auto& J = pre.jacobian();
  const Matrix3 Jr_inv_e = lie::rightJacobianInvSO3(e);
  const Vector3 phi = J.block<3, 3>(O_R, O_BG) * (bg_i - pre.biasGyro());

  if (jacobians[0] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 15, 7, Eigen::RowMajor>> out(jacobians[0]);
    Eigen::Matrix<double, 15, 6> D = Eigen::Matrix<double, 15, 6>::Zero();
    D.block<3, 3>(O_R, 0) = -Jr_inv_e * R_j.transpose() * R_i;
    D.block<3, 3>(O_P, 0) = lie::hat(a_p);
    D.block<3, 3>(O_P, 3) = -Rt_i;
    D.block<3, 3>(O_V, 0) = lie::hat(a_v);
    out.setZero();
    out.leftCols<6>() = sqrt_info * D;
  }
  if (jacobians[1] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 15, 9, Eigen::RowMajor>> out(jacobians[1]);
    Eigen::Matrix<double, 15, 9> D = Eigen::Matrix<double, 15, 9>::Zero();
    D.block<3, 3>(O_R, 3) =
        -Jr_inv_e * E.transpose() * lie::rightJacobianSO3(phi) * J.block<3, 3>(O_R, O_BG);
    D.block<3, 3>(O_P, 0) = -Rt_i * T;
    D.block<3, 3>(O_P, 3) = -J.block<3, 3>(O_P, O_BG);
    D.block<3, 3>(O_P, 6) = -J.block<3, 3>(O_P, O_BA);
    D.block<3, 3>(O_V, 0) = -Rt_i;
    D.block<3, 3>(O_V, 3) = -J.block<3, 3>(O_V, O_BG);
    D.block<3, 3>(O_V, 6) = -J.block<3, 3>(O_V, O_BA);
    D.block<3, 3>(O_BG, 3) = -Matrix3::Identity();
    D.block<3, 3>(O_BA, 6) = -Matrix3::Identity();
    out = sqrt_info * D;
  }
  if (jacobians[2] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 15, 7, Eigen::RowMajor>> out(jacobians[2]);
    Eigen::Matrix<double, 15, 6> D = Eigen::Matrix<double, 15, 6>::Zero();
    D.block<3, 3>(O_R, 0) = Jr_inv_e;
    D.block<3, 3>(O_P, 3) = Rt_i;
    out.setZero();
    out.leftCols<6>() = sqrt_info * D;
  }
  if (jacobians[3] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 15, 9, Eigen::RowMajor>> out(jacobians[3]);
    Eigen::Matrix<double, 15, 9> D = Eigen::Matrix<double, 15, 9>::Zero();
    D.block<3, 3>(O_V, 0) = Rt_i;
    D.block<3, 3>(O_BG, 3) = Matrix3::Identity();
    D.block<3, 3>(O_BA, 6) = Matrix3::Identity();
    out = sqrt_info * D;
  }
  if (jacobians[4] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 15, 3, Eigen::RowMajor>> out(jacobians[4]);
    Eigen::Matrix<double, 15, 3> D = Eigen::Matrix<double, 15, 3>::Zero();
    D.block<3, 3>(O_P, 0) = -0.5 * Rt_i * T * T;
    D.block<3, 3>(O_V, 0) = -Rt_i * T;
    out = sqrt_info * D;
  }
  return true;
}

}  // namespace mvis
