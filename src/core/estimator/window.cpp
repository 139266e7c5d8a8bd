#include "window.h"

#include <omp.h>

#include <algorithm>

namespace mvis {
namespace estimator_internal {

Window::Window(const EstimatorOptions& options) : options_(options) { reset(); }

void Window::reset() {
  ceres::Problem::Options po;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.enable_fast_removal = true;
  problem_ = std::make_unique<ceres::Problem>(po);
  states_.clear();
  trust_radius_ = kFirstTrustRadius;
}

void Window::push(std::unique_ptr<State> state) {
  problem_->AddParameterBlock(state->pose, kPoseSize, &pose_manifold_);
  problem_->AddParameterBlock(state->speed_bias, kSpeedBiasSize);
  states_.push_back(std::move(state));
}

void Window::addRecord(State* owner, ceres::CostFunction* cost, ceres::LossFunction* loss,
                       std::vector<double*> blocks, int inertial, int corners) {
  ResidualRecord r;
  r.inertial = inertial;
  r.corners = corners;
  r.id = problem_->AddResidualBlock(cost, loss, blocks);
  r.cost = cost;
  r.loss = loss;
  r.blocks = std::move(blocks);
  owner->residuals.push_back(std::move(r));
}

SolveSummary Window::solve(int iterations, double max_time_s, ceres::IterationCallback* callback,
                           bool* converged) {
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  // Levenberg-Marquardt starts from the radius the last solve ended with (1e4, Ceres's default,
  // after a reset; at most 1e8). Started at 1e4 every time, LM damped the weakly observed
  // directions (gravity, lever arms: eigenvalues far below their diagonal entries) afresh in
  // each solve, which crept towards its minimum over ~6 iterations of relative decrease ~1 and
  // stopped short of it (0.03 sigma on the VI-Rig's camera translations). Carried over, a
  // window that keeps matching its linear model is solved in ~2 Gauss-Newton-like steps, while
  // the first solves from a rough calibration, and any that meet steps raising the cost, stay
  // damped (starting at 1e6 or more every time, wrong tag ids pulled the calibration off).
  o.initial_trust_region_radius = trust_radius_;
  o.max_num_iterations = iterations;
  o.max_solver_time_in_seconds = max_time_s;
  o.num_threads = options_.threads;
  // SuiteSparse's CHOLMOD (Ceres's sparse Cholesky) runs parts of its supernodal factorization
  // on a number of OpenMP threads fixed when it is built (CHOLMOD_OMP_NUM_THREADS, 4 by default;
  // seen here: three besides the caller, whatever num_threads or omp_set_num_threads say). Held
  // to one core they took turns with the solve: a 100-tag no-board run spent a tenth of its time
  // in them and was 20-27% slower. Dynamic adjustment lets OpenMP give a region only the cores that
  // are free (affinity and load), one here; the factorization's result does not depend on it (the
  // runs' outputs are byte-identical). Set per solving thread, as OpenMP keeps it.
  omp_set_dynamic(1);
  o.logging_type = ceres::SILENT;
  if (callback != nullptr) o.callbacks.push_back(callback);
  ceres::Solver::Summary s;
  ceres::Solve(o, problem_.get(), &s);
  if (!s.iterations.empty()) {
    trust_radius_ =
        std::clamp(s.iterations.back().trust_region_radius, kFirstTrustRadius, kLargestStartRadius);
  }
  if (converged != nullptr) *converged = s.termination_type == ceres::CONVERGENCE;
  SolveSummary out = summary();
  out.iterations = static_cast<int>(s.iterations.size());
  out.solve_s = s.total_time_in_seconds;
  out.cost = s.final_cost;
  out.usable = s.IsSolutionUsable();
  return out;
}

SolveSummary Window::summary() const {
  SolveSummary out;
  out.states = static_cast<int>(states_.size());
  for (const auto& st : states_) {
    out.frames += st->frames;
    for (const ResidualRecord& r : st->residuals) out.corners += r.corners;
  }
  return out;
}

void Window::moveToOldest(const std::set<const double*>& blocks) {
  if (blocks.empty()) return;
  State& oldest = *states_.front();
  for (std::size_t k = 1; k < states_.size(); ++k) {
    std::vector<ResidualRecord>& records = states_[k]->residuals;
    std::vector<ResidualRecord> stay;
    for (auto& r : records) {
      const bool touches = std::any_of(r.blocks.begin(), r.blocks.end(),
                                       [&](const double* b) { return blocks.count(b) > 0; });
      (touches ? oldest.residuals : stay).push_back(std::move(r));
    }
    records = std::move(stay);
  }
}

void Window::removeOldest(const std::vector<double*>& leaving) {
  const State& oldest = *states_.front();
  for (const auto& r : oldest.residuals) problem_->RemoveResidualBlock(r.id);
  for (double* block : leaving) problem_->RemoveParameterBlock(block);
  past_.push_back(oldest.toEstimate());
  states_.pop_front();
}

}  // namespace estimator_internal
}  // namespace mvis
