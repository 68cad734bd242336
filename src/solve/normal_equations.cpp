// The Gauss-Newton normal equations' constant part and their sparsity pattern, analysed once per
// set-up (ClusterSolver::assembleConstant, analyzePattern).
#include "hgdeform/solve/solver.h"
#include "solve/block_cholesky.h"
#include "solve/solver_terms.h"

namespace hgd {

using solver_terms::kron;
using solver_terms::Mat12;

// The constant part of the normal equations (w_Prop·JᵀJ of E_Prop, + E_Manip when active) and
// its sparsity pattern: all diagonal blocks, and off-diagonal blocks for adjacent free pairs.
// E_Manip adds to the manipulated cluster's diagonal block, which is always there, so the
// pattern does not depend on it.
void ClusterSolver::assembleConstant() {
  const int nv = static_cast<int>(x_.size());
  const int nb = nv / 12;
  auto block = [&](int c) { return var_[static_cast<std::size_t>(c)] / 12; };
  // Constant part of the normal equations and the sparsity pattern (all diagonal blocks, and
  // off-diagonal blocks for adjacent free pairs).
  std::vector<Eigen::Triplet<double>> trip;
  // Off-diagonal blocks keep only what can be nonzero there: E_Prop's kron(S) couples the
  // same row of the two 3x4 transforms, E_Length the two translations. A third of the dense
  // block, so fewer values to refresh and scatter into the factor every iteration.
  auto addBlock = [&](int bi, int bj, const Mat12& m) {
    for (int r = 0; r < 12; ++r)
      for (int c = 0; c < 12; ++c)
        if (bi == bj || r % 3 == c % 3 || (r >= 9 && c >= 9))
          trip.emplace_back(12 * bi + r, 12 * bj + c, m(r, c));
  };
  // Every diagonal block is dense (Rot couples A's entries); 1e-9 I keeps the system definite
  // when a cluster is unconstrained (no neighbours).
  // A held cluster's rows and columns are the identity's (zero coupling, zero gradient: its
  // step is exactly 0), with the same entries in the pattern, so the analysis stays valid.
  const int held = held_ >= 0 ? block(held_) : -1;
  for (int b = 0; b < nb; ++b) addBlock(b, b, (b == held ? 1.0 : 1e-9) * Mat12::Identity());
  for (const auto& p : pairs_) {
    const bool fi = var_[static_cast<std::size_t>(p.i)] >= 0, fj = var_[static_cast<std::size_t>(p.j)] >= 0;
    const double wi = moves(p.i) ? w_.prop * p.omega : 0, wj = moves(p.j) ? w_.prop * p.omega : 0;
    if (fi) addBlock(block(p.i), block(p.i), wi * kron(p.sii));
    if (fj) addBlock(block(p.j), block(p.j), wj * kron(p.sjj));
    if (fi && fj) {
      addBlock(block(p.i), block(p.j), -std::min(wi, wj) * kron(p.sij));
      addBlock(block(p.j), block(p.i), -std::min(wi, wj) * kron(p.sij.transpose()));
    }
  }
  if (manip_active_) addBlock(block(manipulated_), block(manipulated_), w_.manip * kron(manip_s_));
  h_const_.resize(nv, nv);
  h_const_.setFromTriplets(trip.begin(), trip.end());
  h_const_.makeCompressed();
  h_ = h_const_;
}

// The symbolic analysis, once per setup: where the per-iteration terms land and the block
// Cholesky's elimination order and fill.
void ClusterSolver::analyzePattern() {
  assembleConstant();
  const int nb = static_cast<int>(x_.size()) / 12;
  auto block = [&](int c) { return var_[static_cast<std::size_t>(c)] / 12; };
  // Where the per-iteration terms land in h_'s value array (found once, not per entry and
  // iteration): Rot's 9x9 in each diagonal block, Length's 3x3 translation blocks.
  auto at = [&](int row, int col) {
    const int* b = h_.innerIndexPtr() + h_.outerIndexPtr()[col];
    const int* e = h_.innerIndexPtr() + h_.outerIndexPtr()[col + 1];
    return static_cast<int>(std::lower_bound(b, e, row) - h_.innerIndexPtr());
  };
  auto positions = [&](int bi, int bj, int off, int size, std::vector<int>& out) {
    for (int c = 0; c < size; ++c)
      for (int r = 0; r < size; ++r) out.push_back(at(12 * bi + off + r, 12 * bj + off + c));
  };
  rot_at_.clear();
  for (int b = 0; b < nb; ++b) positions(b, b, 0, 9, rot_at_);
  length_at_.clear();
  for (const auto& p : pairs_) {
    const int bi = var_[static_cast<std::size_t>(p.i)] >= 0 ? block(p.i) : -1;
    const int bj = var_[static_cast<std::size_t>(p.j)] >= 0 ? block(p.j) : -1;
    for (const auto& [x, y] : {std::pair<int, int>(bi, bi), {bj, bj}, {bi, bj}, {bj, bi}}) {
      if (x >= 0 && y >= 0)
        positions(x, y, 9, 3, length_at_);
      else
        length_at_.insert(length_at_.end(), 9, -1);
    }
  }
  if (!factor_) factor_ = std::make_unique<BlockCholesky>();  // a moved-from solver set up again
  factor_->analyze(h_);
}

}  // namespace hgd
