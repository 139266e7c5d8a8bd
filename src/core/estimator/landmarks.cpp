#include "landmarks.h"

#include <algorithm>
#include <set>

#include "mvis/estimator/initialization.h"

namespace mvis {
namespace estimator_internal {
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

bool Landmarks::poseOnTag(const Camera& camera, const TagFrame& frame, SE3* T_T_C,
                          bool* restarted) {
  const std::size_t c = frame.camera;
  *restarted = false;
  if (pose_tag_[c] >= 0 && tagPose(camera, frame, pose_tag_[c], 1.0, T_T_C)) return true;
  const TagObservation* best = nullptr;
  for (const auto& tag : frame.tags) {
    if (best == nullptr || imageArea(tag) > imageArea(*best)) best = &tag;
  }
  if (best == nullptr) return false;
  if (pose_tag_[c] != best->tag_id) {
    // Rotations on different tags do not compare (tags need not be parallel): start over.
    pose_tag_[c] = best->tag_id;
    *restarted = true;
  }
  return tagPose(camera, frame, pose_tag_[c], 1.0, T_T_C);
}

double Landmarks::meanTagSide() const {
  // The carried tags' when there are any: they are squares placed by every view since they came,
  // while the window's own tags are free corners placed by a few states (their sides 86-116 mm
  // on the test's 88 mm board).
  double sum = 0.0;
  int n = 0;
  for (const auto& [id, landmark] : landmarks_) {
    if (carried_count_ > 0 && !landmark->carried) continue;
    for (int k = 0; k < 4; ++k) {
      sum +=
          (Eigen::Vector3d(landmark->x + 3 * k) - Eigen::Vector3d(landmark->x + 3 * ((k + 1) % 4)))
              .norm();
      ++n;
    }
  }
  return n > 0 ? sum / n : initial_side_;
}

double* Landmarks::landmarkFor(ceres::Problem* problem, const Camera& camera, const TagFrame& frame,
                               const TagObservation& tag, const std::function<SE3()>& T_G_C_at) {
  const auto found = landmarks_.find(tag.tag_id);
  if (found != landmarks_.end()) return found->second->x;
  const auto left = left_.find(tag.tag_id);
  if (left != left_.end()) {
    auto landmark = std::make_unique<TagLandmark>(left->second);
    left_.erase(left);
    return add(problem, tag.tag_id, std::move(landmark));
  }
  const SE3 T_G_C = T_G_C_at();
  // One view of a tag tells its size only through the others': tags of one size are assumed
  // (another size starts at the wrong depth, which the following views correct).
  const double side = meanTagSide();
  SE3 T_T_C;
  if (!tagPose(camera, frame, tag.tag_id, side, &T_T_C)) return nullptr;
  const SE3 T_G_T = T_G_C * T_T_C.inverse();
  auto landmark = std::make_unique<TagLandmark>();
  for (int i = 0; i < 4; ++i) {
    Eigen::Map<Eigen::Vector3d>(landmark->x + 3 * i) = T_G_T * tagCorner(i, side);
  }
  if (!Eigen::Map<const Eigen::Matrix<double, kTagLandmarkSize, 1>>(landmark->x).allFinite()) {
    return nullptr;
  }
  return add(problem, tag.tag_id, std::move(landmark));
}

double* Landmarks::add(ceres::Problem* problem, int id, std::unique_ptr<TagLandmark> landmark) {
  landmark->carried = roomToCarry();
  if (landmark->carried) {
    ++carried_count_;
    // Made a square (a window's own tag starting again is carried once there is room: its
    // corners were free).
    const double zero[7] = {0, 0, 0, 0, 0, 0, 0};
    double square[kTagLandmarkSize];
    if (square_.Plus(landmark->x, zero, square)) {
      std::copy(square, square + kTagLandmarkSize, landmark->x);
    }
    problem->AddParameterBlock(landmark->x, kTagLandmarkSize, &square_);
  } else {
    problem->AddParameterBlock(landmark->x, kTagLandmarkSize);
  }
  double* block = landmark->x;
  ids_[block] = id;
  landmarks_[id] = std::move(landmark);
  return block;
}

std::vector<double*> Landmarks::leaving(const std::deque<std::unique_ptr<State>>& states) const {
  if (landmarks_.empty()) return {};
  const State& oldest = *states.front();
  std::set<const double*> kept;
  for (const auto& s : states) {
    if (s.get() == &oldest) continue;
    for (const auto& r : s->residuals) {
      for (double* b : r.blocks) {
        if (ids_.count(b)) kept.insert(b);
      }
    }
  }
  std::vector<double*> out;
  std::set<const double*> seen;
  for (const auto& r : oldest.residuals) {
    for (double* b : r.blocks) {
      if (ids_.count(b) && (!kept.count(b) || !carried(b)) && seen.insert(b).second) {
        out.push_back(b);
      }
    }
  }
  return out;
}

bool Landmarks::carried(const double* block) const {
  const auto id = ids_.find(block);
  return id != ids_.end() && landmarks_.at(id->second)->carried;
}

bool Landmarks::wouldCarry(int id) const {
  const auto found = landmarks_.find(id);
  return found != landmarks_.end() ? found->second->carried : roomToCarry();
}

void Landmarks::remove(double* block) {
  const auto id = ids_.find(block);
  if (id == ids_.end()) return;
  const TagLandmark& landmark = *landmarks_.at(id->second);
  if (landmark.carried) {
    --carried_count_;
  } else {
    left_[id->second] = landmark;
  }
  landmarks_.erase(id->second);
  ids_.erase(id);
}

std::map<int, std::array<Eigen::Vector3d, 4>> Landmarks::corners() const {
  std::map<int, std::array<Eigen::Vector3d, 4>> out;
  for (const auto& [id, landmark] : landmarks_) {
    if (!landmark->carried) continue;
    for (int k = 0; k < 4; ++k) out[id][k] = Eigen::Vector3d(landmark->x + 3 * k);
  }
  return out;
}

void Landmarks::clear() {
  landmarks_.clear();
  left_.clear();
  carried_count_ = 0;
  ids_.clear();
}

void Landmarks::resetPoseTags() { std::fill(pose_tag_.begin(), pose_tag_.end(), -1); }

}  // namespace estimator_internal
}  // namespace mvis
