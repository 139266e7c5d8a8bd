#include "mvis/factors/gyro_factor.h"

#include <algorithm>
#include <array>

#include "aux_end.h"
#include "mvis/common/lie.h"
#include "mvis/factors/state_blocks.h"
#include "whitening.h"

namespace mvis {
namespace {

// Columns of the unwhitened Jacobian D (6 x kColumns, in the blocks' tangents):
// [dtheta_i, dp_i] 0-5, speed_bias_i 6-14, [dtheta_j, dp_j] 15-20, speed_bias_j 21-29, bias_i
// 30-32, bias_j 33-35, extrinsic dtheta 36-38, t_d 39.
constexpr int kBiasColumn = 30, kExtrinsicColumn = 36, kTimeOffsetColumn = 39, kColumns = 40;
const aux_end::BlockColumns kLayout[] = {{0, 6, 7},  {6, 9, 9},  {15, 6, 7}, {21, 9, 9},
                                         {30, 3, 3}, {33, 3, 3}, {36, 3, 4}, {39, 1, 1}};
constexpr int kBlocks = 8;

}  // namespace

GyroFactor::GyroFactor(std::shared_ptr<const ImuPreintegration> pre, double time_offset0_i,
                       double time_offset0_j, const BaseMotion& base_i, const BaseMotion& base_j)
    : pre_(std::move(pre)),
      time_offset0_i_(time_offset0_i),
      time_offset0_j_(time_offset0_j),
      base_i_(base_i),
      base_j_(base_j) {
  set_num_residuals(6);
  auto* sizes = mutable_parameter_block_sizes();
  for (const auto& l : kLayout) sizes->push_back(l.ambient);
  using P = ImuPreintegration;
  Eigen::Matrix<double, 6, 6> cov;
  const auto& C = pre_->covariance();
  cov.topLeftCorner<3, 3>() = C.block<3, 3>(P::kRotation, P::kRotation);
  cov.topRightCorner<3, 3>() = C.block<3, 3>(P::kRotation, P::kBiasGyro);
  cov.bottomLeftCorner<3, 3>() = C.block<3, 3>(P::kBiasGyro, P::kRotation);
  cov.bottomRightCorner<3, 3>() = C.block<3, 3>(P::kBiasGyro, P::kBiasGyro);
  sqrt_information_ = sqrtInformation<6>(cov);
}

GyroFactor::GyroFactor(std::shared_ptr<const ImuPreintegration> pre, double time_offset0_i,
                       double time_offset0_j, const BaseMotion& base_i, const BaseMotion& base_j,
                       const ImuIntrinsicsFrame& frame, IntrinsicsLinearization mode,
                       const double* intrinsics0)
    : GyroFactor(std::move(pre), time_offset0_i, time_offset0_j, base_i, base_j) {
  intrinsics_ = true;
  frame_ = frame;
  frame_.gyro_only = true;
  mode_ = mode;
  mutable_parameter_block_sizes()->push_back(kImuIntrinsicsSize);
  if (mode_ == IntrinsicsLinearization::kFixed) {
    fixed_ =
        reintegrate(pre_->samples(), deltaVariables(pre_->biasGyro().data(), nullptr, intrinsics0),
                    frame_, true);
  }
}

bool GyroFactor::Evaluate(double const* const* parameters, double* residuals,
                          double** jacobians) const {
  using Matrix3 = Eigen::Matrix3d;
  using Vector3 = Eigen::Vector3d;
  using L = ImuIntrinsicsLayout;
  const bool jacobian = jacobians != nullptr;
  ImuDeltas local;
  const ImuDeltas& d =
      factorDeltas(*pre_, intrinsics_, mode_, fixed_,
                   deltaVariables(parameters[4], nullptr, intrinsics_ ? parameters[8] : nullptr),
                   frame_, jacobian, &local);
  // The deltas' variables: the bias of state i and, estimated, Dw and Tg; the rest of the
  // intrinsics block does not enter (held where the deltas were integrated).
  ImuDeltas::Vector30d x = d.x0;
  x.head<3>() = Vector3(parameters[4]);
  for (int k = 0; intrinsics_ && k < 6; ++k) x[6 + L::kDw + k] = parameters[8][L::kDw + k];
  for (int k = 0; intrinsics_ && k < 9; ++k) x[6 + L::kTg + k] = parameters[8][L::kTg + k];

  aux_end::Inputs in;
  in.R_AI =
      Eigen::Quaterniond(Eigen::Map<const Eigen::Quaterniond>(parameters[6])).toRotationMatrix();
  in.position = false;
  // End k (0: i, 1: j): its base blocks, base motion and offset.
  const auto end = [&](int k, const BaseMotion& motion, double time_offset0) {
    in.motion = &motion;
    in.pose = parameters[2 * k];
    in.speed_bias = parameters[2 * k + 1];
    in.delta = parameters[7][0] - time_offset0;
    return aux_end::evaluate(in, jacobian);
  };
  const aux_end::End end_i = end(0, base_i_, time_offset0_i_);
  const aux_end::End end_j = end(1, base_j_, time_offset0_j_);

  const Vector3 phi = d.J.topRows<3>() * (x - d.x0);
  const Matrix3 dR = d.dR * lie::expSO3(phi);
  const Matrix3 E = dR.transpose() * end_i.R.transpose() * end_j.R;
  const Vector3 e = lie::logSO3(E);
  Eigen::Map<Eigen::Matrix<double, 6, 1>> r(residuals);
  r.head<3>() = e;
  r.tail<3>() = Vector3(parameters[5]) - Vector3(parameters[4]);
  // With the intrinsics estimated, the readings' noise seen through the current correction
  // (imu_factor.h): the rotation rows times Dw^-1 before the whitening, d(Dw^-1)/dDw r into Dw's
  // columns. Dw only: the kalibr model's rotation, which the gyroscope does not estimate, turns
  // its isotropic noise without changing it.
  Matrix3 G_inv = Matrix3::Identity();
  Eigen::Matrix<double, 9, kImuIntrinsicsSize> K;
  if (intrinsics_) {
    ImuIntrinsicsFrame scale_only = frame_;
    scale_only.R0.setIdentity();
    std::array<double, kImuIntrinsicsSize> block;
    std::copy(parameters[8], parameters[8] + kImuIntrinsicsSize, block.begin());
    std::fill(block.begin() + L::kAccRotation, block.end(), 0.0);
    Eigen::Matrix<double, 9, 1> rows = Eigen::Matrix<double, 9, 1>::Zero(), scaled;
    rows.head<3>() = r.head<3>();
    Matrix3 M_inv;
    noiseMapInverses(block.data(), scale_only, rows, &scaled, jacobian ? &K : nullptr, &G_inv,
                     &M_inv);
    r.head<3>() = scaled.head<3>();
  }
  if (!jacobian) {
    whiten<6>(sqrt_information_, parameter_block_sizes(), residuals, nullptr);
    return true;
  }

  // As AuxImuFactor's rotation rows (aux_imu_factor.h), chained with the ends' (aux_end.h).
  const Matrix3 Jr_inv_e = lie::rightJacobianInvSO3(e);
  const Eigen::Matrix<double, 3, aux_end::kColumns> M_i =
      -Jr_inv_e * end_j.R.transpose() * end_i.R * end_i.J.topRows<3>();
  const Eigen::Matrix<double, 3, aux_end::kColumns> M_j = Jr_inv_e * end_j.J.topRows<3>();
  Eigen::Matrix<double, 6, kColumns> D = Eigen::Matrix<double, 6, kColumns>::Zero();
  D.block<3, 15>(0, 0) = M_i.leftCols<15>();
  D.block<3, 15>(0, 15) = M_j.leftCols<15>();
  D.block<3, 3>(0, kExtrinsicColumn) =
      M_i.middleCols<3>(aux_end::kE) + M_j.middleCols<3>(aux_end::kE);
  D.block<3, 1>(0, kTimeOffsetColumn) = M_i.col(aux_end::kTd) + M_j.col(aux_end::kTd);
  const Eigen::Matrix<double, 3, kDeltaVariables> Dx =
      -Jr_inv_e * E.transpose() * lie::rightJacobianSO3(phi) * d.J.topRows<3>();
  D.block<3, 3>(0, kBiasColumn) += Dx.leftCols<3>();
  D.block<3, 3>(3, kBiasColumn) = -Matrix3::Identity();
  D.block<3, 3>(3, kBiasColumn + 3) = Matrix3::Identity();
  D.topRows<3>() = G_inv * D.topRows<3>();

  aux_end::writeBlocks(D, kLayout, kBlocks, jacobians);
  if (intrinsics_ && jacobians[8] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 6, kImuIntrinsicsSize, Eigen::RowMajor>> out(jacobians[8]);
    out.setZero();
    out.block<3, 6>(0, L::kDw) = G_inv * Dx.middleCols<6>(6 + L::kDw) + K.block<3, 6>(0, L::kDw);
    out.block<3, 9>(0, L::kTg) = G_inv * Dx.middleCols<9>(6 + L::kTg);
  }
  whiten<6>(sqrt_information_, parameter_block_sizes(), residuals, jacobians);
  return true;
}

}  // namespace mvis
