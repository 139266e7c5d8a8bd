#include "window_prior.h"

#include <algorithm>
#include <set>

namespace mvis {
namespace estimator_internal {

StatusOr<std::unique_ptr<MarginalizationFactor>> WindowPrior::marginalize(
    const std::vector<ResidualRecord>& residuals, const std::vector<double*>& leaving,
    const ManifoldOf& manifold_of, const std::map<const double*, Eigen::MatrixXd>& uninformative,
    const std::set<const double*>& fixed, const std::set<const double*>& alone, bool semidefinite,
    bool rows) const {
  Marginalizer m;
  if (semidefinite) m.allowSemidefinite();
  if (!rows) m.informationOnly();
  for (const double* block : fixed) m.setFixed(block);
  for (const double* block : alone) m.eliminateAlone(block);
  for (const auto& r : residuals) {
    for (double* block : r.blocks) m.setManifold(block, manifold_of(block));
    m.addResidual(r.cost, r.loss, r.blocks, true);
  }
  if (whole_) {
    for (double* block : whole_->parameterBlocks()) m.setManifold(block, manifold_of(block));
    m.addPrior(whole_.get());
  }
  for (const auto& [block, held] : uninformative) m.setUninformative(block, held);
  return m.marginalize(std::set<const double*>(leaving.begin(), leaving.end()));
}

Status WindowPrior::release(ceres::Problem* problem, const std::set<const double*>& blocks,
                            const ManifoldOf& manifold_of) {
  if (!whole_) return Status::Ok();
  const std::vector<double*> held = whole_->parameterBlocks();
  if (std::none_of(held.begin(), held.end(), [&](double* b) { return blocks.count(b) > 0; })) {
    return Status::Ok();
  }
  Marginalizer m;
  m.allowSemidefinite();
  if (whole_->J0().rows() == 0) m.informationOnly();
  for (double* block : held) m.setManifold(block, manifold_of(block));
  m.addPrior(whole_.get());
  auto made = m.marginalize(blocks);
  if (!made.ok()) return made.status();
  removeFrom(problem);
  install(problem, std::move(made).value());
  return Status::Ok();
}

void WindowPrior::removeFrom(ceres::Problem* problem) {
  for (const auto& r : rows_) problem->RemoveResidualBlock(r.id);
  clear();
}

void WindowPrior::install(ceres::Problem* problem, std::unique_ptr<MarginalizationFactor> prior) {
  if (prior->J0().rows() == 0) {  // information only
    whole_ = std::move(prior);
    return;
  }
  for (auto& rows : prior->splitRows()) {
    ResidualRecord r;
    r.blocks = rows->parameterBlocks();
    r.cost = rows.get();
    r.id = problem->AddResidualBlock(rows.release(), nullptr, r.blocks);
    rows_.push_back(std::move(r));
  }
  whole_ = std::move(prior);
}

void WindowPrior::clear() {
  rows_.clear();
  whole_.reset();
}

}  // namespace estimator_internal
}  // namespace mvis
