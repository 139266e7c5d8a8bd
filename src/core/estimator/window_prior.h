// The marginalization prior of the window (MarginalizationFactor): made when the oldest state
// leaves, from the factors leaving with it and the previous prior, and kept in the problem as one
// residual block per row group. Private to src/core/estimator.
//
// Owns: the prior, as made and as its split rows in the problem. Asks of the others, through its
// caller: the leaving state's residual records, the blocks that leave, each block's own manifold
// (also while it is held) and the directions the leaving measurements must not inform (the
// observability monitor's).
#pragma once

#include <ceres/ceres.h>

#include <functional>
#include <map>
#include <memory>
#include <set>
#include <utility>
#include <vector>

#include "mvis/common/status.h"
#include "mvis/factors/marginalization_factor.h"
#include "window_state.h"

namespace mvis {
namespace estimator_internal {

class WindowPrior {
 public:
  using ManifoldOf = std::function<const ceres::Manifold*(const double* block)>;

  // The prior after marginalizing `leaving` out of `residuals` and the current prior; nothing
  // changes in the problem yet. Blocks in `fixed` (constant for the whole run) are conditioned
  // on, as the solves do. The measurements add nothing along `uninformative` (per block,
  // tangent directions as columns: marginalization_factor.h); the old prior keeps what earlier
  // motion told. The leaving blocks
  // in `alone` couple to few others and are eliminated one at a time, and a semi-definite result
  // is factored as such with `semidefinite` (Marginalizer). Without `rows` it is made as its
  // information only, for the next marginalization alone (install adds nothing to the problem).
  StatusOr<std::unique_ptr<MarginalizationFactor>> marginalize(
      const std::vector<ResidualRecord>& residuals, const std::vector<double*>& leaving,
      const ManifoldOf& manifold_of, const std::map<const double*, Eigen::MatrixXd>& uninformative,
      const std::set<const double*>& fixed, const std::set<const double*>& alone = {},
      bool semidefinite = false, bool rows = true) const;
  // What the prior knows of `blocks` is let go (their sensor moved: what earlier measurements
  // told of them was of the old mount): they are marginalized out of it, so that it keeps what
  // those measurements told of the rest through them, and the prior in the problem is replaced.
  // Nothing changes when the prior does not hold them.
  Status release(ceres::Problem* problem, const std::set<const double*>& blocks,
                 const ManifoldOf& manifold_of);
  // Removes the current prior's rows from the problem and forgets it.
  void removeFrom(ceres::Problem* problem);
  // Adds a new prior to the problem, one residual block per row group (Ceres's J^T J of the dense
  // prior is its largest cost with many auxiliary sensors).
  void install(ceres::Problem* problem, std::unique_ptr<MarginalizationFactor> prior);
  // Forgets the prior without touching a problem (when the problem itself is replaced).
  void clear();

 private:
  std::vector<ResidualRecord> rows_;
  // The prior as made, before its rows were split: the next marginalization adds it through the
  // information it keeps (Marginalizer::addPrior).
  std::unique_ptr<MarginalizationFactor> whole_;
};

}  // namespace estimator_internal
}  // namespace mvis
