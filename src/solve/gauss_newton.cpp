// The Gauss-Newton loop of the cluster solver: the line search, the diagonal shifts that keep the
// system definite, and the reweighted E_Prop rounds (ClusterSolver::solve).
#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "hgdeform/solve/solver.h"
#include "solve/block_cholesky.h"
#include "solve/solver_terms.h"
#include "util/timer.h"

namespace hgd {

using solver_terms::Mat34;
using solver_terms::rotResiduals;
using solver_terms::toU;
using solver_terms::Vec12;

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
