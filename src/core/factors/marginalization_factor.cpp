#include "mvis/factors/marginalization_factor.h"

#include <algorithm>
#include <cmath>

#include "scaled_factorization.h"

namespace mvis {
namespace {

using scaled_factorization::inverseOrZero;
using scaled_factorization::pseudoInverse;
using scaled_factorization::ScaledCholesky;
using scaled_factorization::scaledCholesky;
using scaled_factorization::ScaledEigen;
using scaled_factorization::scaledEigen;
using scaled_factorization::scaledSemidefiniteFactor;

int tangentSize(const ceres::Manifold* manifold, int ambient) {
  return manifold != nullptr ? manifold->TangentSize() : ambient;
}

// The prior with rows J0, r0 and the information they keep of Hs and gs (J0^T J0, J0^T r0: the
// directions a factorization dropped are not in J0).
std::unique_ptr<MarginalizationFactor> withKeptInformation(
    std::vector<MarginalizationFactor::Block> kept, Eigen::MatrixXd J0, Eigen::VectorXd r0) {
  Eigen::MatrixXd H0 = J0.transpose() * J0;
  Eigen::VectorXd g0 = J0.transpose() * r0;
  auto made =
      std::make_unique<MarginalizationFactor>(std::move(kept), std::move(J0), std::move(r0));
  made->setInformation(std::move(H0), std::move(g0));
  return made;
}

}  // namespace

void Marginalizer::setManifold(const double* block, const ceres::Manifold* manifold) {
  manifolds_[block] = manifold;
}

void Marginalizer::setUninformative(const double* block, Eigen::MatrixXd directions) {
  uninformative_[block] = std::move(directions);
}

void Marginalizer::addResidual(const ceres::CostFunction* cost, const ceres::LossFunction* loss,
                               std::vector<double*> blocks, bool projected) {
  residuals_.push_back({cost, loss, std::move(blocks), projected});
}

void Marginalizer::addPrior(const MarginalizationFactor* prior) { priors_.push_back(prior); }

StatusOr<Marginalizer::Reduced> Marginalizer::reduce(const std::set<const double*>& drop,
                                                     double eps) const {
  // Every block once: dropped ones first, then kept ones, in order of first appearance.
  Reduced out;
  std::vector<Entry>& entries = out.entries;
  std::map<const double*, int> index;
  const auto enter = [&](int pass, double* address, int ambient) {
    const bool dropped = drop.count(address) > 0;
    if ((pass == 0) != dropped || index.count(address) || fixed_.count(address)) return;
    const auto m = manifolds_.find(address);
    const ceres::Manifold* manifold = m == manifolds_.end() ? nullptr : m->second;
    index[address] = static_cast<int>(entries.size());
    entries.push_back({address, ambient, tangentSize(manifold, ambient), 0, manifold});
  };
  for (int pass = 0; pass < 2; ++pass) {
    for (const auto& residual : residuals_) {
      const auto& sizes = residual.cost->parameter_block_sizes();
      for (std::size_t b = 0; b < residual.blocks.size(); ++b) {
        enter(pass, residual.blocks[b], sizes[b]);
      }
    }
    for (const MarginalizationFactor* prior : priors_) {
      for (const auto& b : prior->blocks()) enter(pass, b.address, b.ambient);
    }
    if (pass == 0) out.dropped = entries.size();
  }
  int n = 0, m = 0;
  for (auto& e : entries) {
    e.offset = n;
    n += e.tangent;
    if (drop.count(e.address)) m = n;
  }
  if (m == n) return Status::Error("marginalization keeps no parameter block");

  // H = sum J^T J and g = sum J^T r, accumulated block by block: a residual touches few blocks.
  // Projected residuals go to their own (Hp, gp) first.
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(n, n);
  Eigen::VectorXd g = Eigen::VectorXd::Zero(n);
  // Only needed when some directions are to be forgotten.
  const bool forgetting = !uninformative_.empty();
  Eigen::MatrixXd Hp = forgetting ? Eigen::MatrixXd::Zero(n, n) : Eigen::MatrixXd();
  Eigen::VectorXd gp = forgetting ? Eigen::VectorXd::Zero(n) : Eigen::VectorXd();
  bool any_projected = false;
  for (const auto& residual : residuals_) {
    const bool projected = residual.projected && forgetting;
    any_projected = any_projected || projected;
    Eigen::MatrixXd& Ha = projected ? Hp : H;
    Eigen::VectorXd& ga = projected ? gp : g;
    const int rows = residual.cost->num_residuals();
    const auto& sizes = residual.cost->parameter_block_sizes();
    Eigen::VectorXd r(rows);
    std::vector<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> J;
    std::vector<double*> jac_ptrs;
    bool any_variable = false;
    for (std::size_t b = 0; b < sizes.size(); ++b) {
      const bool fixed = fixed_.count(residual.blocks[b]) > 0;
      any_variable = any_variable || !fixed;
      J.emplace_back(fixed ? 0 : rows, fixed ? 0 : sizes[b]);
    }
    if (!any_variable) continue;
    for (auto& j : J) jac_ptrs.push_back(j.size() > 0 ? j.data() : nullptr);
    std::vector<const double*> params(residual.blocks.begin(), residual.blocks.end());
    if (!residual.cost->Evaluate(params.data(), r.data(), jac_ptrs.data())) {
      return Status::Error("a residual block failed to evaluate during marginalization");
    }
    double weight = 1.0;
    if (residual.loss != nullptr) {
      double rho[3];
      residual.loss->Evaluate(r.squaredNorm(), rho);
      weight = std::sqrt(std::max(rho[1], 0.0));
    }
    r *= weight;
    // The residual's tangent Jacobian over its variable blocks, side by side: one product for
    // its J^T J and J^T r, added block by block.
    std::vector<const Entry*> at;
    std::vector<std::size_t> of;
    int cols = 0;
    for (std::size_t b = 0; b < residual.blocks.size(); ++b) {
      if (jac_ptrs[b] == nullptr) continue;
      at.push_back(&entries[index.at(residual.blocks[b])]);
      of.push_back(b);
      cols += at.back()->tangent;
    }
    Eigen::MatrixXd Jt(rows, cols);
    int col = 0;
    for (std::size_t a = 0; a < at.size(); ++a) {
      const Entry& e = *at[a];
      if (e.manifold != nullptr) {
        Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> plus(e.ambient,
                                                                                    e.tangent);
        e.manifold->PlusJacobian(e.address, plus.data());
        Jt.middleCols(col, e.tangent).noalias() = weight * (J[of[a]] * plus);
      } else {
        Jt.middleCols(col, e.tangent) = weight * J[of[a]];
      }
      col += e.tangent;
    }
    const Eigen::MatrixXd JtJ = Jt.transpose() * Jt;
    const Eigen::VectorXd Jtr = Jt.transpose() * r;
    int ca = 0;
    for (std::size_t a = 0; a < at.size(); ++a) {
      const int ta = at[a]->tangent;
      ga.segment(at[a]->offset, ta) += Jtr.segment(ca, ta);
      int cb = ca;
      for (std::size_t b = a; b < at.size(); ++b) {
        const int tb = at[b]->tangent;
        Ha.block(at[a]->offset, at[b]->offset, ta, tb) += JtJ.block(ca, cb, ta, tb);
        if (b != a) Ha.block(at[b]->offset, at[a]->offset, tb, ta) += JtJ.block(cb, ca, tb, ta);
        cb += tb;
      }
      ca += ta;
    }
  }
  for (const MarginalizationFactor* prior : priors_) {
    // Per block: dx = Minus(x, x0) and M, the prior's MinusJacobian at x times this entry's
    // PlusJacobian, as the prior's own Evaluate and addResidual would have them.
    const auto& blocks = prior->blocks();
    const Eigen::MatrixXd& Hs = prior->information();
    const Eigen::VectorXd& gs = prior->gradient();
    std::vector<int> offsets;
    int total = 0;
    for (const auto& b : blocks) {
      offsets.push_back(total);
      total += b.tangent;
    }
    if (Hs.rows() != total || gs.size() != total) {
      return Status::Error("a prior without its information cannot be marginalized again");
    }
    Eigen::VectorXd dx(total);
    std::vector<Eigen::MatrixXd> M(blocks.size());
    std::vector<const Entry*> at(blocks.size(), nullptr);
    for (std::size_t i = 0; i < blocks.size(); ++i) {
      const auto& b = blocks[i];
      if (fixed_.count(b.address)) {  // conditioned on: constant, at x0 (dx = 0)
        dx.segment(offsets[i], b.tangent).setZero();
        continue;
      }
      const Entry& e = entries[index.at(b.address)];
      at[i] = &e;
      Eigen::MatrixXd minus = Eigen::MatrixXd::Identity(b.tangent, b.ambient);
      if (b.manifold != nullptr) {
        if (!b.manifold->Minus(b.address, b.x0.data(), dx.data() + offsets[i])) {
          return Status::Error("a prior's block failed its manifold's Minus");
        }
        Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> mj(b.tangent,
                                                                                  b.ambient);
        b.manifold->MinusJacobian(b.address, mj.data());
        minus = mj;
      } else {
        for (int j = 0; j < b.ambient; ++j) dx[offsets[i] + j] = b.address[j] - b.x0[j];
      }
      Eigen::MatrixXd plus = Eigen::MatrixXd::Identity(e.ambient, e.tangent);
      if (e.manifold != nullptr) {
        Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> pj(e.ambient,
                                                                                  e.tangent);
        e.manifold->PlusJacobian(e.address, pj.data());
        plus = pj;
      }
      M[i] = minus * plus;
    }
    const Eigen::VectorXd grad = gs + Hs * dx;
    // M is the identity for the manifolds here (MinusJacobian and PlusJacobian at one point), up
    // to round-off (within 2e-15 on the tag landmarks' and poses' manifolds: about half the
    // carried tags' products were not exactly it): then a block of H* is added as it is.
    std::vector<bool> identity(blocks.size());
    for (std::size_t i = 0; i < blocks.size(); ++i) {
      identity[i] =
          at[i] != nullptr && M[i].rows() == M[i].cols() &&
          (M[i] - Eigen::MatrixXd::Identity(M[i].rows(), M[i].cols())).cwiseAbs().maxCoeff() <=
              1e-12;
    }
    for (std::size_t i = 0; i < blocks.size(); ++i) {
      if (at[i] == nullptr) continue;
      const int ti = blocks[i].tangent;
      if (identity[i]) {
        g.segment(at[i]->offset, at[i]->tangent) += grad.segment(offsets[i], ti);
      } else {
        g.segment(at[i]->offset, at[i]->tangent).noalias() +=
            M[i].transpose() * grad.segment(offsets[i], ti);
      }
      for (std::size_t j = 0; j < blocks.size(); ++j) {
        if (at[j] == nullptr) continue;
        const auto Hij = Hs.block(offsets[i], offsets[j], ti, blocks[j].tangent);
        auto out = H.block(at[i]->offset, at[j]->offset, at[i]->tangent, at[j]->tangent);
        if (identity[i] && identity[j]) {
          out += Hij;
        } else {
          out.noalias() += M[i].transpose() * Hij * M[j];
        }
      }
    }
  }
  if (any_projected) {
    // The projected residuals forget the uninformative directions U: the components along U
    // are marginalized out of their (Hp, gp), which takes both the information along U and the
    // share of the residual that U explains, so that nothing else has to absorb it.
    // U's columns in the entries' order: the map's order is the blocks' addresses, and a
    // different column order rounds U^T Hp U's pseudo-inverse differently (the same bag gave
    // estimates differing in the 12th digit with its path spelled otherwise).
    int k = 0;
    for (const Entry& e : entries) {
      const auto u = uninformative_.find(e.address);
      if (u != uninformative_.end()) k += static_cast<int>(u->second.cols());
    }
    Eigen::MatrixXd U = Eigen::MatrixXd::Zero(n, k);
    int col = 0;
    for (const Entry& e : entries) {
      const auto u = uninformative_.find(e.address);
      if (u == uninformative_.end()) continue;
      const Eigen::MatrixXd& D = u->second;
      U.block(e.offset, col, e.tangent, D.cols()) = D;
      col += static_cast<int>(D.cols());
    }
    if (k > 0) {
      const Eigen::MatrixXd HpU = Hp * U;
      const Eigen::MatrixXd inv = pseudoInverse(U.transpose() * HpU, eps);
      Hp -= HpU * inv * HpU.transpose();
      gp -= HpU * (inv * (U.transpose() * gp));
    }
    H += Hp;
    g += gp;
  }
  eliminateAlone(&out, &H, &g, eps);
  m = 0;
  for (std::size_t i = 0; i < out.dropped; ++i) m += entries[i].tangent;
  n = static_cast<int>(H.rows());

  const int k = n - m;
  if (m == 0) {  // every dropped block went alone
    out.H = std::move(H);
    out.g = std::move(g);
    return out;
  }
  ScaledCholesky c;
  if (scaledCholesky(H.topLeftCorner(m, m), &c)) {
    // Hmm = D^1/2 L L^T D^1/2: with W = L^-1 D^-1/2 Hmk and w = L^-1 D^-1/2 gm, the Schur
    // complement is Hkk - W^T W (a symmetric rank update: half the products of Hkm Hmm^-1 Hmk
    // through the inverse, which matters when the prior is dense over many sensors' blocks)
    // and gk - W^T w.
    const Eigen::VectorXd inv_d = c.sqrt_d.cwiseInverse();
    Eigen::MatrixXd W = inv_d.asDiagonal() * H.topRightCorner(m, k);
    Eigen::VectorXd w = inv_d.asDiagonal() * g.head(m);
    c.L.triangularView<Eigen::Lower>().solveInPlace(W);
    c.L.triangularView<Eigen::Lower>().solveInPlace(w);
    out.H = H.bottomRightCorner(k, k);
    out.H.selfadjointView<Eigen::Lower>().rankUpdate(W.transpose(), -1.0);
    out.H.triangularView<Eigen::StrictlyUpper>() = out.H.transpose().eval();
    out.g = g.tail(k) - W.transpose() * w;
  } else {
    const Eigen::MatrixXd Hmm_inv = pseudoInverse(H.topLeftCorner(m, m), eps);
    const Eigen::MatrixXd Hkm = H.bottomLeftCorner(k, m);
    const Eigen::MatrixXd HkmHmm_inv = Hkm * Hmm_inv;
    out.H = H.bottomRightCorner(k, k) - HkmHmm_inv * Hkm.transpose();
    out.g = g.tail(k) - HkmHmm_inv * g.head(m);
  }
  for (std::size_t i = out.dropped; i < entries.size(); ++i) entries[i].offset -= m;
  return out;
}

void Marginalizer::eliminateAlone(Reduced* out, Eigen::MatrixXd* H, Eigen::VectorXd* g,
                                  double eps) const {
  std::vector<Entry>& entries = out->entries;
  std::vector<bool> gone(entries.size(), false);
  bool any = false;
  for (std::size_t i = 0; i < out->dropped; ++i) {
    const Entry& e = entries[i];
    if (!alone_.count(e.address)) continue;
    // The blocks it couples to, and its rows of H over their columns.
    std::vector<std::size_t> near;
    int q = 0;
    for (std::size_t j = 0; j < entries.size(); ++j) {
      if (j == i || gone[j]) continue;
      if (H->block(e.offset, entries[j].offset, e.tangent, entries[j].tangent).isZero(0.0)) {
        continue;
      }
      near.push_back(j);
      q += entries[j].tangent;
    }
    Eigen::MatrixXd B(e.tangent, q);
    int col = 0;
    for (std::size_t j : near) {
      B.middleCols(col, entries[j].tangent) =
          H->block(e.offset, entries[j].offset, e.tangent, entries[j].tangent);
      col += entries[j].tangent;
    }
    const Eigen::MatrixXd BtInv =
        B.transpose() * pseudoInverse(H->block(e.offset, e.offset, e.tangent, e.tangent), eps);
    const Eigen::MatrixXd S = BtInv * B;
    const Eigen::VectorXd s = BtInv * g->segment(e.offset, e.tangent);
    int ca = 0;
    for (std::size_t a : near) {
      const Entry& ea = entries[a];
      g->segment(ea.offset, ea.tangent) -= s.segment(ca, ea.tangent);
      int cb = 0;
      for (std::size_t b : near) {
        const Entry& eb = entries[b];
        H->block(ea.offset, eb.offset, ea.tangent, eb.tangent) -=
            S.block(ca, cb, ea.tangent, eb.tangent);
        cb += eb.tangent;
      }
      ca += ea.tangent;
    }
    gone[i] = true;
    any = true;
  }
  if (!any) return;
  // The rest, without the eliminated blocks' rows and columns.
  std::vector<Entry> rest;
  std::vector<int> from;  // each kept entry's offset in H
  std::size_t dropped = 0;
  int n = 0;
  for (std::size_t i = 0; i < entries.size(); ++i) {
    if (gone[i]) continue;
    rest.push_back(entries[i]);
    from.push_back(entries[i].offset);
    rest.back().offset = n;
    n += entries[i].tangent;
    if (i < out->dropped) ++dropped;
  }
  Eigen::MatrixXd Hr(n, n);
  Eigen::VectorXd gr(n);
  for (std::size_t a = 0; a < rest.size(); ++a) {
    const int ta = rest[a].tangent;
    gr.segment(rest[a].offset, ta) = g->segment(from[a], ta);
    for (std::size_t b = 0; b < rest.size(); ++b) {
      Hr.block(rest[a].offset, rest[b].offset, ta, rest[b].tangent) =
          H->block(from[a], from[b], ta, rest[b].tangent);
    }
  }
  entries = std::move(rest);
  out->dropped = dropped;
  *H = std::move(Hr);
  *g = std::move(gr);
}

StatusOr<std::unique_ptr<MarginalizationFactor>> Marginalizer::marginalize(
    const std::set<const double*>& drop, double eps) const {
  auto reduced = reduce(drop, eps);
  if (!reduced.ok()) return reduced.status();
  const Reduced& red = reduced.value();
  const Eigen::MatrixXd& Hs = red.H;
  const Eigen::VectorXd& gs = red.g;
  const auto k = Hs.rows();

  std::vector<MarginalizationFactor::Block> kept;
  for (std::size_t i = red.dropped; i < red.entries.size(); ++i) {
    const Entry& e = red.entries[i];
    MarginalizationFactor::Block block;
    block.address = e.address;
    block.manifold = e.manifold;
    block.ambient = e.ambient;
    block.tangent = e.tangent;
    block.x0.assign(e.address, e.address + e.ambient);
    kept.push_back(std::move(block));
  }
  if (information_only_) {
    auto made = std::make_unique<MarginalizationFactor>(std::move(kept), Eigen::MatrixXd(0, k),
                                                        Eigen::VectorXd(0));
    made->setInformation(Hs, gs);
    return made;
  }

  // Hs = J0^T J0 with J0 = L^T D^1/2 (clearly positive definite), r0 = L^-1 D^-1/2 gs.
  ScaledCholesky c;
  if (scaledCholesky(Hs, &c)) {
    Eigen::MatrixXd J0 = c.L.transpose() * c.sqrt_d.asDiagonal();
    Eigen::VectorXd r0 = c.sqrt_d.cwiseInverse().asDiagonal() * gs;
    c.L.triangularView<Eigen::Lower>().solveInPlace(r0);
    auto made =
        std::make_unique<MarginalizationFactor>(std::move(kept), std::move(J0), std::move(r0));
    made->setInformation(Hs, gs);  // J0^T J0 = Hs, J0^T r0 = gs
    return made;
  }
  // Semi-definite, where allowed (allowSemidefinite): LDL^T over the kept pivots, J0 = J D^1/2,
  // r0 from the lower-triangular L_kept D^1/2 r0 = D^-1/2 gs on the kept rows.
  Eigen::VectorXd sqrt_d;
  Eigen::MatrixXd J;
  std::vector<int> pivots;
  if (semidefinite_ && scaledSemidefiniteFactor(Hs, eps, &sqrt_d, &J, &pivots) && !pivots.empty()) {
    const Eigen::VectorXd inv_d = inverseOrZero(sqrt_d);
    const Eigen::VectorXd gs_scaled = inv_d.asDiagonal() * gs;
    const auto rows = static_cast<Eigen::Index>(pivots.size());
    Eigen::MatrixXd T(rows, rows);  // J's columns at the pivots: upper triangular
    Eigen::VectorXd rhs(rows);
    for (Eigen::Index i = 0; i < rows; ++i) {
      T.col(i) = J.col(pivots[i]);
      rhs[i] = gs_scaled[pivots[i]];
    }
    return withKeptInformation(std::move(kept), J * sqrt_d.asDiagonal(),
                               T.transpose().triangularView<Eigen::Lower>().solve(rhs));
  }
  // Otherwise J0 = diag(sqrt(l)) V^T D^1/2 over the scaled eigenvalues l > eps; r0 solves
  // J0^T r0 = gs.
  const ScaledEigen es = scaledEigen(Hs, eps);
  if (es.kept.empty()) return Status::Error("marginalization left no information");
  const Eigen::VectorXd inv_d = inverseOrZero(es.sqrt_d);
  const Eigen::VectorXd gs_scaled = inv_d.asDiagonal() * gs;
  Eigen::MatrixXd J0(es.kept.size(), k);
  Eigen::VectorXd r0(es.kept.size());
  for (std::size_t i = 0; i < es.kept.size(); ++i) {
    const double s = std::sqrt(es.l[es.kept[i]]);
    const Eigen::VectorXd v = es.V.col(es.kept[i]);
    J0.row(i) = s * v.transpose() * es.sqrt_d.asDiagonal();
    r0[i] = v.dot(gs_scaled) / s;
  }
  return withKeptInformation(std::move(kept), std::move(J0), std::move(r0));
}

MarginalizationFactor::MarginalizationFactor(std::vector<Block> blocks, Eigen::MatrixXd J0,
                                             Eigen::VectorXd r0)
    : blocks_(std::move(blocks)), J0_(std::move(J0)), r0_(std::move(r0)) {
  set_num_residuals(static_cast<int>(r0_.size()));
  for (const auto& b : blocks_) mutable_parameter_block_sizes()->push_back(b.ambient);
}

std::vector<double*> MarginalizationFactor::parameterBlocks() const {
  std::vector<double*> out;
  for (const auto& b : blocks_) out.push_back(b.address);
  return out;
}

std::vector<std::unique_ptr<MarginalizationFactor>> MarginalizationFactor::splitRows() const {
  std::vector<int> offsets;
  int total = 0;
  for (const auto& b : blocks_) {
    offsets.push_back(total);
    total += b.tangent;
  }
  // The first block each row touches.
  std::vector<std::vector<int>> rows_of(blocks_.size());
  for (int r = 0; r < J0_.rows(); ++r) {
    std::size_t first = blocks_.size() - 1;
    for (std::size_t i = 0; i < blocks_.size(); ++i) {
      if ((J0_.row(r).segment(offsets[i], blocks_[i].tangent).array() != 0.0).any()) {
        first = i;
        break;
      }
    }
    rows_of[first].push_back(r);
  }
  std::vector<std::unique_ptr<MarginalizationFactor>> out;
  for (std::size_t i = 0; i < blocks_.size(); ++i) {
    const std::vector<int>& rows = rows_of[i];
    if (rows.empty()) continue;
    const int cols = total - offsets[i];
    Eigen::MatrixXd J(rows.size(), cols);
    Eigen::VectorXd r(rows.size());
    for (std::size_t k = 0; k < rows.size(); ++k) {
      J.row(k) = J0_.row(rows[k]).tail(cols);
      r[k] = r0_[rows[k]];
    }
    std::vector<Block> blocks(blocks_.begin() + i, blocks_.end());
    out.push_back(std::make_unique<MarginalizationFactor>(std::move(blocks), std::move(J), r));
  }
  return out;
}

bool MarginalizationFactor::Evaluate(double const* const* parameters, double* residuals,
                                     double** jacobians) const {
  int total = 0;
  for (const auto& b : blocks_) total += b.tangent;
  Eigen::VectorXd dx(total);
  int offset = 0;
  for (std::size_t i = 0; i < blocks_.size(); ++i) {
    const Block& b = blocks_[i];
    if (b.manifold != nullptr) {
      if (!b.manifold->Minus(parameters[i], b.x0.data(), dx.data() + offset)) return false;
    } else {
      for (int j = 0; j < b.ambient; ++j) dx[offset + j] = parameters[i][j] - b.x0[j];
    }
    offset += b.tangent;
  }
  Eigen::Map<Eigen::VectorXd>(residuals, r0_.size()) = r0_ + J0_ * dx;
  if (jacobians == nullptr) return true;
  offset = 0;
  for (std::size_t i = 0; i < blocks_.size(); ++i) {
    const Block& b = blocks_[i];
    if (jacobians[i] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> out(
          jacobians[i], r0_.size(), b.ambient);
      if (b.manifold != nullptr) {
        Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> minus(b.tangent,
                                                                                     b.ambient);
        b.manifold->MinusJacobian(parameters[i], minus.data());
        out = J0_.middleCols(offset, b.tangent) * minus;
      } else {
        out = J0_.middleCols(offset, b.tangent);
      }
    }
    offset += b.tangent;
  }
  return true;
}

}  // namespace mvis
