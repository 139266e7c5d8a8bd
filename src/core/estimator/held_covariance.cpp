// Covariances with held directions: the pose's with every hold released at the uncertainty it
// kept, and the IMU intrinsics' holds as consider parameters (observability_monitor.h; the
// formula: mvis/estimator/observability.h, consideredCovariance).
//
// An IMU intrinsics' held direction u is kept at its value u_h while the window goes on, and the
// solves give the rest conditioned on it. Its error, of the variance V it had when held, then
// moves the rest by their gain on u, which the covariance adds once, however many
// marginalizations the hold lasts; that needs the prior to keep what every leaving measurement
// told along u and across it and the rest, so those directions are marginalized as kept blocks
// (heldDirections leaves them out).
//
// The gauge (anchors()): with the first camera's translation held along D (tangent coordinates a
// of variance V) and other cameras following it, nothing the data say changes when every sensor
// moves in {I} by d = -R_C0_I^T D_p a and imu0 by -R_W_I d in {W} (every camera's pose in {W}
// stays; without a board the tags move instead). The solves and the prior are conditioned on a;
// its error moves a follower's p_X_I by -R_X_I d and, with a board, every state's position by
// -R_W_I d, exactly, so the covariances add G V G^T with that G (gaugeMap) instead of releasing
// a: released, the window's information along the shift is only what the linearization points
// make up, and took the position NEES to 6-47 for 3.
#include <algorithm>

#include "mvis/estimator/observability.h"
#include "mvis/factors/tangent_prior_factor.h"
#include "observability_monitor.h"

namespace mvis::estimator_internal {

void ObservabilityMonitor::setHolds(ceres::Problem* problem, bool held, bool considered_only,
                                    bool keep_anchor) {
  for (const auto& [const_block, hold] : holds_) {
    if (considered_only && !considered(const_block)) continue;
    if (keep_anchor && anchors(const_block)) continue;
    double* block = const_cast<double*>(const_block);
    if (hold.subspace) {
      problem->SetManifold(block, held ? hold.subspace.get() : hold.base);
    } else if (held) {
      problem->SetParameterBlockConstant(block);
    } else {
      problem->SetParameterBlockVariable(block);
    }
  }
}

bool ObservabilityMonitor::considered(const double* block) const {
  return consider_ && holds_.count(block) > 0 && intrinsics_.isBlock(block);
}

void ObservabilityMonitor::findFollowers(const ceres::Problem& problem) {
  followers_.clear();
  if (!consider_ || calibration_.cameras() < 2) return;
  const auto h = holds_.find(calibration_.camera(0).extrinsic);
  // Only a held translation (a held rotation is not a shift of positions).
  if (h == holds_.end() || h->second.directions.cols() == 0 ||
      h->second.directions.bottomRows<3>().colwise().norm().minCoeff() < 0.99) {
    return;
  }
  for (std::size_t c = 1; c < calibration_.cameras(); ++c) {
    const double* e = calibration_.camera(c).extrinsic;
    if (holds_.count(e) == 0 && !problem.IsParameterBlockConstant(e)) followers_.push_back(e);
  }
}

bool ObservabilityMonitor::anchors(const double* block) const {
  return !followers_.empty() && block == calibration_.camera(0).extrinsic;
}

Eigen::VectorXd ObservabilityMonitor::gaugeVariance() const {
  if (followers_.empty()) return {};
  return holds_.at(calibration_.camera(0).extrinsic).variance;
}

Eigen::MatrixXd ObservabilityMonitor::gaugeMap(const double* block, bool pose) const {
  if (followers_.empty()) return {};
  const double* anchor = calibration_.camera(0).extrinsic;
  const Eigen::MatrixXd& D = holds_.at(anchor).directions;
  if (block == anchor) return D;
  // Extrinsics are T_X_I ([q_X_I, p_X_I], the translation's tangent additive): the anchor's held
  // coordinates a move its p_X_I by D_p a, i.e. every sensor's position in {I} by
  // d = -R_X0_I^T D_p a; a follower's p_X_I by -R_X_I d, imu0's position in {W} by -R_W_I d.
  const Eigen::MatrixXd d =
      -(poseRotation(anchor).toRotationMatrix().transpose() * D.bottomRows<3>());
  const bool follows = std::find(followers_.begin(), followers_.end(), block) != followers_.end();
  if (!pose && !follows) return {};
  // Without a board the estimation frame is imu0's first state's (a tight prior holds it): the
  // tags' corners move with the cameras instead, and imu0's positions stay.
  if (pose && !rig_.target) return {};
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(6, D.cols());
  G.bottomRows<3>() = -(poseRotation(block).toRotationMatrix() * d);
  return G;
}

bool ObservabilityMonitor::considering() const {
  for (const auto& entry : holds_) {
    if (considered(entry.first)) return true;
  }
  return false;
}

void ObservabilityMonitor::consideredColumns(const std::vector<std::pair<int, const double*>>& at,
                                             int rows, Eigen::MatrixXd* U,
                                             Eigen::VectorXd* v) const {
  int q = 0;
  for (const auto& entry : at) q += static_cast<int>(holds_.at(entry.second).directions.cols());
  *U = Eigen::MatrixXd::Zero(rows, q);
  v->resize(q);
  int col = 0;
  for (const auto& [row, block] : at) {
    const Hold& hold = holds_.at(block);
    const auto k = static_cast<int>(hold.directions.cols());
    U->block(row, col, hold.directions.rows(), k) = hold.directions;
    v->segment(col, k) = hold.variance;
    col += k;
  }
}

Eigen::MatrixXd ObservabilityMonitor::considerCovariance(
    const ceres::Problem& problem, const BlockCovariance& cov,
    const std::vector<const double*>& blocks,
    std::map<const double*, std::pair<int, int>>* offsets) const {
  const Eigen::MatrixXd sigma = jointTangentCovariance(problem, cov, blocks, true, offsets);
  if (sigma.size() == 0) return sigma;
  std::vector<std::pair<int, const double*>> at;  // the considered blocks' first rows
  for (const double* block : blocks) {
    if (considered(block)) at.emplace_back(offsets->at(block).first, block);
  }
  Eigen::MatrixXd U;
  Eigen::VectorXd v;
  consideredColumns(at, static_cast<int>(sigma.rows()), &U, &v);
  return consideredCovariance(sigma, U, v);
}

Status ObservabilityMonitor::poseCovarianceWithHeld(ceres::Problem* problem,
                                                    const std::vector<double*>& poses,
                                                    std::vector<Eigen::Matrix<double, 6, 6>>* out) {
  // The pose depends on what is held (a camera's translation along the only rotation axis
  // moves imu0's position in the board frame along it): with the held directions constant its
  // covariance would be as if they were known. Released for this computation, with a prior of
  // the uncertainty they kept, they carry it into the pose. The window may still know a little
  // along them (the marginalization prior keeps what earlier motion told, which is part of the
  // kept variance too), so the pose's variance along them is at worst about half what it is.
  // Considered holds get no prior: the window has their information, and consideredCovariance
  // adds what their kept variance makes of the pose.
  std::vector<ceres::ResidualBlockId> added;
  // In the order they were held, not by address: the residuals' order is the covariance's.
  std::vector<std::pair<std::uint64_t, const double*>> order;
  for (const auto& [block, hold] : holds_) order.emplace_back(hold.sequence, block);
  std::sort(order.begin(), order.end());
  // The gauge's anchor stays held: the pose given it, and G V G^T below.
  liftHolds(problem, false, true);
  std::vector<const double*> considered_blocks;
  for (const auto& [sequence, const_block] : order) {
    if (anchors(const_block)) continue;
    if (considered(const_block)) {
      considered_blocks.push_back(const_block);
      continue;
    }
    Hold& hold = holds_.at(const_block);
    double* block = const_cast<double*>(const_block);
    const int ambient = problem->ParameterBlockSize(block);
    added.push_back(problem->AddResidualBlock(
        new TangentPriorFactor(hold.base, std::vector<double>(block, block + ambient),
                               hold.directions, hold.variance.cwiseMax(1e-30).cwiseSqrt()),
        nullptr, block));
  }
  BlockCovariance cov;
  std::vector<std::pair<const double*, const double*>> listed;
  for (double* pose : poses) listed.emplace_back(pose, pose);
  for (const double* b : considered_blocks) listed.emplace_back(b, b);
  bool ok = cov.compute(listed, problem, !considered_blocks.empty());
  out->assign(poses.size(), Eigen::Matrix<double, 6, 6>::Zero());
  for (std::size_t k = 0; ok && k < poses.size(); ++k) {
    if (considered_blocks.empty()) {
      cov.GetCovarianceBlockInTangentSpace(poses[k], poses[k], (*out)[k].data());
      continue;
    }
    // Every hold is lifted here: the considered ones' rows are their own tangents.
    std::vector<const double*> joint{poses[k]};
    joint.insert(joint.end(), considered_blocks.begin(), considered_blocks.end());
    Eigen::MatrixXd C;
    ok = cov.joint(joint, &C);
    if (!ok) break;
    std::vector<std::pair<int, const double*>> at;
    int row = 6;
    for (const double* b : considered_blocks) {
      at.emplace_back(row, b);
      row += static_cast<int>(holds_.at(b).directions.rows());
    }
    Eigen::MatrixXd U;
    Eigen::VectorXd v;
    consideredColumns(at, static_cast<int>(C.rows()), &U, &v);
    (*out)[k] = consideredCovariance(C, U, v).topLeftCorner<6, 6>();
  }
  const Eigen::VectorXd V = gaugeVariance();
  for (std::size_t k = 0; ok && V.size() > 0 && k < poses.size(); ++k) {
    const Eigen::MatrixXd G = gaugeMap(poses[k], true);
    if (G.size() > 0) (*out)[k] += G * V.asDiagonal() * G.transpose();
  }
  for (ceres::ResidualBlockId id : added) problem->RemoveResidualBlock(id);
  restoreHolds(problem, false, true);
  return ok ? Status::Ok() : Status::Error("pose covariance with the held directions failed");
}

}  // namespace mvis::estimator_internal
