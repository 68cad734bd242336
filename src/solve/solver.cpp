#include "hgdeform/solve/solver.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "solve/block_cholesky.h"
#include "util/timer.h"

namespace hgd {

ClusterSolver::ClusterSolver() : factor_(std::make_unique<BlockCholesky>()) {}
ClusterSolver::~ClusterSolver() = default;
ClusterSolver::ClusterSolver(ClusterSolver&&) noexcept = default;
ClusterSolver& ClusterSolver::operator=(ClusterSolver&&) noexcept = default;

namespace {
using Mat34 = Eigen::Matrix<double, 3, 4>;
using Vec12 = Eigen::Matrix<double, 12, 1>;
using Mat12 = Eigen::Matrix<double, 12, 12>;

Mat34 toU(const NormalisedTransform& tr) {
  Mat34 u;
  u.leftCols<3>() = tr.A;
  u.col(3) = tr.t;
  return u;
}

// The six Rot residuals and their Jacobian with respect to (a1, a2, a3).
void rotResiduals(const Eigen::Matrix3d& a, Eigen::Matrix<double, 6, 1>& r, Eigen::Matrix<double, 6, 9>& j) {
  const Eigen::Vector3d c1 = a.col(0), c2 = a.col(1), c3 = a.col(2);
  r << c1.dot(c2), c1.dot(c3), c2.dot(c3), c1.dot(c1) - 1, c2.dot(c2) - 1, c3.dot(c3) - 1;
  j.setZero();
  j.block<1, 3>(0, 0) = c2.transpose();
  j.block<1, 3>(0, 3) = c1.transpose();
  j.block<1, 3>(1, 0) = c3.transpose();
  j.block<1, 3>(1, 6) = c1.transpose();
  j.block<1, 3>(2, 3) = c3.transpose();
  j.block<1, 3>(2, 6) = c2.transpose();
  j.block<1, 3>(3, 0) = 2 * c1.transpose();
  j.block<1, 3>(4, 3) = 2 * c2.transpose();
  j.block<1, 3>(5, 6) = 2 * c3.transpose();
}

// (S ⊗ I3) for the ordering u = [a1; a2; a3; t].
Mat12 kron(const Eigen::Matrix4d& s) {
  Mat12 k = Mat12::Zero();
  for (int a = 0; a < 4; ++a)
    for (int b = 0; b < 4; ++b) k.block<3, 3>(3 * a, 3 * b) = s(a, b) * Eigen::Matrix3d::Identity();
  return k;
}
}  // namespace

double rotationResidual(const Eigen::Matrix3d& a) {
  Eigen::Matrix<double, 6, 1> r;
  Eigen::Matrix<double, 6, 9> j;
  rotResiduals(a, r, j);
  return r.squaredNorm();
}

void ClusterSolver::setup(std::vector<SolverCluster> clusters, const std::vector<std::pair<int, int>>& edges,
                          int manipulated, const SolverWeights& weights) {
  clusters_ = std::move(clusters);
  manipulated_ = manipulated;
  w_ = weights;
  const int nc = static_cast<int>(clusters_.size());
  var_.assign(static_cast<std::size_t>(nc), -1);
  int nv = 0;
  for (int c = 0; c < nc; ++c)
    if (!clusters_[static_cast<std::size_t>(c)].constant) {
      var_[static_cast<std::size_t>(c)] = nv;
      nv += 12;
    }
  transforms_.assign(static_cast<std::size_t>(nc), NormalisedTransform{});
  x_ = Eigen::VectorXd::Zero(nv);
  reset();

  pairs_.clear();
  for (const auto& [i, j] : edges) {
    if (i == j) continue;
    const auto& ci = clusters_[static_cast<std::size_t>(i)];
    const auto& cj = clusters_[static_cast<std::size_t>(j)];
    if (ci.constant && cj.constant) continue;
    Pair p{i,
           j,
           Eigen::Matrix4d::Zero(),
           Eigen::Matrix4d::Zero(),
           Eigen::Matrix4d::Zero(),
           Eigen::Vector4d::Zero(),
           Eigen::Vector4d::Zero(),
           0,
           (ci.barycentre - cj.barycentre).norm()};
    for (const auto* cl : {&ci, &cj})
      for (const auto& x : cl->points) {
        Eigen::Vector4d yi, yj;
        yi << x - ci.barycentre, 1;
        yj << x - cj.barycentre, 1;
        p.sii += yi * yi.transpose();
        p.sij += yi * yj.transpose();
        p.sjj += yj * yj.transpose();
        p.mi += yi;
        p.mj += yj;
        p.count += 1;
      }
    pairs_.push_back(p);
  }
  manip_active_ = false;
  held_ = -1;
  if (nv > 0) analyzePattern();
  constant_ready_ = true;
}

void ClusterSolver::reset() {
  for (std::size_t c = 0; c < clusters_.size(); ++c) {
    if (var_[c] < 0) continue;
    transforms_[c] = NormalisedTransform{};
    x_.segment<12>(var_[c]) << 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0;
  }
}

void ClusterSolver::setTransforms(const std::vector<NormalisedTransform>& transforms) {
  if (transforms.size() != clusters_.size())
    throw std::invalid_argument("ClusterSolver: wrong number of transforms");
  transforms_ = transforms;
  for (std::size_t c = 0; c < clusters_.size(); ++c) {
    if (var_[c] < 0) continue;
    for (int k = 0; k < 3; ++k) x_.segment<3>(var_[c] + 3 * k) = transforms[c].A.col(k);
    x_.segment<3>(var_[c] + 9) = transforms[c].t;
  }
}

void ClusterSolver::setManipulation(const std::vector<Eigen::Vector3d>& rest,
                                    const std::vector<Eigen::Vector3d>& target,
                                    const std::vector<double>& weight) {
  if (manipulated_ < 0 || !moves(manipulated_))
    throw std::logic_error("ClusterSolver: no free manipulated cluster");
  if (rest.size() != target.size() || rest.size() != weight.size())
    throw std::invalid_argument("ClusterSolver: rest, target and weight sizes differ");
  const Eigen::Vector3d g = clusters_[static_cast<std::size_t>(manipulated_)].barycentre;
  Eigen::Matrix4d s = Eigen::Matrix4d::Zero();
  Eigen::Matrix<double, 4, 3> b = Eigen::Matrix<double, 4, 3>::Zero();
  double c = 0;
  for (std::size_t k = 0; k < rest.size(); ++k) {
    Eigen::Vector4d y;
    y << rest[k] - g, 1;
    const Eigen::Vector3d z = target[k] - g;
    s += weight[k] * y * y.transpose();
    b += weight[k] * y * z.transpose();
    c += weight[k] * z.squaredNorm();
  }
  const bool structure_changed = !manip_active_ || s != manip_s_;
  manip_s_ = s;
  manip_b_ = b;
  manip_c_ = c;
  manip_active_ = true;
  if (structure_changed) constant_ready_ = false;
}

void ClusterSolver::clearManipulation() {
  if (manip_active_) constant_ready_ = false;
  manip_active_ = false;
}

void ClusterSolver::hold(int cluster, const NormalisedTransform& transform) {
  const int v = var_.at(static_cast<std::size_t>(cluster));
  if (v < 0) throw std::logic_error("ClusterSolver: hold: the cluster is constant already");
  if (held_ >= 0 && held_ != cluster) throw std::logic_error("ClusterSolver: hold: another cluster is held");
  if (cluster == manipulated_) clearManipulation();
  if (held_ != cluster) constant_ready_ = false;  // its rows and columns become the identity's
  held_ = cluster;
  transforms_[static_cast<std::size_t>(cluster)] = transform;
  for (int k = 0; k < 3; ++k) x_.segment<3>(v + 3 * k) = transform.A.col(k);
  x_.segment<3>(v + 9) = transform.t;
}

void ClusterSolver::release() {
  if (held_ >= 0) constant_ready_ = false;
  held_ = -1;
}

void ClusterSolver::unpack(const Eigen::VectorXd& x) {
  for (std::size_t c = 0; c < clusters_.size(); ++c) {
    if (var_[c] < 0) continue;
    const auto u = x.segment<12>(var_[c]);
    for (int k = 0; k < 3; ++k) transforms_[c].A.col(k) = u.segment<3>(3 * k);
    transforms_[c].t = u.segment<3>(9);
  }
}

Eigen::Vector3d ClusterSolver::translationOf(const Eigen::VectorXd& x, int cluster) const {
  const int v = var_[static_cast<std::size_t>(cluster)];
  return v >= 0 ? Eigen::Vector3d(x.segment<3>(v + 9)) : transforms_[static_cast<std::size_t>(cluster)].t;
}

double ClusterSolver::propOf(const Pair& p, const Mat34& ui, const Mat34& uj) const {
  const Eigen::Vector3d d = clusters_[static_cast<std::size_t>(p.i)].barycentre -
                            clusters_[static_cast<std::size_t>(p.j)].barycentre;
  return (ui * p.sii * ui.transpose()).trace() - 2 * (ui * p.sij * uj.transpose()).trace() +
         (uj * p.sjj * uj.transpose()).trace() + 2 * d.dot(ui * p.mi - uj * p.mj) + p.count * d.squaredNorm();
}

Energies ClusterSolver::evaluate(const Eigen::VectorXd& x) const {
  auto uOf = [&](int c) -> Mat34 {
    const int v = var_[static_cast<std::size_t>(c)];
    if (v < 0) return toU(transforms_[static_cast<std::size_t>(c)]);
    return Eigen::Map<const Mat34>(x.data() + v);
  };
  Energies e;
  // Constant terms (of clusters that do not move) are left out, held or not: the same energy
  // as if the held cluster had been constant from the setup on.
  for (std::size_t c = 0; c < clusters_.size(); ++c) {
    if (!moves(static_cast<int>(c))) continue;
    const Mat34 u = uOf(static_cast<int>(c));
    e.detail += w_.detail * clusters_[c].rot_weight * rotationResidual(u.leftCols<3>());
  }
  for (const auto& p : pairs_) {
    if (!moves(p.i) && !moves(p.j)) continue;
    e.prop += w_.prop * p.omega * std::max(propOf(p, uOf(p.i), uOf(p.j)), 0.0);
    const Eigen::Vector3d d = clusters_[static_cast<std::size_t>(p.i)].barycentre -
                              clusters_[static_cast<std::size_t>(p.j)].barycentre;
    const Eigen::Vector3d gap = d + translationOf(x, p.i) - translationOf(x, p.j);
    const double r = gap.norm() - p.rest_length;
    e.length += w_.length * r * r;
  }
  if (manip_active_) {
    const Mat34 u = uOf(manipulated_);
    const double m = (u * manip_s_ * u.transpose()).trace() - 2 * (u * manip_b_).trace() + manip_c_;
    e.manip = w_.manip * std::max(m, 0.0);
  }
  return e;
}

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

SolveStats ClusterSolver::solve(const GaussNewtonOptions& options) {
  if (options.reweight_rounds <= 0) return solveOnce(options);
  Stopwatch sw;
  // Every solve from uniform weights, and back to them however it ends (a throw included): a
  // result depends only on its start, and a later solve without rounds is the paper's.
  struct Uniform {
    ClusterSolver& s;
    void operator()() const {
      for (auto& p : s.pairs_) p.omega = 1;
      s.constant_ready_ = false;
    }
    ~Uniform() { (*this)(); }
  } uniform{*this};
  uniform();
  SolveStats st = solveOnce(options);
  int iterations = st.iterations;
  for (int r = 0; r < options.reweight_rounds && reweightPairs(); ++r) {
    constant_ready_ = false;  // E_Prop's part of the normal equations changed
    const SolveStats round = solveOnce(options);
    iterations += round.iterations;
    if (!round.decreased) break;  // no step lowers this round's energy: the last result stays
  }
  uniform();
  // Whether the handle could be followed is the paper's solve's to say; the rounds only move
  // the bending between pairs.
  st.iterations = iterations;
  st.energy = evaluate(x_);  // the paper's energy of the result
  st.ms = sw.ms();
  return st;
}

bool ClusterSolver::reweightPairs() {
  // Each pair's mean squared mismatch (E_Prop over its points, over their count), for the
  // pairs whose weight matters: a constant term's changes nothing.
  const auto weighed = [&](const Pair& p) { return (moves(p.i) || moves(p.j)) && p.count > 0; };
  std::vector<double> mismatch(pairs_.size(), 0.0);
  double mean = 0, count = 0;
  for (std::size_t k = 0; k < pairs_.size(); ++k) {
    const Pair& p = pairs_[k];
    if (!weighed(p)) continue;
    const double prop = propOf(p, toU(transforms_[static_cast<std::size_t>(p.i)]),
                               toU(transforms_[static_cast<std::size_t>(p.j)]));
    mismatch[k] = std::max(prop, 0.0) / p.count;
    mean += mismatch[k] * p.count;
    count += p.count;
  }
  if (!(count > 0) || !std::isfinite(mean)) return false;
  mean /= count;
  // Nothing bends: a mismatch of 10^-7 of the diagonal (squared, in the normalised frame) is
  // rounding, and weights from rounding would only stir it.
  if (!(mean > 1e-14)) return false;
  // Inverse square roots (a least-squares step towards the sum of the mismatches' roots, which
  // gathers the bending), the mismatch floored so that a pair in perfect agreement weighs at
  // most 100 times the mean; then normalised to a count-weighted mean of 1.
  double sum = 0;
  for (std::size_t k = 0; k < pairs_.size(); ++k) {
    Pair& p = pairs_[k];
    if (!weighed(p)) continue;
    p.omega = 1 / std::sqrt(std::max(mismatch[k], 1e-4 * mean));
    sum += p.omega * p.count;
  }
  for (auto& p : pairs_)
    if (weighed(p)) p.omega *= count / sum;
  return true;
}

SolveStats ClusterSolver::solveOnce(const GaussNewtonOptions& options) {
  Stopwatch sw;
  SolveStats st;
  const int nv = static_cast<int>(x_.size());
  if (nv == 0) {
    st.converged = true;
    st.energy = evaluate(x_);
    return st;
  }

  if (!constant_ready_) {  // E_Manip's targets changed: the constant part's values only
    assembleConstant();
    constant_ready_ = true;
  }

  Energies e = evaluate(x_);
  double energy = e.total();
  Eigen::VectorXd grad(nv), step(nv), trial(nv);
  double* hv = h_.valuePtr();
  // Adds a column-major block at the value positions `pos`.
  auto addAt = [hv](const int* pos, const double* m, int count) {
    for (int q = 0; q < count; ++q) hv[pos[q]] += m[q];
  };
  auto uOf = [&](int c) -> Mat34 {
    const int v = var_[static_cast<std::size_t>(c)];
    if (v < 0) return toU(transforms_[static_cast<std::size_t>(c)]);
    return Eigen::Map<const Mat34>(x_.data() + v);
  };

  for (int it = 0; it < options.max_iterations; ++it) {
    // Gradient (J^T r) of every term, and the varying part of J^T J (Rot, Length).
    std::copy(h_const_.valuePtr(), h_const_.valuePtr() + h_const_.nonZeros(), hv);
    grad.setZero();
    for (std::size_t pi = 0; pi < pairs_.size(); ++pi) {
      const Pair& p = pairs_[pi];
      const bool mi = moves(p.i), mj = moves(p.j);
      if (!mi && !mj) continue;
      const Mat34 ui = uOf(p.i), uj = uOf(p.j);
      const Eigen::Vector3d d = clusters_[static_cast<std::size_t>(p.i)].barycentre -
                                clusters_[static_cast<std::size_t>(p.j)].barycentre;
      const int vi = mi ? var_[static_cast<std::size_t>(p.i)] : -1,
                vj = mj ? var_[static_cast<std::size_t>(p.j)] : -1;
      if (vi >= 0) {
        const Mat34 gi = ui * p.sii - uj * p.sij.transpose() + d * p.mi.transpose();
        grad.segment<12>(vi) += w_.prop * p.omega * Eigen::Map<const Vec12>(gi.data());
      }
      if (vj >= 0) {
        const Mat34 gj = uj * p.sjj - ui * p.sij - d * p.mj.transpose();
        grad.segment<12>(vj) += w_.prop * p.omega * Eigen::Map<const Vec12>(gj.data());
      }
      const Eigen::Vector3d gap = d + translationOf(x_, p.i) - translationOf(x_, p.j);
      const double len = gap.norm();
      if (len > 1e-12) {
        const Eigen::Vector3d dir = gap / len;
        const double r = len - p.rest_length;
        const Eigen::Matrix3d jj = w_.length * dir * dir.transpose();
        const Eigen::Matrix3d neg = -jj;
        const int* pos = length_at_.data() + 36 * pi;  // ii, jj, ij, ji
        if (vi >= 0) {
          grad.segment<3>(vi + 9) += w_.length * r * dir;
          addAt(pos, jj.data(), 9);
        }
        if (vj >= 0) {
          grad.segment<3>(vj + 9) -= w_.length * r * dir;
          addAt(pos + 9, jj.data(), 9);
        }
        if (vi >= 0 && vj >= 0) {
          addAt(pos + 18, neg.data(), 9);
          addAt(pos + 27, neg.data(), 9);
        }
      }
    }
    for (std::size_t c = 0; c < clusters_.size(); ++c) {
      const int v = var_[c];
      if (!moves(static_cast<int>(c))) continue;
      Eigen::Matrix<double, 6, 1> r;
      Eigen::Matrix<double, 6, 9> j;
      rotResiduals(uOf(static_cast<int>(c)).leftCols<3>(), r, j);
      const double w = w_.detail * clusters_[c].rot_weight;
      grad.segment<9>(v) += w * j.transpose() * r;
      const Eigen::Matrix<double, 9, 9> jtj = w * j.transpose() * j;
      addAt(rot_at_.data() + 81 * (v / 12), jtj.data(), 81);
    }
    if (manip_active_) {
      const int v = var_[static_cast<std::size_t>(manipulated_)];
      const Mat34 g = uOf(manipulated_) * manip_s_ - manip_b_.transpose();
      grad.segment<12>(v) += w_.manip * Eigen::Map<const Vec12>(g.data());
    }
    // J^T J is only semi-definite and 1e-9 I can drown in rounding where the weights are large:
    // on failure, retry with a shift relative to the largest diagonal entry (a damped step).
    bool factored = factor_->factorize(h_);
    if (!factored) {
      double largest = 0;  // of the clusters that move (a held one's diagonal is 1)
      const int hb = held_ >= 0 ? var_[static_cast<std::size_t>(held_)] : -1;
      for (int k = 0; k < nv; ++k)
        if (hb < 0 || k < hb || k >= hb + 12) largest = std::max(largest, std::abs(h_.coeff(k, k)));
      for (double shift = 1e-12 * largest; !factored && shift <= 1e-3 * largest; shift *= 100) {
        for (int k = 0; k < nv; ++k) h_.coeffRef(k, k) += shift;
        factored = factor_->factorize(h_);
      }
    }
    if (!factored) throw std::runtime_error("Gauss-Newton: singular normal equations");
    factor_->solve(grad, step);
    step = -step;
    if (!step.allFinite()) throw std::runtime_error("Gauss-Newton: non-finite step");

    // Backtracking keeps every iteration a decrease (Rot and Length are not linear).
    double alpha = 1, trial_energy = energy;
    Energies te;
    bool ok = false;
    for (int k = 0; k < 10; ++k, alpha *= 0.5) {
      trial = x_ + alpha * step;
      te = evaluate(trial);
      trial_energy = te.total();
      if (trial_energy <= energy) {
        ok = true;
        break;
      }
    }
    ++st.iterations;
    if (!ok) {
      st.decreased = energy <= 1e-15;
      st.converged = st.decreased || alpha * step.norm() < 1e-12;
      break;
    }
    const double decrease = energy - trial_energy;
    x_ = trial;
    e = te;
    const double previous = energy;
    energy = trial_energy;
    if (decrease <= options.tolerance * std::max(previous, 1e-300) || energy < 1e-15) {
      st.converged = true;
      break;
    }
  }
  unpack(x_);
  st.energy = e;
  st.ms = sw.ms();
  return st;
}

}  // namespace hgd
