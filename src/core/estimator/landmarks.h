// Tag corners as landmark states when the rig has no board (report Eq. 11). Before the window
// starts, one tag per camera (its largest) gives that camera's poses at unit side; then every tag
// starts from one view, placed with the camera pose at that frame, and leaves the window
// (marginalized into the prior) with the last state that sees it. At most `carried` tags are
// carried that way (the prior is dense over them), each kept a square of unknown size
// (TagLandmarkManifold: 7 values instead of 12); a tag beyond them is a landmark of the window
// alone: it leaves with the oldest state that sees it, together with every observation of it in
// the window (they tell the states and the calibration what they tell through it, as a
// multi-state constraint), and starts again from its next view. Private to src/core/estimator.
//
// Owns: the landmark blocks by tag id, each camera's pose tag, the tag side the initialization
// found. Asks of the others, through its caller: the problem to add a new landmark to, the
// camera with its current intrinsics, and the camera's pose at a frame.
#pragma once

#include <ceres/ceres.h>

#include <array>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <vector>

#include "mvis/factors/tag_landmark_manifold.h"
#include "mvis/factors/tag_reprojection_factor.h"
#include "window_state.h"

namespace mvis {
namespace estimator_internal {

class Landmarks {
 public:
  // carried: the most tags carried across marginalizations (0: every tag).
  Landmarks(std::size_t cameras, int carried) : pose_tag_(cameras, -1), carried_limit_(carried) {}

  // The camera's pose on its pose tag (unit side) in the frame, choosing a new pose tag (the
  // largest in the frame) when it is not seen; *restarted when it did (rotations on different
  // tags do not compare: the caller starts that camera's history over).
  bool poseOnTag(const Camera& camera, const TagFrame& frame, SE3* T_T_C, bool* restarted);
  int poseTag(std::size_t c) const { return pose_tag_[c]; }
  int count() const { return static_cast<int>(landmarks_.size()); }
  int carriedCount() const { return carried_count_; }
  void setInitialSide(double side_m) { initial_side_ = side_m; }

  // The tag's landmark block, made if it has none yet: PnP on the tag at the mean side, placed
  // with the camera pose T_G_C() at the frame (a window's own landmark starting again: where it
  // left, as a starting point only). Null if that fails.
  double* landmarkFor(ceres::Problem* problem, const Camera& camera, const TagFrame& frame,
                      const TagObservation& tag, const std::function<SE3()>& T_G_C);
  // Landmarks that leave with the oldest window state: those only its records observe, and the
  // window's own (not carried) that it observes.
  std::vector<double*> leaving(const std::deque<std::unique_ptr<State>>& states) const;
  // Whether the landmark is carried across marginalizations.
  bool carried(const double* block) const;
  // Whether the tag's landmark is carried, or would be if it were made now.
  bool wouldCarry(int id) const;
  // Forgets a landmark (after its block left the problem).
  void remove(double* block);
  // The carried landmarks' corners in the world frame, by tag id (the window's own tags are
  // placed by the window's few states alone: centimetres off, so not reported).
  std::map<int, std::array<Eigen::Vector3d, 4>> corners() const;
  // Forgets every landmark (the problem is replaced); resetPoseTags also every pose tag.
  void clear();
  void resetPoseTags();

 private:
  struct TagLandmark {
    double x[kTagLandmarkSize];  // [p_G,0 .. p_G,3] (TagReprojectionFactor::useLandmarkBlock)
    bool carried = true;
  };
  // Whether a new landmark would be carried now.
  bool roomToCarry() const { return carried_limit_ <= 0 || carried_count_ < carried_limit_; }
  // Adds the landmark's block to the problem, carried if there is room.
  double* add(ceres::Problem* problem, int id, std::unique_ptr<TagLandmark> landmark);
  // The mean side of the landmarks' tags [m] (the guess for a new tag's size).
  double meanTagSide() const;

  TagLandmarkManifold square_;  // every landmark block's: a square of unknown size
  std::map<int, std::unique_ptr<TagLandmark>> landmarks_;
  // Where the window's own landmarks that left were, by tag id (until they start again).
  std::map<int, TagLandmark> left_;
  std::map<const double*, int> ids_;
  std::vector<int> pose_tag_;  // per camera, -1: none yet
  double initial_side_ = 1.0;  // [m] from the initial alignment
  int carried_limit_ = 0;      // 0: every tag carried
  int carried_count_ = 0;
};

}  // namespace estimator_internal
}  // namespace mvis
