// Tag corners as landmark states when the rig has no board (report Eq. 11): before the window
// starts, one tag per camera gives its poses (at unit side; initialize() finds the side); then
// every tag starts from one view, and leaves the window (marginalized into the prior) with the
// last state that sees it.
#include <set>

#include "estimator_impl.h"

namespace mvis {
namespace {

// The tag's area in the image [px^2] (shoelace formula over its corners).
double imageArea(const TagObservation& tag) {
  double twice = 0.0;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2d& a = tag.corners_px[k];
    const Eigen::Vector2d& b = tag.corners_px[(k + 1) % 4];
    twice += a.x() * b.y() - b.x() * a.y();
  }
  return 0.5 * std::abs(twice);
}

}  // namespace

bool Estimator::Impl::poseOnTag(const TagFrame& frame, SE3* T_T_C) {
  const std::size_t c = frame.camera;
  const Camera camera = currentCamera(c);
  if (pose_tag[c] >= 0 && tagPose(camera, frame, pose_tag[c], 1.0, T_T_C)) return true;
  const TagObservation* best = nullptr;
  for (const auto& tag : frame.tags) {
    if (best == nullptr || imageArea(tag) > imageArea(*best)) best = &tag;
  }
  if (best == nullptr) return false;
  if (pose_tag[c] != best->tag_id) {
    // Rotations on different tags do not compare (tags need not be parallel): start over.
    pose_tag[c] = best->tag_id;
    board_rotations[c].clear();
    if (c == 0) init.clear();
  }
  return tagPose(camera, frame, pose_tag[c], 1.0, T_T_C);
}

double Estimator::Impl::meanTagSide() const {
  double sum = 0.0;
  int n = 0;
  for (const auto& [id, landmark] : landmarks) {
    for (int k = 0; k < 4; ++k) {
      sum +=
          (Eigen::Vector3d(landmark->x + 3 * k) - Eigen::Vector3d(landmark->x + 3 * ((k + 1) % 4)))
              .norm();
      ++n;
    }
  }
  return n > 0 ? sum / n : initial_tag_side;
}

double* Estimator::Impl::landmarkFor(const TagFrame& frame, const TagObservation& tag,
                                     std::size_t k) {
  const auto found = landmarks.find(tag.tag_id);
  if (found != landmarks.end()) return found->second->x;
  // The camera's pose at the frame: state k's carried there with the readings.
  const State& sk = *states[k];
  const std::size_t c = frame.camera;
  const TimeNs t = std::max(sk.t, frame.stamp_ns + timeOffsetNs(c));
  Eigen::Vector3d bg, ba;
  propagationBiases(Eigen::Vector3d(sk.speed_bias + 3), Eigen::Vector3d(sk.speed_bias + 6), &bg,
                    &ba);
  Eigen::Quaterniond q;
  Eigen::Vector3d p, v;
  preintegrate(sk.t, t, bg, ba, true)
      ->predict(poseRotation(sk.pose), posePosition(sk.pose), Eigen::Vector3d(sk.speed_bias),
                Eigen::Vector3d(gravity), &q, &p, &v);
  const SE3 T_G_C = SE3(q, p) * poseToSE3(cameras[c]->extrinsic).inverse();
  // One view of a tag tells its size only through the others': tags of one size are assumed
  // (another size starts at the wrong depth, which the following views correct).
  const double side = meanTagSide();
  SE3 T_T_C;
  if (!tagPose(currentCamera(c), frame, tag.tag_id, side, &T_T_C)) return nullptr;
  const SE3 T_G_T = T_G_C * T_T_C.inverse();
  auto landmark = std::make_unique<TagLandmark>();
  for (int i = 0; i < 4; ++i) {
    Eigen::Map<Eigen::Vector3d>(landmark->x + 3 * i) = T_G_T * tagCorner(i, side);
  }
  if (!Eigen::Map<const Eigen::Matrix<double, kTagLandmarkSize, 1>>(landmark->x).allFinite()) {
    return nullptr;
  }
  problem->AddParameterBlock(landmark->x, kTagLandmarkSize);
  double* block = landmark->x;
  landmark_ids[block] = tag.tag_id;
  landmarks[tag.tag_id] = std::move(landmark);
  return block;
}

std::vector<double*> Estimator::Impl::leavingLandmarks(const State& oldest) const {
  if (landmarks.empty()) return {};
  std::set<const double*> kept;
  for (const auto& s : states) {
    if (s.get() == &oldest) continue;
    for (const auto& r : s->residuals) {
      for (double* b : r.blocks) {
        if (landmark_ids.count(b)) kept.insert(b);
      }
    }
  }
  std::vector<double*> out;
  std::set<const double*> seen;
  for (const auto& r : oldest.residuals) {
    for (double* b : r.blocks) {
      if (landmark_ids.count(b) && !kept.count(b) && seen.insert(b).second) out.push_back(b);
    }
  }
  return out;
}

void Estimator::Impl::removeLandmark(double* block) {
  const auto id = landmark_ids.find(block);
  if (id == landmark_ids.end()) return;
  landmarks.erase(id->second);
  landmark_ids.erase(id);
}

}  // namespace mvis
