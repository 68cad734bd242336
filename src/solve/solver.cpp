// The cluster solver (ClusterSolver): its set-up, its state (transforms, manipulation, a held
// cluster) and its energies. (The normal equations: normal_equations.cpp; the Gauss-Newton loop:
// gauss_newton.cpp; their block Cholesky: block_cholesky.cpp.)
#include "hgdeform/solve/solver.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "solve/block_cholesky.h"
#include "solve/solver_terms.h"

namespace hgd {

using solver_terms::Mat34;
using solver_terms::rotResiduals;
using solver_terms::toU;

ClusterSolver::ClusterSolver() : factor_(std::make_unique<BlockCholesky>()) {}
ClusterSolver::~ClusterSolver() = default;
ClusterSolver::ClusterSolver(ClusterSolver&&) noexcept = default;
ClusterSolver& ClusterSolver::operator=(ClusterSolver&&) noexcept = default;

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

}  // namespace hgd
