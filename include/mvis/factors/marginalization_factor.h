// Marginalization prior: what the states leaving the window knew, as a Ceres cost.
//
// The residual blocks touching the dropped parameter blocks x_m are linearized at the current
// estimate x0 in the tangent spaces of their blocks (robust losses by their first-order weight
// sqrt(rho'(s))): r(x0 + dx) ~ r + J dx. With H = J^T J and b = J^T r split into dropped (m) and
// kept (k) parts, the Schur complement
//   H* = H_kk - H_km H_mm^-1 H_mk,   b* = b_k - H_km H_mm^-1 b_m
// is the information the dropped blocks leave on the kept ones. The blocks' information spans
// many orders of magnitude (biases ~1e10, gravity ~1), so H_mm^-1 and the factorization of H*
// work on the Jacobi-scaled matrix S = D^-1/2 A D^-1/2 (D = diag(A)). H_mm^-1 is applied through
// the Cholesky factor of its scaled matrix, D_m^-1/2 H_mm D_m^-1/2 = L_m L_m^T, when that is
// clearly positive definite: W = L_m^-1 D_m^-1/2 H_mk, w = L_m^-1 D_m^-1/2 b_m, H* = H_kk - W^T W
// (a symmetric rank update), b* = b_k - W^T w; otherwise through its pseudo-inverse (scaled
// eigenvalues above eps, as for J0 below). The prior is the cost ||r0 + J0 dx_k||^2,
// dx_k = Minus(x_k, x0_k) per kept block (the manifold's Minus, Euclidean difference otherwise),
// with
//   S = L L^T (Cholesky, when every pivot exceeds 1e-10: clearly positive definite):
//     J0 = L^T D^1/2,   r0 = L^-1 D^-1/2 b*;
//   S = V diag(l) V^T otherwise (eigen-decomposition; scaled eigenvalues l <= eps count as zero):
//     J0 = diag(sqrt(l)) V^T D^1/2,   r0 = diag(1 / sqrt(l)) V^T D^-1/2 b*.
// Both give J0^T J0 = H* and J0^T r0 = b*; Cholesky costs about a twentieth as much. Its
// Jacobian is J0 times each block's MinusJacobian, first-estimate by construction: it stays at
// the linearization point x0.
//
// The Cholesky J0 is upper triangular: the rows of kept block i touch only blocks i, i+1, ...,
// so splitRows() hands Ceres one residual block per kept block, whose J^T J costs about a third
// of the dense square's. That matters once the prior spans many auxiliary sensors: it is dense
// over every calibration block and the next state.
//
// Uninformative directions: residuals added as `projected` must not inform the tangent
// directions D (orthonormal columns) set for some blocks. With U the columns D placed at their
// blocks' rows, the projected residuals' own (Hp, gp) lose what U carries by a Schur complement
// on the coordinates along U:
//   Hp' = Hp - Hp U (U^T Hp U)^+ U^T Hp,   gp' = gp - Hp U (U^T Hp U)^+ U^T gp
// (Hp' U = 0: no information along U; and the share of the residual that U explains goes with
// it rather than into other blocks). The others add unchanged. The estimator uses this for
// calibration directions the recent motion does not make observable (observability.h) while the
// cameras' intrinsics are estimated, and for the window check's weak directions
// (ObservabilityMonitor::heldDirections), so that what leaves the window adds no information
// along them, which only linearization noise would. Marginalized as unknown, U takes along what
// the residuals tell about everything correlated with it; the IMU intrinsics' held directions,
// which the cameras' tilt is tied to, are therefore kept instead, as consider parameters
// (src/core/estimator/held_covariance.cpp).
#pragma once

#include <ceres/cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/manifold.h>

#include <Eigen/Core>
#include <map>
#include <memory>
#include <set>
#include <vector>

#include "mvis/common/status.h"

namespace mvis {

class MarginalizationFactor;

// Collects the residual blocks around the dropped states, then makes the prior.
class Marginalizer {
 public:
  // `manifold` of a block (nullptr: Euclidean); not owned, must outlive the prior.
  void setManifold(const double* block, const ceres::Manifold* manifold);
  // Tangent directions of `block` (orthonormal columns) that projected residuals must not inform
  // (see above: marginalized as unknown).
  void setUninformative(const double* block, Eigen::MatrixXd directions);
  // A block held constant for the whole run (Ceres never varies it): left out, i.e. conditioned
  // on. The kept blocks' information is the same as with it kept and its rows and columns
  // dropped from the result (the Schur complement's [kept, kept] block does not depend on
  // whether a constant block was carried along); its Jacobian is never asked for.
  void setFixed(const double* block) { fixed_.insert(block); }
  // A dropped block coupled to few others (a landmark that a few frames see and no earlier prior
  // holds): eliminated on its own before the rest, H -= H_:b H_bb^+ H_b: over the rows and
  // columns of the blocks it couples to only. The same Schur complement as in one piece (in exact
  // arithmetic), at a cost linear in the number of such blocks instead of cubic.
  void eliminateAlone(const double* block) { alone_.insert(block); }
  // A Schur complement that is not clearly positive definite is factored by LDL^T with its
  // vanishing pivots skipped (a third of the eigen-decomposition's cost, same triangular shape as
  // Cholesky's) rather than by the eigen-decomposition, unless that meets round-off. The
  // estimator's landmarks that leave with their observations make every prior so: each later
  // state they touch enters it with what its frames tell of its pose, velocity and biases
  // together, the rest of that state in the window's inertial factors.
  void allowSemidefinite() { semidefinite_ = true; }
  // The prior as its information (H*, b*) only, without rows (J0 and r0 empty): for one that only
  // the next marginalization reads (addPrior), never a solve. Saves factoring it.
  void informationOnly() { information_only_ = true; }
  // A residual block touching at least one dropped block. Neither pointer is owned; both are
  // only used inside marginalize().
  void addResidual(const ceres::CostFunction* cost, const ceres::LossFunction* loss,
                   std::vector<double*> blocks, bool projected = false);
  // An earlier prior (as marginalize() made it, not split), added through the information it
  // stores: H += M^T H* M, g += M^T (g* + H* dx), with dx = Minus(x, x0) and M per block its
  // MinusJacobian at x times this marginalizer's PlusJacobian there (as its own Evaluate has it;
  // the identity for the manifolds here). The same as adding its rows as a residual, without the
  // cube of its size that their products cost. Not owned; only used inside marginalize().
  void addPrior(const MarginalizationFactor* prior);
  // Linearizes everything added and makes the prior on every block that is not in `drop`.
  // Fails if evaluating a residual fails or nothing is kept.
  StatusOr<std::unique_ptr<MarginalizationFactor>> marginalize(const std::set<const double*>& drop,
                                                               double eps = 1e-8) const;

 private:
  struct Residual {
    const ceres::CostFunction* cost;
    const ceres::LossFunction* loss;
    std::vector<double*> blocks;
    bool projected;
  };
  struct Entry {
    double* address;
    int ambient, tangent, offset;
    const ceres::Manifold* manifold;
  };
  // The Schur complement on the kept blocks (entries after the first `dropped`).
  struct Reduced {
    std::vector<Entry> entries;
    std::size_t dropped = 0;
    Eigen::MatrixXd H;
    Eigen::VectorXd g;
  };
  StatusOr<Reduced> reduce(const std::set<const double*>& drop, double eps) const;
  // Eliminates the dropped blocks in alone_ one at a time from (H, g) and removes their rows,
  // columns and entries (offsets renumbered, `dropped` counting the rest).
  void eliminateAlone(Reduced* out, Eigen::MatrixXd* H, Eigen::VectorXd* g, double eps) const;

  std::vector<Residual> residuals_;
  std::vector<const MarginalizationFactor*> priors_;
  std::map<const double*, const ceres::Manifold*> manifolds_;
  std::map<const double*, Eigen::MatrixXd> uninformative_;
  std::set<const double*> fixed_;
  std::set<const double*> alone_;
  bool semidefinite_ = false;
  bool information_only_ = false;
};

class MarginalizationFactor final : public ceres::CostFunction {
 public:
  struct Block {
    double* address = nullptr;                  // the kept parameter block
    const ceres::Manifold* manifold = nullptr;  // nullptr: Euclidean
    int ambient = 0, tangent = 0;
    std::vector<double> x0;  // linearization point
  };

  MarginalizationFactor(std::vector<Block> blocks, Eigen::MatrixXd J0, Eigen::VectorXd r0);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  // Parameter blocks in the order Ceres must be given them.
  std::vector<double*> parameterBlocks() const;
  // The same cost as residual blocks that touch fewer parameter blocks: rows are grouped by the
  // first block they touch (their first nonzero column), each group a factor on that block and
  // the ones after it. Their costs sum to this one's. A dense J0 gives one factor.
  std::vector<std::unique_ptr<MarginalizationFactor>> splitRows() const;
  const std::vector<Block>& blocks() const { return blocks_; }
  const Eigen::MatrixXd& J0() const { return J0_; }
  const Eigen::VectorXd& r0() const { return r0_; }
  // Its information at x0, H* = J0^T J0 and g* = J0^T r0 (tangent coordinates in block order),
  // kept by Marginalizer::marginalize for Marginalizer::addPrior; empty otherwise.
  const Eigen::MatrixXd& information() const { return H_; }
  const Eigen::VectorXd& gradient() const { return g_; }
  void setInformation(Eigen::MatrixXd H, Eigen::VectorXd g) {
    H_ = std::move(H);
    g_ = std::move(g);
  }

 private:
  std::vector<Block> blocks_;
  Eigen::MatrixXd J0_;
  Eigen::VectorXd r0_;
  Eigen::MatrixXd H_;
  Eigen::VectorXd g_;
};

}  // namespace mvis
