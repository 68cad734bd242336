// The sparse block Cholesky of the normal equations (solve/block_cholesky.h).
#include "solve/block_cholesky.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <stdexcept>

namespace hgd {

int BlockCholesky::blockAt(int i, int j) const {
  if (i == j) return diag_at_[static_cast<std::size_t>(j)];
  const int* b = col_row_.data() + col_start_[static_cast<std::size_t>(j)];
  const int* e = col_row_.data() + col_start_[static_cast<std::size_t>(j) + 1];
  return diag_at_[static_cast<std::size_t>(j)] + 1 + static_cast<int>(std::lower_bound(b, e, i) - b);
}

void BlockCholesky::analyze(const Eigen::SparseMatrix<double>& pattern) {
  nb_ = static_cast<int>(pattern.cols() / 12);
  const auto nb = static_cast<std::size_t>(nb_);
  // Block adjacency.
  std::vector<std::vector<int>> adj(nb);
  for (int c = 0; c < pattern.outerSize(); ++c)
    for (Eigen::SparseMatrix<double>::InnerIterator it(pattern, c); it; ++it) {
      const int bi = static_cast<int>(it.row()) / 12, bj = c / 12;
      if (bi != bj) adj[static_cast<std::size_t>(bj)].push_back(bi);
    }
  for (auto& a : adj) {
    std::sort(a.begin(), a.end());
    a.erase(std::unique(a.begin(), a.end()), a.end());
  }
  // Minimum degree on the block graph, with the fill it makes (clusters form chains and
  // trees, so there is little). A block's neighbours when it is eliminated are the rows of its
  // column of L.
  std::vector<std::vector<int>> g = adj, rows(nb);
  std::vector<char> done(nb, 0);
  order_.clear();
  rank_.assign(nb, -1);
  for (std::size_t step = 0; step < nb; ++step) {
    int best = -1;
    for (std::size_t b = 0; b < nb; ++b)
      if (!done[b] && (best < 0 || g[b].size() < g[static_cast<std::size_t>(best)].size()))
        best = static_cast<int>(b);
    const auto v = static_cast<std::size_t>(best);
    done[v] = 1;
    rank_[v] = static_cast<int>(order_.size());
    order_.push_back(best);
    rows[step] = g[v];
    // Neighbours of v become a clique; v leaves the graph.
    for (int a : g[v]) {
      auto& ga = g[static_cast<std::size_t>(a)];
      ga.erase(std::remove(ga.begin(), ga.end(), best), ga.end());
      for (int b : g[v])
        if (b != a && std::find(ga.begin(), ga.end(), b) == ga.end()) ga.push_back(b);
    }
  }
  col_start_.assign(nb + 1, 0);
  col_row_.clear();
  for (std::size_t j = 0; j < nb; ++j) {
    for (int& b : rows[j]) b = rank_[static_cast<std::size_t>(b)];  // blocks -> positions
    std::sort(rows[j].begin(), rows[j].end());
    col_row_.insert(col_row_.end(), rows[j].begin(), rows[j].end());
    col_start_[j + 1] = static_cast<int>(col_row_.size());
  }
  diag_at_.resize(nb);
  for (std::size_t j = 0; j < nb; ++j) diag_at_[j] = static_cast<int>(j) + col_start_[j];
  l_.assign(nb + col_row_.size(), Block::Zero());
  // Where each pattern value goes: the lower triangle by position (the diagonal block whole).
  value_to_.assign(static_cast<std::size_t>(pattern.nonZeros()), -1);
  for (int c = 0; c < pattern.outerSize(); ++c)
    for (int k = pattern.outerIndexPtr()[c]; k < pattern.outerIndexPtr()[c + 1]; ++k) {
      const int r = pattern.innerIndexPtr()[k];
      const int pi = rank_[static_cast<std::size_t>(r / 12)], pj = rank_[static_cast<std::size_t>(c / 12)];
      if (pi < pj) continue;
      value_to_[static_cast<std::size_t>(k)] = 144 * blockAt(pi, pj) + 12 * (c % 12) + r % 12;
    }
}

bool BlockCholesky::factorize(const Eigen::SparseMatrix<double>& matrix) {
  if (nb_ == 0 || static_cast<std::size_t>(matrix.nonZeros()) != value_to_.size()) return nb_ == 0;
  for (auto& b : l_) b.setZero();
  const double* v = matrix.valuePtr();
  for (std::size_t k = 0; k < value_to_.size(); ++k)
    if (value_to_[k] >= 0) l_[static_cast<std::size_t>(value_to_[k] / 144)].data()[value_to_[k] % 144] = v[k];
  const auto nb = static_cast<std::size_t>(nb_);
  Eigen::LLT<Block> llt;
  for (std::size_t j = 0; j < nb; ++j) {
    Block& d = l_[static_cast<std::size_t>(diag_at_[j])];
    llt.compute(d);
    if (llt.info() != Eigen::Success) return false;
    d = llt.matrixL();
    const int b = col_start_[j], e = col_start_[j + 1];
    Block* col = &l_[static_cast<std::size_t>(diag_at_[j]) + 1];
    // L_ij = A_ij L_jj^-T
    for (int s = 0; s < e - b; ++s)
      d.triangularView<Eigen::Lower>().transpose().solveInPlace<Eigen::OnTheRight>(col[s]);
    // Right-looking update of the later columns: A_ik -= L_ij L_kj^T for rows i >= k.
    for (int t = 0; t < e - b; ++t) {
      const int k = col_row_[static_cast<std::size_t>(b + t)];
      l_[static_cast<std::size_t>(diag_at_[static_cast<std::size_t>(k)])].noalias() -=
          col[t] * col[t].transpose();
      for (int s = t + 1; s < e - b; ++s)
        l_[static_cast<std::size_t>(blockAt(col_row_[static_cast<std::size_t>(b + s)], k))].noalias() -=
            col[s] * col[t].transpose();
    }
  }
  return true;
}

void BlockCholesky::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) const {
  const auto nb = static_cast<std::size_t>(nb_);
  // y = L^-1 P b, then x = P^T L^-T y, by block positions.
  std::vector<Eigen::Matrix<double, 12, 1>> y(nb);
  for (std::size_t j = 0; j < nb; ++j) y[j] = b.segment<12>(12 * order_[j]);
  for (std::size_t j = 0; j < nb; ++j) {
    const Block& d = l_[static_cast<std::size_t>(diag_at_[j])];
    d.triangularView<Eigen::Lower>().solveInPlace(y[j]);
    for (int s = col_start_[j]; s < col_start_[j + 1]; ++s)
      y[static_cast<std::size_t>(col_row_[static_cast<std::size_t>(s)])].noalias() -=
          l_[static_cast<std::size_t>(diag_at_[j] + 1 + s - col_start_[j])] * y[j];
  }
  for (std::size_t j = nb; j-- > 0;) {
    for (int s = col_start_[j]; s < col_start_[j + 1]; ++s)
      y[j].noalias() -= l_[static_cast<std::size_t>(diag_at_[j] + 1 + s - col_start_[j])].transpose() *
                        y[static_cast<std::size_t>(col_row_[static_cast<std::size_t>(s)])];
    l_[static_cast<std::size_t>(diag_at_[j])].triangularView<Eigen::Lower>().transpose().solveInPlace(y[j]);
  }
  x.resize(b.size());
  for (std::size_t j = 0; j < nb; ++j) x.segment<12>(12 * order_[j]) = y[j];
}

}  // namespace hgd
