// What the window (its measurements and its marginalization prior) tells about chosen parameter
// blocks, every other variable block unknown: the Schur complement of the Gauss-Newton
// information onto those blocks,
//   J = [J_x J_c] over every residual but the chosen blocks' own priors (residuals on chosen
//   blocks only: the configured priors, a restart's prior from a trusted covariance),
//   H = J^T J,   Lambda_c = H_cc - H_cx H_xx^-1 H_xc,
// in the blocks' tangent coordinates (their manifolds as set in the problem), stacked in the
// order given. Loss functions are applied as Ceres applies them. H_xx is factored sparse
// (simplicial LDL^T) with a relative damping of 1e-10 of its largest diagonal, which only
// touches gauge directions (the world's yaw and position, which no calibration quantity sees).
// Used by the degeneracy check (observability_window.cpp); a public helper of the core.
#pragma once

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <vector>

#include "mvis/common/status.h"

namespace mvis {

// Every chosen block must be in the problem and variable; the other variable blocks are
// marginalized, the constant ones are as known.
StatusOr<Eigen::MatrixXd> windowInformation(ceres::Problem* problem,
                                            const std::vector<double*>& chosen);

}  // namespace mvis
