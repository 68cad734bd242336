// The field's linear system: the uniform quasi-Laplacian D - W of the neighbour graph,
// restricted to the free points, with the handles' values on the right-hand side; solved
// exactly (CHOLMOD) or by the multilevel solver (multigrid.cpp).
#include "field/laplacian.h"

#include <Eigen/CholmodSupport>
#include <Eigen/Sparse>
#include <algorithm>
#include <stdexcept>
#include <string>

#include "field/multigrid.h"
#include "hgdeform/field/harmonic_field.h"
#include "util/parallel.h"
#include "util/phases.h"
#include "util/timer.h"

namespace hgd {

namespace {
using SpMat = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;
}  // namespace

void solveDirichlet(const NeighborGraph& graph, const std::vector<char>& constrained,
                    std::vector<double>& value, const FieldOptions& options, std::vector<int>& unreachable,
                    FieldTimings& timings, std::vector<int>* piece_out) {
  Stopwatch sw;
  PhaseClock clock;
  const std::size_t n = graph.size();
  // Free points reachable from a constraint (in a connected piece that holds one); the others
  // cannot be given a harmonic value.
  std::vector<int> free_index(n, -1), own_piece;
  std::vector<int>& piece = piece_out ? *piece_out : own_piece;
  std::vector<char> piece_reached(static_cast<std::size_t>(connectedComponents(graph, piece)), 0);
  for (std::size_t i = 0; i < n; ++i)
    if (constrained[i]) piece_reached[static_cast<std::size_t>(piece[i])] = 1;
  std::vector<char> reached(n);
  for (std::size_t i = 0; i < n; ++i) reached[i] = piece_reached[static_cast<std::size_t>(piece[i])];
  unreachable.clear();
  std::vector<int> free_points;
  for (std::size_t i = 0; i < n; ++i) {
    if (!reached[i]) {
      unreachable.push_back(static_cast<int>(i));
      value[i] = 0.0;
    } else if (!constrained[i]) {
      free_index[i] = static_cast<int>(free_points.size());
      free_points.push_back(static_cast<int>(i));
    }
  }
  const int nf = static_cast<int>(free_points.size());
  clock.lap("field.reach");
  if (nf == 0) {
    timings.laplacian_ms = sw.lap();
    timings.solve_ms = 0;
    return;
  }
  // Free block of D - W (uniform weights) and the right-hand side from constrained neighbours,
  // written straight into compressed rows (the graph's rows are sorted, and so stay the
  // columns, free indices growing with point indices).
  Eigen::VectorXd b = Eigen::VectorXd::Zero(nf);
  RowMat a(nf, nf);
  {
    std::vector<int> outer(static_cast<std::size_t>(nf) + 1, 0);
    for (int r = 0; r < nf; ++r) {
      const auto i = static_cast<std::size_t>(free_points[static_cast<std::size_t>(r)]);
      int c = 1;
      for (const int* j = graph.begin(i); j != graph.end(i); ++j)
        c += free_index[static_cast<std::size_t>(*j)] >= 0;
      outer[static_cast<std::size_t>(r) + 1] = outer[static_cast<std::size_t>(r)] + c;
    }
    a.resizeNonZeros(outer.back());
    std::copy(outer.begin(), outer.end(), a.outerIndexPtr());
    int* inner = a.innerIndexPtr();
    double* val = a.valuePtr();
    const long long rows = nf;
#pragma omp parallel for schedule(dynamic, kDynamicChunkCostly) if (rows > kParallelMin)
    for (long long rr = 0; rr < rows; ++rr) {
      const auto r = static_cast<std::size_t>(rr);
      const auto i = static_cast<std::size_t>(free_points[r]);
      int k = outer[r];
      bool diagonal_done = false;
      double rhs = 0;
      for (const int* j = graph.begin(i); j != graph.end(i); ++j) {
        const int fj = free_index[static_cast<std::size_t>(*j)];
        if (fj < 0) {
          rhs += value[static_cast<std::size_t>(*j)];
          continue;
        }
        if (!diagonal_done && fj > static_cast<int>(r)) {
          inner[k] = static_cast<int>(r);
          val[k++] = graph.degree(i);
          diagonal_done = true;
        }
        inner[k] = fj;
        val[k++] = -1.0;
      }
      if (!diagonal_done) {
        inner[k] = static_cast<int>(r);
        val[k++] = graph.degree(i);
      }
      b[static_cast<Eigen::Index>(r)] = rhs;
    }
  }
  a.makeCompressed();
  timings.laplacian_ms = sw.lap();
  clock.lap("field.laplacian");

  Eigen::VectorXd x;
  const bool exact =
      options.solver == FieldSolver::Exact ||
      (options.solver == FieldSolver::Auto && static_cast<std::size_t>(nf) <= options.exact_limit);
  timings.exact = exact;
  timings.iterations = 0;
  if (exact) {
    Eigen::CholmodSupernodalLLT<SpMat, Eigen::Lower> solver;
    solver.compute(SpMat(a));
    if (solver.info() != Eigen::Success)
      throw std::runtime_error("harmonic field: Cholesky factorisation failed");
    x = solver.solve(b);
  } else {
    if (!solveMultilevel(a, b, x, options, timings.iterations))
      throw std::runtime_error("harmonic field: multilevel solver did not converge in " +
                               std::to_string(options.max_iterations) + " iterations");
    clock.skip();  // (the multilevel solve records its own phases)
  }
  if (!x.allFinite()) throw std::runtime_error("harmonic field: solver produced non-finite values");
  for (int r = 0; r < nf; ++r)
    value[static_cast<std::size_t>(free_points[static_cast<std::size_t>(r)])] = x[r];
  timings.solve_ms = sw.lap();
  clock.lap("field.solve");
}

}  // namespace hgd
