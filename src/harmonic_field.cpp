#include "hgdeform/harmonic_field.h"

#include <Eigen/CholmodSupport>
#include <Eigen/Sparse>
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "timer.h"

#ifdef _OPENMP
#include <omp.h>
#endif

namespace hgd {

void HarmonicField::setInputCloud(const pcl::PointCloud<pcl::PointXYZ>::ConstPtr& cloud) {
  if (cloud != cloud_) graph_valid_ = false;
  cloud_ = cloud;
}

void HarmonicField::setInputNormals(const pcl::PointCloud<pcl::Normal>::ConstPtr& normals) {
  if (normals != input_normals_) graph_valid_ = false;
  input_normals_ = normals;
}

void HarmonicField::setPolygons(const std::vector<pcl::Vertices>& polygons) {
  polygons_ = polygons;
  graph_valid_ = false;
}

void HarmonicField::setHandles(const std::vector<std::vector<int>>& fixed,
                               const std::vector<int>& manipulated) {
  fixed_ = fixed;
  manipulated_ = manipulated;
}

void HarmonicField::setOptions(const FieldOptions& options) {
  if (options.k_neighbors != options_.k_neighbors || options.k_normals != options_.k_normals ||
      options.mesh_ring != options_.mesh_ring || options.normal_filter != options_.normal_filter ||
      options.orient_to_viewpoint != options_.orient_to_viewpoint || options.viewpoint != options_.viewpoint)
    graph_valid_ = false;
  options_ = options;
}

void HarmonicField::buildGraph() {
  const auto& pts = *cloud_;
  Stopwatch sw;
  const bool have_normals = input_normals_ && input_normals_->size() == pts.size();
  const bool mesh = !polygons_.empty();
  const bool ring = mesh && options_.mesh_ring;
  // One kNN query serves both normal estimation and the neighbour graph.
  const int k =
      (have_normals || mesh) ? options_.k_neighbors : std::max(options_.k_neighbors, options_.k_normals);
  if (!ring) knn_ = computeKnn(pts, k);
  timings_.knn_ms = sw.lap();
  if (have_normals) {
    normals_ = input_normals_;
  } else if (mesh) {
    auto n = meshNormals(pts, polygons_);
    // Vertices on no face: fall back to estimated normals so that they can still connect.
    bool missing = false;
    for (const auto& v : *n) missing = missing || !std::isfinite(v.normal_x);
    if (missing) {
      if (knn_.k == 0) knn_ = computeKnn(pts, options_.k_neighbors);
      auto est = estimateNormals(pts, knn_, options_.k_normals);
      for (std::size_t i = 0; i < n->size(); ++i)
        if (!std::isfinite((*n)[i].normal_x)) (*n)[i] = (*est)[i];
    }
    normals_ = n;
  } else {
    normals_ =
        estimateNormals(pts, knn_, options_.k_normals, options_.orient_to_viewpoint, options_.viewpoint);
  }
  timings_.normals_ms = sw.lap();
  graph_ = ring ? ringGraph(pts.size(), polygons_)
                : knnGraph(knn_, options_.k_neighbors, options_.normal_filter ? normals_.get() : nullptr);
  timings_.graph_ms = sw.lap();
  graph_valid_ = true;
}

void HarmonicField::compute(std::vector<float>& phi) {
  if (!cloud_ || cloud_->empty()) throw std::invalid_argument("HarmonicField: no input cloud");
  if (manipulated_.empty()) throw std::invalid_argument("HarmonicField: no manipulated handle");
  if (fixed_.empty()) throw std::invalid_argument("HarmonicField: no fixed handle");
  const std::size_t n = cloud_->size();
  std::vector<char> constrained(n, 0);
  std::vector<double> value(n, 0.0);
  auto mark = [&](const std::vector<int>& idx, double v) {
    for (int i : idx) {
      if (i < 0 || static_cast<std::size_t>(i) >= n)
        throw std::invalid_argument("HarmonicField: handle index " + std::to_string(i) + " out of range");
      constrained[static_cast<std::size_t>(i)] = 1;
      value[static_cast<std::size_t>(i)] = v;
    }
  };
  for (const auto& f : fixed_) mark(f, 0.0);
  mark(manipulated_, 1.0);  // a point in both keeps 1; resolveHandles rejects that earlier

  const double knn_ms = timings_.knn_ms, normals_ms = timings_.normals_ms, graph_ms = timings_.graph_ms;
  const bool rebuilt = !graph_valid_;
  if (rebuilt) buildGraph();
  FieldTimings t = timings_;
  if (!rebuilt) t.knn_ms = t.normals_ms = t.graph_ms = 0;  // cached: this compute() did not pay for them
  (void)knn_ms;
  (void)normals_ms;
  (void)graph_ms;
  solveDirichlet(graph_, constrained, value, options_, unreachable_, t);
  timings_ = t;
  phi.resize(n);
  for (std::size_t i = 0; i < n; ++i) phi[i] = static_cast<float>(std::clamp(value[i], 0.0, 1.0));
}

namespace {

using SpMat = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;
using RowMat = Eigen::SparseMatrix<double, Eigen::RowMajor, int>;

// y = A x for a row-major sparse matrix, in parallel.
// y = A x for the free block of the graph Laplacian: off-diagonal entries are all -1, so only
// the column indices are read (half the memory traffic of a general product).
void multiply(const RowMat& a, const Eigen::VectorXd& diag, const Eigen::VectorXd& x, Eigen::VectorXd& y) {
  const long long rows = a.rows();
  y.resize(a.rows());
  const int* outer = a.outerIndexPtr();
  const int* inner = a.innerIndexPtr();
#pragma omp parallel for schedule(static) if (rows > kParallelMin)
  for (long long r = 0; r < rows; ++r) {
    double s = 0;
    for (int m = outer[r]; m < outer[r + 1]; ++m) s += x[inner[m]];
    y[r] = (diag[r] + 1.0) * x[r] - s;  // the diagonal's own column was summed with the rest
  }
}

// Coarse points: a maximal distance-2 independent set of the graph (greedy), so that every
// point is within two hops of a coarse point and coarse points follow the graph's topology.
std::vector<int> coarsen(const RowMat& a, std::vector<int>& coarse_of) {
  const int n = static_cast<int>(a.rows());
  coarse_of.assign(static_cast<std::size_t>(n), -1);
  std::vector<char> blocked(static_cast<std::size_t>(n), 0);
  std::vector<int> coarse;
  const int* outer = a.outerIndexPtr();
  const int* inner = a.innerIndexPtr();
  for (int i = 0; i < n; ++i) {
    if (blocked[static_cast<std::size_t>(i)]) continue;
    coarse_of[static_cast<std::size_t>(i)] = static_cast<int>(coarse.size());
    coarse.push_back(i);
    blocked[static_cast<std::size_t>(i)] = 1;
    for (int m = outer[i]; m < outer[i + 1]; ++m) {
      const int j = inner[m];
      blocked[static_cast<std::size_t>(j)] = 1;
      for (int q = outer[j]; q < outer[j + 1]; ++q) blocked[static_cast<std::size_t>(inner[q])] = 1;
    }
  }
  return coarse;
}

// Prolongation: each fine point takes its coarse value (coarse points), else the mean of the
// coarse points among its neighbours, else of those two hops away.
RowMat prolongation(const RowMat& a, const std::vector<int>& coarse_of, int n_coarse) {
  const int n = static_cast<int>(a.rows());
  // Written straight into compressed rows (rows in order, columns sorted within each).
  std::vector<int> outer(static_cast<std::size_t>(n) + 1, 0), inner;
  std::vector<double> val;
  inner.reserve(static_cast<std::size_t>(n) * 3);
  val.reserve(static_cast<std::size_t>(n) * 3);
  const int* ao = a.outerIndexPtr();
  const int* ai = a.innerIndexPtr();
  std::vector<int> found;
  for (int i = 0; i < n; ++i) {
    found.clear();
    if (coarse_of[static_cast<std::size_t>(i)] >= 0) {
      found.push_back(coarse_of[static_cast<std::size_t>(i)]);
    } else {
      for (int m = ao[i]; m < ao[i + 1]; ++m)
        if (ai[m] != i && coarse_of[static_cast<std::size_t>(ai[m])] >= 0)
          found.push_back(coarse_of[static_cast<std::size_t>(ai[m])]);
      if (found.empty())
        for (int m = ao[i]; m < ao[i + 1]; ++m)
          for (int q = ao[ai[m]]; q < ao[ai[m] + 1]; ++q)
            if (coarse_of[static_cast<std::size_t>(ai[q])] >= 0)
              found.push_back(coarse_of[static_cast<std::size_t>(ai[q])]);
      std::sort(found.begin(), found.end());
      found.erase(std::unique(found.begin(), found.end()), found.end());
    }
    for (int c : found) {
      inner.push_back(c);
      val.push_back(1.0 / static_cast<double>(found.size()));
    }
    outer[static_cast<std::size_t>(i) + 1] = static_cast<int>(inner.size());
  }
  RowMat p(n, n_coarse);
  p.resizeNonZeros(static_cast<Eigen::Index>(inner.size()));
  std::copy(outer.begin(), outer.end(), p.outerIndexPtr());
  std::copy(inner.begin(), inner.end(), p.innerIndexPtr());
  std::copy(val.begin(), val.end(), p.valuePtr());
  return p;
}

// The Galerkin coarse operator P^T A P in one pass per coarse row (Eigen's two general sparse
// products cost three times as much): row I sums w_iI a_ij w_jJ over the fine rows i that I
// interpolates to, their neighbours j, and j's coarse points J. Rows run in parallel.
SpMat galerkin(const RowMat& a, const RowMat& p, const RowMat& pt) {
  const int nc = static_cast<int>(p.cols());
  int threads = 1;
#ifdef _OPENMP
  if (a.rows() > kParallelMin) threads = omp_get_max_threads();
#endif
  std::vector<std::vector<int>> cols(static_cast<std::size_t>(threads));
  std::vector<std::vector<double>> vals(static_cast<std::size_t>(threads));
  std::vector<int> row_nnz(static_cast<std::size_t>(nc) + 1, 0);
#pragma omp parallel num_threads(threads)
  {
    int t = 0;
#ifdef _OPENMP
    t = omp_get_thread_num();
#endif
    const int begin = static_cast<int>(static_cast<long long>(nc) * t / threads);
    const int end = static_cast<int>(static_cast<long long>(nc) * (t + 1) / threads);
    std::vector<double> acc(static_cast<std::size_t>(nc), 0.0);
    std::vector<int> slot(static_cast<std::size_t>(nc), -1), touched;
    auto& my_cols = cols[static_cast<std::size_t>(t)];
    auto& my_vals = vals[static_cast<std::size_t>(t)];
    for (int ci = begin; ci < end; ++ci) {
      touched.clear();
      for (RowMat::InnerIterator pi(pt, ci); pi; ++pi) {
        const int i = static_cast<int>(pi.index());
        for (RowMat::InnerIterator ai(a, i); ai; ++ai) {
          const double w = pi.value() * ai.value();
          for (RowMat::InnerIterator pj(p, ai.index()); pj; ++pj) {
            const int cj = static_cast<int>(pj.index());
            if (slot[static_cast<std::size_t>(cj)] < 0) {
              slot[static_cast<std::size_t>(cj)] = 1;
              touched.push_back(cj);
            }
            acc[static_cast<std::size_t>(cj)] += w * pj.value();
          }
        }
      }
      std::sort(touched.begin(), touched.end());
      for (int cj : touched) {
        my_cols.push_back(cj);
        my_vals.push_back(acc[static_cast<std::size_t>(cj)]);
        acc[static_cast<std::size_t>(cj)] = 0.0;
        slot[static_cast<std::size_t>(cj)] = -1;
      }
      row_nnz[static_cast<std::size_t>(ci) + 1] = static_cast<int>(touched.size());
    }
  }
  for (int ci = 0; ci < nc; ++ci)
    row_nnz[static_cast<std::size_t>(ci) + 1] += row_nnz[static_cast<std::size_t>(ci)];
  RowMat ac(nc, nc);
  ac.resizeNonZeros(row_nnz.back());
  std::copy(row_nnz.begin(), row_nnz.end(), ac.outerIndexPtr());
  std::size_t at = 0;
  for (int t = 0; t < threads; ++t) {
    std::copy(cols[static_cast<std::size_t>(t)].begin(), cols[static_cast<std::size_t>(t)].end(),
              ac.innerIndexPtr() + at);
    std::copy(vals[static_cast<std::size_t>(t)].begin(), vals[static_cast<std::size_t>(t)].end(),
              ac.valuePtr() + at);
    at += cols[static_cast<std::size_t>(t)].size();
  }
  return SpMat(ac);
}

// Two-grid preconditioned conjugate gradients: damped-Jacobi smoothing around an exact
// Galerkin coarse solve. Symmetric, so CG applies; converges in a few dozen iterations
// independently of the size.
bool solveMultilevel(const RowMat& a, const Eigen::VectorXd& b, Eigen::VectorXd& x, const FieldOptions& opt,
                     int& iterations) {
  std::vector<int> coarse_of;
  const std::vector<int> coarse = coarsen(a, coarse_of);
  const RowMat p = prolongation(a, coarse_of, static_cast<int>(coarse.size()));
  const RowMat pt = p.transpose();
  SpMat ac = galerkin(a, p, pt);
  // AMD alone (CHOLMOD's default also tries METIS, which costs more than it saves here), and
  // CHOLMOD's own choice of simplicial or supernodal: simplicial at 173k points (10k coarse
  // unknowns), supernodal at 1M.
  Eigen::CholmodDecomposition<SpMat, Eigen::Lower> coarse_solver;
  coarse_solver.setMode(Eigen::CholmodAuto);
  coarse_solver.cholmod().nmethods = 1;
  coarse_solver.cholmod().method[0].ordering = CHOLMOD_AMD;
  coarse_solver.compute(ac);
  if (coarse_solver.info() != Eigen::Success) return false;
  const Eigen::VectorXd diag = a.diagonal();
  const Eigen::VectorXd inv_diag = diag.cwiseInverse();
  const double omega = 0.6;
  Eigen::VectorXd t1, t2;
  auto precondition = [&](const Eigen::VectorXd& r, Eigen::VectorXd& z) {
    z = omega * inv_diag.cwiseProduct(r);
    multiply(a, diag, z, t1);
    Eigen::VectorXd rc = pt * (r - t1);
    z += p * coarse_solver.solve(rc);
    multiply(a, diag, z, t1);
    z += omega * inv_diag.cwiseProduct(r - t1);
  };
  // Initial guess: the coarse solution, prolonged.
  x = p * coarse_solver.solve(pt * b);
  Eigen::VectorXd r(b.size()), z, d, q;
  multiply(a, diag, x, t2);
  r = b - t2;
  const double bnorm = std::max(b.norm(), 1e-300);
  precondition(r, z);
  d = z;
  double rz = r.dot(z);
  iterations = 0;
  while (r.norm() / bnorm > opt.tolerance && iterations < opt.max_iterations) {
    multiply(a, diag, d, q);
    const double alpha = rz / d.dot(q);
    x += alpha * d;
    r -= alpha * q;
    precondition(r, z);
    const double rz_new = r.dot(z);
    d = z + (rz_new / rz) * d;
    rz = rz_new;
    ++iterations;
  }
  return r.norm() / bnorm <= opt.tolerance * 10;
}

}  // namespace

void solveDirichlet(const NeighborGraph& graph, const std::vector<char>& constrained,
                    std::vector<double>& value, const FieldOptions& options, std::vector<int>& unreachable,
                    FieldTimings& timings) {
  Stopwatch sw;
  const std::size_t n = graph.size();
  // Free points reachable from a constraint; the others cannot be given a harmonic value.
  std::vector<int> free_index(n, -1);
  std::vector<char> reached(n, 0);
  std::vector<int> stack;
  for (std::size_t i = 0; i < n; ++i)
    if (constrained[i]) {
      reached[i] = 1;
      stack.push_back(static_cast<int>(i));
    }
  while (!stack.empty()) {
    const int v = stack.back();
    stack.pop_back();
    for (const int* j = graph.begin(static_cast<std::size_t>(v)); j != graph.end(static_cast<std::size_t>(v));
         ++j)
      if (!reached[static_cast<std::size_t>(*j)]) {
        reached[static_cast<std::size_t>(*j)] = 1;
        stack.push_back(*j);
      }
  }
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
#pragma omp parallel for schedule(static) if (rows > kParallelMin)
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
  }
  if (!x.allFinite()) throw std::runtime_error("harmonic field: solver produced non-finite values");
  for (int r = 0; r < nf; ++r)
    value[static_cast<std::size_t>(free_points[static_cast<std::size_t>(r)])] = x[r];
  timings.solve_ms = sw.lap();
}

}  // namespace hgd
