#include "mvis/factors/aux_imu_factor.h"

#include <algorithm>
#include <iterator>

#include "aux_end.h"
#include "mvis/common/lie.h"
#include "mvis/factors/state_blocks.h"
#include "whitening.h"

namespace mvis {
namespace {

// Columns of the unwhitened Jacobian D (15 x kColumns, in the blocks' tangents):
// [dtheta_i, dp_i] 0-5, speed_bias_i 6-14, [dtheta_j, dp_j] 15-20, speed_bias_j 21-29, aux_i
// 30-38 (or 30-35), aux_j 39-47 (or 36-41), [dtheta_e, dp_e] 48-53, t_d 54, gravity 55-57, and the
// intrinsics 58-81 when they are estimated.
constexpr int kAuxColumn = 30, kExtrinsicColumn = 48, kGravityColumn = 55, kIntrinsicsColumn = 58;
constexpr int kColumns = kIntrinsicsColumn + kImuIntrinsicsSize;

// The blocks' columns in D in parameter order, into out[10] (the intrinsics' last); returns how
// many there are without the intrinsics.
int blockColumns(AuxImuModel model, aux_end::BlockColumns* out) {
  const int a = AuxImuFactor::auxBlockSize(model);
  const aux_end::BlockColumns blocks[] = {
      {0, 6, 7},
      {6, 9, 9},
      {15, 6, 7},
      {21, 9, 9},
      {kAuxColumn, a, a},
      {kAuxColumn + a, a, a},
      {kExtrinsicColumn, 6, 7},
      {kExtrinsicColumn + 6, 1, 1},
      {kGravityColumn, 3, 3},
      {kIntrinsicsColumn, kImuIntrinsicsSize, kImuIntrinsicsSize}};
  std::copy(std::begin(blocks), std::end(blocks), out);
  return 9;  // without the intrinsics
}

}  // namespace

AuxImuFactor::AuxImuFactor(AuxImuModel model, std::shared_ptr<const ImuPreintegration> pre,
                           double time_offset0_i, double time_offset0_j, const BaseMotion& base_i,
                           const BaseMotion& base_j)
    : model_(model),
      pre_(std::move(pre)),
      base_i_(base_i),
      base_j_(base_j),
      time_offset0_i_(time_offset0_i),
      time_offset0_j_(time_offset0_j) {
  set_num_residuals(15);
  auto* sizes = mutable_parameter_block_sizes();
  aux_end::BlockColumns blocks[10];
  const int count = blockColumns(model_, blocks);
  for (int b = 0; b < count; ++b) sizes->push_back(blocks[b].ambient);
  sqrt_information_ = sqrtInformation<15>(pre_->covariance());
}

AuxImuFactor::AuxImuFactor(AuxImuModel model, std::shared_ptr<const ImuPreintegration> pre,
                           double time_offset0_i, double time_offset0_j, const BaseMotion& base_i,
                           const BaseMotion& base_j, const ImuIntrinsicsFrame& frame,
                           IntrinsicsLinearization mode, const double* intrinsics0)
    : AuxImuFactor(model, std::move(pre), time_offset0_i, time_offset0_j, base_i, base_j) {
  intrinsics_ = true;
  mode_ = mode;
  frame_ = frame;
  mutable_parameter_block_sizes()->push_back(kImuIntrinsicsSize);
  if (mode_ == IntrinsicsLinearization::kFixed) {
    fixed_ =
        reintegrate(pre_->samples(),
                    deltaVariables(pre_->biasGyro().data(), pre_->biasAccel().data(), intrinsics0),
                    frame_, true);
  }
}

bool AuxImuFactor::Evaluate(double const* const* parameters, double* residuals,
                            double** jacobians) const {
  using Matrix3 = Eigen::Matrix3d;
  using Vector3 = Eigen::Vector3d;
  using P = ImuPreintegration;
  const bool velocity_state = model_ == AuxImuModel::kVelocityState;
  const int a = auxBlockSize(model_);
  const int bias_at = velocity_state ? 3 : 0;  // b^A_g within the aux block
  const bool jacobian = jacobians != nullptr;
  const ImuDeltas::Vector30d x = deltaVariables(
      parameters[4] + bias_at, parameters[4] + bias_at + 3, intrinsics_ ? parameters[9] : nullptr);
  ImuDeltas local;
  const ImuDeltas& d = factorDeltas(*pre_, intrinsics_, mode_, fixed_, x, frame_, jacobian, &local);

  aux_end::Inputs in;
  in.R_AI = poseRotation(parameters[6]).toRotationMatrix();
  in.p_AI = posePosition(parameters[6]);
  in.g = Vector3(parameters[8]);
  in.velocity_state = velocity_state;
  // End k (0: i, 1: j): its base blocks, aux block, base motion, offset and aux gyro reading.
  const auto end = [&](int k, const BaseMotion& motion, double time_offset0,
                       const ImuMeasurement& reading) {
    in.motion = &motion;
    in.pose = parameters[2 * k];
    in.speed_bias = parameters[2 * k + 1];
    in.delta = parameters[7][0] - time_offset0;
    in.aux = parameters[4 + k];
    in.aux_gyro = reading.gyro;
    return aux_end::evaluate(in, jacobian);
  };
  const aux_end::End end_i = end(0, base_i_, time_offset0_i_, pre_->samples().front());
  const aux_end::End end_j = end(1, base_j_, time_offset0_j_, pre_->samples().back());

  // The deltas corrected to x to first order about where they were integrated (Eq. 32-34).
  const Eigen::Matrix<double, 9, 1> lin = d.J * (x - d.x0);
  const Vector3 phi = lin.head<3>();
  const Matrix3 dR = d.dR * lie::expSO3(phi);
  const double T = pre_->duration();
  const Vector3& g = in.g;
  const Matrix3 Rt_i = end_i.R.transpose();
  const Matrix3 E = dR.transpose() * Rt_i * end_j.R;
  const Vector3 e = lie::logSO3(E);
  const Vector3 a_p = Rt_i * (end_j.p - end_i.p - end_i.v * T - 0.5 * T * T * g);
  const Vector3 a_v = Rt_i * (end_j.v - end_i.v - g * T);
  Eigen::Map<Eigen::Matrix<double, 15, 1>> r(residuals);
  r.segment<3>(P::kRotation) = e;
  r.segment<3>(P::kPosition) = a_p - (d.dp + lin.segment<3>(3));
  r.segment<3>(P::kVelocity) = a_v - (d.dv + lin.tail<3>());
  r.segment<3>(P::kBiasGyro) = Vector3(parameters[5] + bias_at) - Vector3(parameters[4] + bias_at);
  r.segment<3>(P::kBiasAccel) =
      Vector3(parameters[5] + bias_at + 3) - Vector3(parameters[4] + bias_at + 3);
  // With the intrinsics estimated, the readings' noise seen through the current corrections
  // (imu_factor.h): r <- S^-1 r before the whitening, d(S^-1)/dx r into the intrinsics' columns.
  Matrix3 G_inv = Matrix3::Identity(), M_inv = Matrix3::Identity();
  Eigen::Matrix<double, 9, kImuIntrinsicsSize> K;
  if (intrinsics_) {
    Eigen::Matrix<double, 9, 1> scaled;
    noiseMapInverses(parameters[9], frame_, r.head<9>(), &scaled, jacobian ? &K : nullptr, &G_inv,
                     &M_inv);
    r.head<9>() = scaled;
  }
  if (!jacobian) {
    whiten<15>(sqrt_information_, parameter_block_sizes(), residuals, nullptr);
    return true;
  }

  // The residual's derivatives in each end's (theta_A, p_A, v_A), as ImuFactor's in its states,
  // chained with the ends' (aux_end.h); then gravity's and the deltas' variables' own terms.
  const Matrix3 Jr_inv_e = lie::rightJacobianInvSO3(e);
  Eigen::Matrix<double, 15, 9> B_i = Eigen::Matrix<double, 15, 9>::Zero();
  Eigen::Matrix<double, 15, 9> B_j = Eigen::Matrix<double, 15, 9>::Zero();
  B_i.block<3, 3>(P::kRotation, 0) = -Jr_inv_e * end_j.R.transpose() * end_i.R;
  B_i.block<3, 3>(P::kPosition, 0) = lie::hat(a_p);
  B_i.block<3, 3>(P::kPosition, 3) = -Rt_i;
  B_i.block<3, 3>(P::kPosition, 6) = -T * Rt_i;
  B_i.block<3, 3>(P::kVelocity, 0) = lie::hat(a_v);
  B_i.block<3, 3>(P::kVelocity, 6) = -Rt_i;
  B_j.block<3, 3>(P::kRotation, 0) = Jr_inv_e;
  B_j.block<3, 3>(P::kPosition, 3) = Rt_i;
  B_j.block<3, 3>(P::kVelocity, 6) = Rt_i;
  const Eigen::Matrix<double, 15, aux_end::kColumns> M_i = B_i * end_i.J;
  const Eigen::Matrix<double, 15, aux_end::kColumns> M_j = B_j * end_j.J;
  constexpr int kShared = aux_end::kAux - aux_end::kE;  // extrinsic, t_d, gravity
  Eigen::Matrix<double, 15, kColumns> D = Eigen::Matrix<double, 15, kColumns>::Zero();
  D.leftCols<15>() = M_i.leftCols<15>();
  D.middleCols<15>(15) = M_j.leftCols<15>();
  D.middleCols<kShared>(kExtrinsicColumn) =
      M_i.middleCols<kShared>(aux_end::kE) + M_j.middleCols<kShared>(aux_end::kE);
  D.middleCols<3>(kAuxColumn) = M_i.rightCols<3>();
  D.middleCols<3>(kAuxColumn + a) = M_j.rightCols<3>();
  D.block<3, 3>(P::kPosition, kGravityColumn) -= 0.5 * T * T * Rt_i;
  D.block<3, 3>(P::kVelocity, kGravityColumn) -= T * Rt_i;
  Eigen::Matrix<double, 9, kDeltaVariables> Dx;
  Dx.topRows<3>() = -Jr_inv_e * E.transpose() * lie::rightJacobianSO3(phi) * d.J.topRows<3>();
  Dx.bottomRows<6>() = -d.J.bottomRows<6>();
  D.block<9, 6>(0, kAuxColumn + bias_at) += Dx.leftCols<6>();
  if (intrinsics_) D.block<9, kImuIntrinsicsSize>(0, kIntrinsicsColumn) = Dx.rightCols<24>();
  const Matrix3 I = Matrix3::Identity();
  for (int k = 0; k < 2; ++k) {  // the bias random walks: b^A_j - b^A_i
    const int row = k == 0 ? P::kBiasGyro : P::kBiasAccel;
    D.block<3, 3>(row, kAuxColumn + bias_at + 3 * k) -= I;
    D.block<3, 3>(row, kAuxColumn + a + bias_at + 3 * k) += I;
  }

  if (intrinsics_) {
    D.middleRows<3>(P::kRotation) = G_inv * D.middleRows<3>(P::kRotation);
    D.middleRows<3>(P::kPosition) = M_inv * D.middleRows<3>(P::kPosition);
    D.middleRows<3>(P::kVelocity) = M_inv * D.middleRows<3>(P::kVelocity);
    D.block<9, kImuIntrinsicsSize>(0, kIntrinsicsColumn) += K;
  }
  aux_end::BlockColumns blocks[10];
  const int count = blockColumns(model_, blocks) + (intrinsics_ ? 1 : 0);
  aux_end::writeBlocks(D, blocks, count, jacobians);
  whiten<15>(sqrt_information_, parameter_block_sizes(), residuals, jacobians);
  return true;
}

}  // namespace mvis
