// The sliding window: the Ceres problem, the window states in time order, and the poses that
// have left it. Private to src/core/estimator.
//
// Owns: the problem (every parameter and residual block of the estimator lives in it; the parts
// that own calibration, auxiliary states or landmarks add theirs through problem()), the states
// and their residual records, the trajectory of states that have left. Asks nothing of the other
// parts. Factors are added through addRecord with the state they leave with.
#pragma once

#include <ceres/ceres.h>

#include <deque>
#include <memory>
#include <set>
#include <vector>

#include "window_state.h"

namespace mvis {
namespace estimator_internal {

class Window {
 public:
  explicit Window(const EstimatorOptions& options);

  // A new, empty problem without states (everything in the old one is dropped).
  void reset();
  ceres::Problem* problem() { return problem_.get(); }

  std::size_t size() const { return states_.size(); }
  bool empty() const { return states_.empty(); }
  State& state(std::size_t k) { return *states_[k]; }
  State& newest() { return *states_.back(); }
  const State& newest() const { return *states_.back(); }
  State& oldest() { return *states_.front(); }
  const State& oldest() const { return *states_.front(); }
  TimeNs newestTime() const { return states_.back()->t; }
  // The states in time order (read only: states enter with push and leave with removeOldest).
  const std::deque<std::unique_ptr<State>>& states() const { return states_; }

  // Appends a state and adds its pose and speed-bias blocks.
  void push(std::unique_ptr<State> state);
  // Adds a residual block, recorded with the state it is marginalized with (`inertial`: the
  // inertial sensor whose readings it holds, if any; `corners`: the tag corners it holds).
  void addRecord(State* owner, ceres::CostFunction* cost, ceres::LossFunction* loss,
                 std::vector<double*> blocks, int inertial = -1, int corners = 0);
  // Solves the problem: at most `iterations`, `max_time_s` seconds (`callback`, if given,
  // called after every iteration; *converged set to whether Ceres's tests were met).
  SolveSummary solve(int iterations, double max_time_s,
                     ceres::IterationCallback* callback = nullptr, bool* converged = nullptr);
  // States, frames and corners in the window (a frame's corners moved to the oldest state with
  // a leaving tag, moveToOldest, count once).
  SolveSummary summary() const;
  // Removes the oldest state: its residual blocks in their recorded order (Ceres's own removal
  // of a parameter block's dependents walks a hash set, whose order by pointer values would make
  // results differ from run to run), then the `leaving` parameter blocks; its estimate joins
  // past().
  void removeOldest(const std::vector<double*>& leaving);
  // Moves every later state's residual records that touch one of `blocks` to the oldest state's
  // (in time and record order): they are marginalized and removed with it.
  void moveToOldest(const std::set<const double*>& blocks);
  const std::vector<EstimatorState>& past() const { return past_; }

 private:
  static constexpr double kFirstTrustRadius = 1e4, kLargestStartRadius = 1e8;
  const EstimatorOptions& options_;
  std::unique_ptr<ceres::Problem> problem_;
  std::deque<std::unique_ptr<State>> states_;
  std::vector<EstimatorState> past_;
  PoseManifold pose_manifold_;
  double trust_radius_ = kFirstTrustRadius;  // where the next solve's LM starts (solve())
};

}  // namespace estimator_internal
}  // namespace mvis
