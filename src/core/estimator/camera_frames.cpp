#include "camera_frames.h"

#include <ceres/normal_prior.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <sstream>

#include "mvis/estimator/initialization.h"

namespace mvis {
namespace estimator_internal {
namespace {

// A camera frame's IMU-propagated pose depends on the IMU intrinsics (as a parameter block of its
// factor) only when it is propagated further than this from its state: over 2 ms a 1% scale
// error at 1 rad/s moves it by 2e-5 rad (~0.01 px), and each such block costs the solver a
// 24-column Jacobian per frame (J^T J was 15% of the run).
constexpr TimeNs kIntrinsicsAnchorSpanNs = 2000000;  // 2 ms
// A frame propagated less than this from its state (cam0's, at their state's time) carries no
// propagation-noise block: its readings' noise is under 1e-5 rad there, and the block would cost
// a parameter block per frame.
constexpr TimeNs kPropagationNoiseSpanNs = 1000000;  // 1 ms
// Frames of one camera waiting at most (the IMU or cam0 stopped: they must not pile up).
constexpr std::size_t kMaxWaiting = 300;
// The frame gate's baseline: the median of a camera's last frames' median residuals (about
// 10 s of them, so that a clock drifting for a few seconds does not carry the baseline with it);
// a frame beyond kBaselineRatio times it (and beyond kBaselineFloor sigma) is dropped.
constexpr std::size_t kBaselineFrames = 300;
constexpr std::size_t kBaselineMinFrames = 30;
constexpr double kBaselineRatio = 3.0;
constexpr double kBaselineFloor = 2.0;
// settleFirstBatch(): a batch tag factor whose corners' whitened residuals have a mean square
// (per corner, both axes) up to this, i.e. an RMS up to 2 sigma, takes the loss per corner; clean
// corners have about 2.
constexpr double kSettledMeanSquare = 4.0;

// The prior of a frame's propagation-noise block, N(0, covariance) ([dtheta, dp, dv]); null
// when the covariance is not positive definite.
ceres::CostFunction* propagationNoisePrior(const Eigen::Matrix<double, 9, 9>& covariance) {
  // A with A^T A = Sigma^-1, through the Jacobi-scaled S = D Sigma D (D = diag(Sigma)^-1/2: the
  // rotation's and position's variances differ by orders of magnitude): A = L^-1 D, S = L L^T.
  const Eigen::Matrix<double, 9, 1> d = covariance.diagonal();
  if (!(d.minCoeff() > 0.0) || !d.allFinite()) return nullptr;
  const Eigen::Matrix<double, 9, 1> D = d.cwiseSqrt().cwiseInverse();
  const Eigen::Matrix<double, 9, 9> S = D.asDiagonal() * covariance * D.asDiagonal();
  const Eigen::LLT<Eigen::Matrix<double, 9, 9>> llt(S);
  if (llt.info() != Eigen::Success) return nullptr;
  Eigen::Matrix<double, 9, 9> A = D.asDiagonal();
  llt.matrixL().solveInPlace(A);
  return new ceres::NormalPrior(A, Eigen::VectorXd::Zero(kPropagationNoiseSize));
}

}  // namespace

CameraFrames::CameraFrames(const Rig& rig, const EstimatorOptions& options, Window& window,
                           const ImuBuffer& imu, CalibrationBlocks& calibration,
                           ImuIntrinsicsBlocks& intrinsics, Landmarks& landmarks,
                           EstimatorCounters& counters)
    : rig_(rig),
      options_(options),
      window_(window),
      imu_(imu),
      calibration_(calibration),
      intrinsics_(intrinsics),
      landmarks_(landmarks),
      counters_(counters),
      waiting_(rig.cameras.size()),
      last_(rig.cameras.size(), std::numeric_limits<TimeNs>::min()),
      recent_(rig.cameras.size()),
      held_out_(rig.cameras.size(), false) {
  if (options.huber_sigma > 0.0) huber_ = std::make_unique<ceres::HuberLoss>(options.huber_sigma);
}

int CameraFrames::minTags() const { return !rig_.target ? 1 : options_.min_tags; }

bool CameraFrames::markNewer(const TagFrame& frame) {
  if (frame.stamp_ns <= last_[frame.camera]) return false;
  last_[frame.camera] = frame.stamp_ns;
  return true;
}

void CameraFrames::enqueue(TagFrame frame) {
  auto& q = frame.camera == 0 ? base_ : waiting_[frame.camera];
  q.push_back(std::move(frame));
  while (q.size() > kMaxWaiting) {
    q.pop_front();
    ++counters_.frames_too_old;
  }
}

TagFrame CameraFrames::takeBaseFrame() {
  TagFrame out = std::move(base_.front());
  base_.pop_front();
  return out;
}

void CameraFrames::forgetResiduals() {
  for (auto& r : recent_) r.clear();
  gate_sigma_ = 0.0;
}

void CameraFrames::clear() {
  base_.clear();
  for (auto& q : waiting_) q.clear();
  std::fill(last_.begin(), last_.end(), std::numeric_limits<TimeNs>::min());
  last_entered_ = std::numeric_limits<TimeNs>::min();
  // recent_ stays: a camera's residual level is the camera's, not the window's
  // (forgetResiduals() when the calibration starts over from the configured one).
}

namespace {

// Each corner's whitened residual norm at the blocks' current values (empty if the factor
// cannot be evaluated there).
std::vector<double> cornerResiduals(const ceres::CostFunction& factor,
                                    const std::vector<double*>& blocks) {
  std::vector<double> r(static_cast<std::size_t>(factor.num_residuals()));
  if (r.size() < 2 ||
      !factor.Evaluate(const_cast<double* const*>(blocks.data()), r.data(), nullptr)) {
    return {};
  }
  std::vector<double> norms;
  for (std::size_t i = 0; i + 1 < r.size(); i += 2) norms.push_back(std::hypot(r[i], r[i + 1]));
  return norms;
}

// The median of v (infinite if v is empty).
double medianOf(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::infinity();
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

}  // namespace

ceres::LossFunction* CameraFrames::tagLoss(int tags) {
  if (!huber_) return nullptr;
  auto& loss = tag_losses_[tags];
  if (!loss) {
    loss = std::make_unique<ceres::HuberLoss>(options_.huber_sigma / std::sqrt(double(tags)));
  }
  return loss.get();
}

void CameraFrames::dropBatchLosses() {
  batch_losses_.clear();
  batch_settled_ = false;
}

int CameraFrames::settleFirstBatch() {
  if (batch_losses_.empty() || batch_settled_) return 0;
  batch_settled_ = true;
  std::map<const ceres::LossFunction*, ceres::LossFunctionWrapper*> wrappers;
  for (const auto& w : batch_losses_) wrappers.emplace(w.get(), w.get());
  int changed = 0;
  std::vector<double> r;
  for (std::size_t k = 0; k < window_.size(); ++k) {
    for (const ResidualRecord& record : window_.state(k).residuals) {
      const auto w = wrappers.find(record.loss);
      if (w == wrappers.end()) continue;
      // The record's factor is the problem's (held const there, not const itself).
      auto* factor =
          dynamic_cast<TagReprojectionFactor*>(const_cast<ceres::CostFunction*>(record.cost));
      if (factor == nullptr || factor->corners().empty()) continue;
      r.resize(static_cast<std::size_t>(factor->num_residuals()));
      if (!factor->Evaluate(record.blocks.data(), r.data(), nullptr)) continue;
      const double mean_square =
          Eigen::Map<const Eigen::VectorXd>(r.data(), r.size()).squaredNorm() /
          static_cast<double>(factor->corners().size());
      if (!(mean_square <= kSettledMeanSquare)) continue;
      factor->useCornerLoss(options_.huber_sigma);
      w->second->Reset(nullptr, ceres::TAKE_OWNERSHIP);  // plain squares from here on
      ++changed;
    }
  }
  return changed;
}

std::vector<double> CameraFrames::addEvidence(const ceres::CostFunction& factor,
                                              const std::vector<double*>& blocks,
                                              const TagFrame& frame) {
  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  const std::size_t c = frame.camera;
  CameraBlocks& cb = calibration_.camera(c);
  const int n = factor.num_residuals();
  if (n < 2) return {};
  Eigen::VectorXd r(n);
  RowMajor J_extrinsic(n, kPoseSize), J_offset(n, 1);
  std::vector<double*> jacobians(blocks.size(), nullptr);
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    if (blocks[i] == cb.extrinsic) jacobians[i] = J_extrinsic.data();
    if (blocks[i] == cb.time_offset) jacobians[i] = J_offset.data();
  }
  if (!factor.Evaluate(const_cast<double* const*>(blocks.data()), r.data(), jacobians.data())) {
    return {};
  }
  // The corners that agree with the frame's others: a camera that moved shifts all of them
  // alike, a wrong detection one (its norm beyond 4 times the frame's median and 3 sigma; with
  // 3% of the corners 15-30 px off the noise level measured on the evidence was 2400).
  std::vector<double> norms;
  for (int i = 0; i + 1 < n; i += 2) norms.push_back(std::hypot(r[i], r[i + 1]));
  const double bound = std::max(4.0 * medianOf(norms), 3.0);
  std::vector<int> rows;
  for (int i = 0; i + 1 < n; i += 2) {
    if (norms[static_cast<std::size_t>(i / 2)] <= bound) rows.insert(rows.end(), {i, i + 1});
  }
  if (rows.empty()) return norms;
  // The pose block's first six columns are its tangent's (state_blocks.h).
  Eigen::VectorXd r_kept(static_cast<Eigen::Index>(rows.size()));
  Eigen::MatrixXd J(static_cast<Eigen::Index>(rows.size()), ChangeDetector::kDim);
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const auto row = static_cast<Eigen::Index>(k);
    r_kept[row] = r[rows[k]];
    J.row(row).head(kPoseTangent) = J_extrinsic.row(rows[k]).head(kPoseTangent);
    J(row, kPoseTangent) = J_offset(rows[k], 0);
  }
  changes_->add(c, frame.stamp_ns + calibration_.timeOffsetNs(c), r_kept, J);
  return norms;
}

SE3 CameraFrames::cameraPoseAt(const TagFrame& frame, std::size_t k) const {
  const State& sk = window_.state(k);
  const std::size_t c = frame.camera;
  const TimeNs t = std::max(sk.t, frame.stamp_ns + calibration_.timeOffsetNs(c));
  Eigen::Vector3d bg, ba;
  intrinsics_.baseBiases(sk.biasGyro(), sk.biasAccel(), &bg, &ba);
  Eigen::Quaterniond q;
  Eigen::Vector3d p, v;
  imu_.preintegrate(sk.t, t, bg, ba, &intrinsics_.baseCorrection())
      ->predict(poseRotation(sk.pose), posePosition(sk.pose), Eigen::Vector3d(sk.speed_bias),
                Eigen::Vector3d(calibration_.gravity()), &q, &p, &v);
  return SE3(q, p) * poseToSE3(calibration_.camera(c).extrinsic).inverse();
}

std::vector<CameraFrames::Piece> CameraFrames::factors(const TagFrame& frame, std::size_t k,
                                                       bool initialized) {
  const std::size_t c = frame.camera;
  if (held_out_[c]) {
    if (!initialized) return {};
    held_out_[c] = false;
  }
  CameraBlocks& cb = calibration_.camera(c);
  double* gravity = calibration_.gravity();
  // The frame's pose comes from the readings around it: inside a gap they are made up.
  if (imu_.insideGap(frame.stamp_ns + calibration_.timeOffsetNs(c))) {
    ++counters_.frames_in_imu_gap;
    return {};
  }
  // The corners in groups of one factor each, with their landmark block (null: board points).
  std::vector<std::pair<std::vector<CornerObservation>, double*>> groups;
  if (!rig_.target) {
    const Camera camera = calibration_.currentCamera(c);  // for the tags seen the first time
    for (const auto& tag : frame.tags) {
      if ((k < carried_only_before_ || !options_.window_own_tags) &&
          !landmarks_.wouldCarry(tag.tag_id)) {
        continue;
      }
      double* landmark = landmarks_.landmarkFor(window_.problem(), camera, frame, tag,
                                                [&] { return cameraPoseAt(frame, k); });
      if (landmark == nullptr) continue;
      std::vector<CornerObservation> obs;
      for (int i = 0; i < 4; ++i) obs.push_back({Eigen::Vector3d::Zero(), tag.corners_px[i], i});
      groups.emplace_back(std::move(obs), landmark);
    }
  } else {
    auto obs = boardCorners(frame, *rig_.target);
    if (!obs.empty()) groups.emplace_back(std::move(obs), nullptr);
  }
  if (groups.empty()) return {};
  const DistortionModel model = rig_.cameras[c].distortion_model;
  State* sk = &window_.state(k);
  std::vector<double*> blocks;
  std::function<TagReprojectionFactor*(std::vector<CornerObservation>)> make;
  double* noise = nullptr;  // the frame's propagation-noise block, shared by its tags' factors
  ceres::CostFunction* noise_prior = nullptr;
  if (options_.interpolation == FrameInterpolation::kImu) {
    const TimeNs t_a = std::max(sk->t, frame.stamp_ns + calibration_.timeOffsetNs(c));
    // The readings at t_a for the last few milliseconds (the time offset's change): corrected by
    // the current intrinsics estimate when they are estimated (the raw bias states are then
    // subtracted from corrected readings: a few parts per thousand of a bias over milliseconds).
    // The rate is the value at t_a of a line fitted to the gyroscope within 10 ms
    // (ImuBuffer::smoothedAt), as for the base motion at a state: on a rig that does not turn
    // one reading's noise is all the rate it shows, and the time offset's derivative took it as
    // motion; that reading is also the last of the propagation to t_a, so its noise entered the
    // frame's pose and that derivative together. With 0.1 px corners on translation-only motion
    // every time offset ended +0.51 ms off (8 sigma; IMU noise alone +1.27 ms), now +0.06 ms
    // (doc/results.md, "Every quantity free", eighth round). The accelerometer reading enters
    // only at second order in the change and stays as it is.
    ImuMeasurement reading = imu_.at(t_a);
    reading.gyro = imu_.smoothedAt(t_a).gyro;
    const ImuMeasurement at = intrinsics_.baseCorrection().apply(reading, false);
    const Eigen::Vector3d alpha = imu_.angularAcceleration(t_a);
    const double dt_nominal = toSeconds(frame.stamp_ns - t_a);
    TagReprojectionFactor::ImuAnchor anchor;
    blocks = {sk->pose, sk->speed_bias, gravity, cb.extrinsic, cb.time_offset, cb.intrinsics};
    // The readings' covariance over [t_k, t_a], [dtheta, dp, dv] (imu_preintegration.h).
    Eigen::Matrix<double, 9, 9> propagation_cov = Eigen::Matrix<double, 9, 9>::Zero();
    double* imu_in = intrinsics_.values(0);
    if (imu_in != nullptr && t_a - sk->t > kIntrinsicsAnchorSpanNs) {
      // Raw readings re-integrated at the state's biases and the current intrinsics, with the
      // intrinsics' Jacobian (tag_reprojection_factor.h).
      const ImuDeltas d =
          reintegrate(imu_.toIntegrate(sk->t, t_a),
                      deltaVariables(sk->speed_bias + 3, sk->speed_bias + 6, imu_in),
                      intrinsics_.block(0)->frame, true);
      anchor = TagReprojectionFactor::makeAnchor(d, true, dt_nominal, at.gyro, at.accel, alpha);
      blocks.push_back(imu_in);
      if (options_.propagation_noise) {
        const Eigen::Vector3d bg(sk->speed_bias + 3), ba(sk->speed_bias + 6);
        propagation_cov = imu_.preintegrate(sk->t, t_a, bg, ba, &intrinsics_.baseCorrection())
                              ->covariance()
                              .topLeftCorner<9, 9>();
      }
    } else {
      // Without intrinsics, or over so short a span (cam0's frames, at their state's time) that
      // they cannot matter: readings corrected by the current estimate, no intrinsics block
      // (the biases in corrected form, imu_correction.h; both identity without intrinsics).
      Eigen::Vector3d bg, ba;
      intrinsics_.baseBiases(sk->biasGyro(), sk->biasAccel(), &bg, &ba);
      auto pre = imu_.preintegrate(sk->t, t_a, bg, ba, &intrinsics_.baseCorrection());
      anchor = TagReprojectionFactor::makeAnchor(*pre, dt_nominal, at.gyro, at.accel, alpha);
      propagation_cov = pre->covariance().topLeftCorner<9, 9>();
    }
    if (options_.propagation_noise && t_a - sk->t >= kPropagationNoiseSpanNs) {
      noise_prior = propagationNoisePrior(propagation_cov);
    }
    if (noise_prior != nullptr) {
      sk->propagation_noise.push_back(std::make_unique<double[]>(kPropagationNoiseSize));
      noise = sk->propagation_noise.back().get();
      std::fill(noise, noise + kPropagationNoiseSize, 0.0);
      blocks.push_back(noise);
    }
    make = [&, anchor](std::vector<CornerObservation> obs) {
      auto* f = TagReprojectionFactor::imuPropagated(model, std::move(obs), options_.pixel_sigma_px,
                                                     anchor);
      if (noise != nullptr) f->usePropagationNoise();
      return f;
    };
  } else if (c == 0) {
    const double dt_nominal = toSeconds(frame.stamp_ns - sk->t);
    blocks = {sk->pose, sk->speed_bias, cb.extrinsic, cb.time_offset, cb.intrinsics};
    make = [&, dt_nominal](std::vector<CornerObservation> obs) {
      return TagReprojectionFactor::kinematic(model, std::move(obs), options_.pixel_sigma_px,
                                              dt_nominal, sk->motion.gyro);
    };
  } else {
    State* sk1 = &window_.state(k + 1);
    blocks = {sk->pose, sk1->pose, cb.extrinsic, cb.time_offset, cb.intrinsics};
    make = [&, sk1](std::vector<CornerObservation> obs) {
      return TagReprojectionFactor::poseBased(model, std::move(obs), options_.pixel_sigma_px,
                                              toSeconds(frame.stamp_ns - sk->t),
                                              toSeconds(sk1->t - sk->t));
    };
  }
  std::vector<Piece> out;
  // A frame's tag factors share its camera pose (without a board; with one it has one factor).
  const auto shared = !rig_.target ? TagReprojectionFactor::makeSharedCameraPose() : nullptr;
  for (auto& [obs, landmark] : groups) {
    const bool gated = landmark == nullptr && initialized && options_.frame_gate_sigma > 0.0;
    TagReprojectionFactor* factor = make(gated ? obs : std::move(obs));
    // Each corner's whitened residual norm, the change test's evaluation's when it has one.
    std::vector<double> norms;
    if (landmark == nullptr && initialized && changes_ != nullptr) {
      norms = addEvidence(*factor, blocks, frame);
    }
    if (gated) {
      if (norms.empty()) norms = cornerResiduals(*factor, blocks);
      const double median = medianOf(norms);
      // Against the camera's own recent frames too: a clock that drifts moves its corners
      // gradually, long before they are gate_sigma_ off.
      auto& recent = recent_[c];
      const double baseline = recent.size() >= kBaselineMinFrames
                                  ? medianOf(std::vector<double>(recent.begin(), recent.end()))
                                  : std::numeric_limits<double>::infinity();
      const bool off = (gate_sigma_ > 0.0 && !(median <= gate_sigma_)) || !std::isfinite(median) ||
                       (median > kBaselineRatio * baseline && median > kBaselineFloor);
      if (!off) {
        recent.push_back(median);
        if (recent.size() > kBaselineFrames) recent.pop_front();
      } else {
        delete factor;
        if (noise != nullptr) {
          sk->propagation_noise.pop_back();
          delete noise_prior;
        }
        ++counters_.frames_rejected;
        std::ostringstream s;
        s << rig_.cameras[c].name << ": frame dropped, its corners " << median
          << " sigma (median) from where the estimate puts them";
        if (std::isfinite(baseline)) s << ", " << median / baseline << "x its recent frames'";
        s << " (its clock jumped or drifts, the camera moved, or wrong detections)";
        warning_ = s.str();
        return {};
      }
      // Once trusted, a corner beyond gate_sigma_ in a frame that is otherwise where the estimate
      // puts it is a wrong detection: on the real EuRoC bag yac's detector put a few corners of
      // cam0's frames 8-33 px off (at 27 s, the board leaving the image), and with the camera's
      // intrinsics estimated they moved them 18 sigma in one step, per-corner Huber loss or not.
      std::vector<CornerObservation> kept;
      double worst = 0.0;
      for (std::size_t i = 0; gate_sigma_ > 0.0 && i < norms.size() && i < obs.size(); ++i) {
        if (norms[i] <= gate_sigma_) {
          kept.push_back(obs[i]);
        } else {
          worst = std::max(worst, norms[i]);
        }
      }
      if (worst > 0.0 && !kept.empty()) {
        const std::size_t dropped = obs.size() - kept.size();
        counters_.corners_rejected += static_cast<long>(dropped);
        std::ostringstream s;
        s << rig_.cameras[c].name << ": " << dropped << " corner(s) of a frame dropped, up to "
          << worst << " sigma from where the estimate puts them (frame_gate_sigma " << gate_sigma_
          << "; wrong detections)";
        warning_ = s.str();
        delete factor;
        factor = make(std::move(kept));
      }
    }
    ceres::LossFunction* loss = nullptr;
    // The first batch (before `initialized`) always has the loss per frame: its residuals are
    // mostly the rough initial calibration's, which a per-corner loss would take for outliers
    // (it left the batch's states tens of millimetres off), and plain squares would let a
    // wrong detection in it bias everything that follows (without a board its clean frames take
    // the loss per corner once it is solved, settleFirstBatch()). A batch starts from a solved
    // calibration: its first frames count as every other.
    if (options_.robust_loss == RobustLoss::kFrame || (!initialized && !options_.batch)) {
      const int tags = static_cast<int>(groups.size());
      if (landmark == nullptr) {
        loss = huber_.get();
      } else if (options_.robust_loss == RobustLoss::kFrame || !huber_) {
        loss = tagLoss(tags);
      } else {
        // Its own, for settleFirstBatch().
        batch_losses_.push_back(std::make_unique<ceres::LossFunctionWrapper>(
            new ceres::HuberLoss(options_.huber_sigma / std::sqrt(double(tags))),
            ceres::TAKE_OWNERSHIP));
        loss = batch_losses_.back().get();
      }
    } else if (options_.huber_sigma > 0.0) {
      factor->useCornerLoss(options_.huber_sigma);
    }
    Piece piece{factor, loss, blocks};
    if (landmark != nullptr) {
      factor->useLandmarkBlock();
      factor->shareCameraPose(shared);
      piece.blocks.push_back(landmark);
    } else if (!options_.batch) {
      // The window's solves, marginalization and covariances see the same normal equations
      // from 15 rows as from every corner's two (tag_reprojection_factor.h); a batch keeps the
      // corners' rows for its residual summary and clustered covariance.
      factor->compressRows(calibration_.fixedBlocks().count(cb.intrinsics) == 0);
    }
    out.push_back(std::move(piece));
  }
  if (noise != nullptr) out.push_back({noise_prior, nullptr, {noise}});
  return out;
}

void CameraFrames::add(const TagFrame& frame, std::size_t k, bool initialized) {
  auto pieces = factors(frame, k, initialized);
  if (pieces.empty()) return;
  State* owner = &window_.state(k);
  for (auto& piece : pieces) {
    const auto* tag = dynamic_cast<const TagReprojectionFactor*>(piece.cost);
    window_.addRecord(owner, piece.cost, piece.loss, std::move(piece.blocks), -1,
                      tag != nullptr ? static_cast<int>(tag->corners().size()) : 0);
  }
  owner->frames += 1;
  last_entered_ = std::max(last_entered_, window_.state(k).t);
}

void CameraFrames::attachWaiting(bool initialized) {
  if (window_.size() < 2) return;
  for (std::size_t c = 1; c < waiting_.size(); ++c) {
    auto& q = waiting_[c];
    const TimeNs offset = calibration_.timeOffsetNs(c);
    while (!q.empty()) {
      const TimeNs t = q.front().stamp_ns + offset;
      if (t < window_.oldest().t) {
        ++counters_.frames_too_old;
        q.pop_front();
        continue;
      }
      if (t > window_.newestTime()) break;
      std::size_t k = 0;
      while (k + 2 < window_.size() && window_.state(k + 1).t <= t) ++k;
      add(q.front(), k, initialized);
      q.pop_front();
    }
  }
}

}  // namespace estimator_internal
}  // namespace mvis
