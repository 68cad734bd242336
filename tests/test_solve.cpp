// The solve stage (docs/method.md, section 5): the block Cholesky of the Gauss-Newton normal
// equations, and the cluster solver's reweighted and held solves.
#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

#include "../src/solve/block_cholesky.h"  // tested apart from the solver
#include "hgdeform/solve/solver.h"
#include "test_util.h"

// The Gauss-Newton normal equations are solved by a block Cholesky: on a random positive
// definite matrix of 12x12 blocks along a branched chain (with fill), its solution matches a
// dense solve, and an indefinite matrix is refused.
TEST(Solver, BlockCholeskyMatchesDenseSolve) {
  std::mt19937 rng(11);
  std::normal_distribution<double> gauss;
  const int nb = 40;
  std::vector<std::pair<int, int>> edges;
  for (int b = 0; b + 1 < nb; ++b) edges.emplace_back(b, b + 1);
  edges.emplace_back(5, 20);
  edges.emplace_back(10, 30);
  edges.emplace_back(0, 39);
  Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(12 * nb, 12 * nb);
  for (const auto& [i, j] : edges) {
    Eigen::Matrix<double, 12, 12> b;
    for (int q = 0; q < 144; ++q) b.data()[q] = (q % 5 == 0) ? 0.0 : gauss(rng);  // some zeros
    dense.block<12, 12>(12 * i, 12 * j) = b;
    dense.block<12, 12>(12 * j, 12 * i) = b.transpose();
  }
  for (int b = 0; b < nb; ++b) {
    Eigen::Matrix<double, 12, 12> m;
    for (int q = 0; q < 144; ++q) m.data()[q] = gauss(rng);
    dense.block<12, 12>(12 * b, 12 * b) =
        m * m.transpose() + 60.0 * Eigen::Matrix<double, 12, 12>::Identity();
  }
  Eigen::SparseMatrix<double> sparse = dense.sparseView(0.0, 0.0);
  // The pattern must hold whole blocks (explicit zeros too), as the solver's does.
  std::vector<Eigen::Triplet<double>> trip;
  for (int c = 0; c < 12 * nb; ++c)
    for (int r = 0; r < 12 * nb; ++r)
      if (dense.block<12, 12>(12 * (r / 12), 12 * (c / 12)).any() || r / 12 == c / 12)
        trip.emplace_back(r, c, dense(r, c));
  sparse.resize(12 * nb, 12 * nb);
  sparse.setFromTriplets(trip.begin(), trip.end());
  sparse.makeCompressed();
  hgd::BlockCholesky factor;
  factor.analyze(sparse);
  ASSERT_TRUE(factor.factorize(sparse));
  Eigen::VectorXd rhs(12 * nb);
  for (int q = 0; q < rhs.size(); ++q) rhs[q] = gauss(rng);
  Eigen::VectorXd x;
  factor.solve(rhs, x);
  const Eigen::VectorXd expected = dense.ldlt().solve(rhs);
  EXPECT_LT((x - expected).norm(), 1e-9 * expected.norm());
  EXPECT_LT((dense * x - rhs).norm(), 1e-9 * rhs.norm());
  // Indefinite: one diagonal block made negative.
  for (int k = 0; k < sparse.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(sparse, k); it; ++it)
      if (it.row() == it.col() && it.row() / 12 == 7) it.valueRef() = -100.0;
  EXPECT_FALSE(factor.factorize(sparse));
}

namespace {

/// A branching set of clusters like a limb's: a fixed root, a chain, a side branch, and the
/// manipulated cluster at the chain's end; points scattered about each barycentre.
std::vector<hgd::SolverCluster> limbClusters(bool manipulated_constant) {
  std::mt19937 rng(17);
  std::normal_distribution<double> jitter(0.0, 0.03);
  const std::vector<Eigen::Vector3d> centres = {{0, 0, 0},     {0.1, 0, 0},   {0.2, 0.01, 0}, {0.3, 0, 0.02},
                                                {0.2, 0.1, 0}, {0.2, 0.2, 0}, {0.4, 0, 0}};
  std::vector<hgd::SolverCluster> c(centres.size());
  for (std::size_t k = 0; k < c.size(); ++k) {
    for (int p = 0; p < 40; ++p)
      c[k].points.push_back(centres[k] + Eigen::Vector3d(jitter(rng), jitter(rng), jitter(rng)));
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    for (const auto& x : c[k].points) g += x;
    c[k].barycentre = g / static_cast<double>(c[k].points.size());
  }
  c[0].constant = true;
  c[6].constant = manipulated_constant;
  c[6].rot_weight = 7.2;
  return c;
}

const std::vector<std::pair<int, int>> kLimbEdges = {{0, 1}, {1, 2}, {2, 3}, {3, 6}, {2, 4}, {4, 5}, {0, 6}};

double largestDifference(const std::vector<hgd::NormalisedTransform>& a,
                         const std::vector<hgd::NormalisedTransform>& b) {
  double d = 0;
  for (std::size_t k = 0; k < a.size(); ++k)
    d = std::max({d, (a[k].A - b[k].A).cwiseAbs().maxCoeff(), (a[k].t - b[k].t).cwiseAbs().maxCoeff()});
  return d;
}

}  // namespace

// The reweighted E_Prop (GaussNewtonOptions::reweight_rounds) starts every solve from uniform
// weights: a solve from a start gives the same transforms whatever the solver solved before,
// and it is not the paper's solve (the weights do change the result).
TEST(Deform, ReweightedSolveDependsOnlyOnItsStart) {
  const int mc = 6;
  hgd::NormalisedTransform move;
  move.A = Eigen::AngleAxisd(0.5, Eigen::Vector3d(0.2, 0.3, 1).normalized()).toRotationMatrix();
  move.t = Eigen::Vector3d(0.05, 0.12, -0.03);
  std::vector<hgd::NormalisedTransform> start(7), other(7);
  start[mc] = move;
  other[mc].t = Eigen::Vector3d(-0.1, 0.02, 0.08);
  hgd::GaussNewtonOptions reweighted;
  reweighted.reweight_rounds = 8;

  hgd::ClusterSolver fresh;
  fresh.setup(limbClusters(true), kLimbEdges, mc, hgd::SolverWeights{});
  fresh.setTransforms(start);
  const hgd::SolveStats st = fresh.solve(reweighted);
  EXPECT_TRUE(st.converged);

  hgd::ClusterSolver used;
  used.setup(limbClusters(true), kLimbEdges, mc, hgd::SolverWeights{});
  used.setTransforms(other);
  used.solve(reweighted);
  used.setTransforms(start);
  used.solve(reweighted);
  EXPECT_LT(largestDifference(used.transforms(), fresh.transforms()), 1e-12);
  // The energy reported is the paper's, of the result.
  EXPECT_NEAR(st.energy.total(), fresh.energies().total(), 1e-12 * st.energy.total());

  hgd::ClusterSolver paper;
  paper.setup(limbClusters(true), kLimbEdges, mc, hgd::SolverWeights{});
  paper.setTransforms(start);
  paper.solve();
  EXPECT_GT(largestDifference(paper.transforms(), fresh.transforms()), 1e-3);
  // The paper's solve minimises the paper's energy: the reweighted result has more of it.
  EXPECT_GT(fresh.energies().total(), paper.energies().total());
}

// A frame move holds the manipulated cluster (ClusterSolver::hold) in the solver that drags it,
// instead of setting up a second solver in which it is constant. Both must give the same
// transforms and the same energy (its own Rot and the pair whose ends both stand still are
// constant terms, left out), and releasing it must give back the drag's coupling exactly.
TEST(Deform, HoldingTheHandleSolvesAsIfItWereConstant) {
  const int mc = 6;
  hgd::NormalisedTransform move;
  // Not a rotation (a frame move may scale): the held cluster's Rot is a nonzero constant.
  move.A = Eigen::AngleAxisd(0.6, Eigen::Vector3d(0.3, 0.2, 1).normalized()).toRotationMatrix() *
           Eigen::Vector3d(1.1, 1, 0.95).asDiagonal();
  move.t = Eigen::Vector3d(0.05, 0.12, -0.03);
  const hgd::NormalisedTransform identity;

  // The reference: the manipulated cluster constant from the setup on (the pre-switch way).
  hgd::ClusterSolver constant;
  constant.setup(limbClusters(true), kLimbEdges, mc, hgd::SolverWeights{});
  std::vector<hgd::NormalisedTransform> start(7, identity);
  start[mc] = move;
  constant.setTransforms(start);
  const hgd::SolveStats ref = constant.solve();
  ASSERT_TRUE(ref.converged);

  // One solver: a drag first (E_Manip active), then the hold, from the same warm start.
  hgd::ClusterSolver solver;
  solver.setup(limbClusters(false), kLimbEdges, mc, hgd::SolverWeights{});
  const std::vector<Eigen::Vector3d> rest = {{0.4, 0, 0}, {0.45, 0.02, 0}, {0.38, -0.02, 0.01}};
  const std::vector<Eigen::Vector3d> target = {{0.4, 0.1, 0}, {0.45, 0.12, 0}, {0.38, 0.08, 0.01}};
  solver.setManipulation(rest, target, {1.0, 1.0, 1.0});
  solver.solve();
  const std::vector<hgd::NormalisedTransform> dragged = solver.transforms();
  solver.setTransforms(start);
  solver.hold(mc, move);
  EXPECT_EQ(solver.held(), mc);
  const hgd::SolveStats held = solver.solve();
  // Measured: 0 (the same arithmetic up to the elimination order); the margin is round-off.
  EXPECT_LT(largestDifference(solver.transforms(), constant.transforms()), 1e-12);
  EXPECT_NEAR(held.energy.total(), ref.energy.total(), 1e-12 * ref.energy.total());
  EXPECT_EQ(held.iterations, ref.iterations);
  // The held transform is the one given, exactly: the solve never moved it.
  EXPECT_EQ(solver.transforms()[mc].A, move.A);
  EXPECT_EQ(solver.transforms()[mc].t, move.t);
  // The coupling to the rest matters: the chain's end next to the handle followed it.
  EXPECT_GT((solver.transforms()[3].t - identity.t).norm(), 0.2 * move.t.norm());

  // Released, the handle is free again: solved from the held state with no E_Manip, it moves as
  // in a solver where it was always free (the coupling is back in the normal equations).
  solver.release();
  solver.setTransforms(start);
  solver.solve();
  hgd::ClusterSolver free;
  free.setup(limbClusters(false), kLimbEdges, mc, hgd::SolverWeights{});
  free.setTransforms(start);
  free.solve();
  EXPECT_LT(largestDifference(solver.transforms(), free.transforms()), 1e-12);
  EXPECT_GT((solver.transforms()[mc].A - move.A).norm(), 1e-3);  // it did move

  // And the same drag from the same start gives the drag's transforms again.
  solver.setTransforms(std::vector<hgd::NormalisedTransform>(7, identity));
  solver.setManipulation(rest, target, {1.0, 1.0, 1.0});
  solver.solve();
  EXPECT_LT(largestDifference(solver.transforms(), dragged), 1e-12);
  EXPECT_THROW(solver.hold(0, move), std::logic_error);  // a fixed cluster has no unknowns
}
