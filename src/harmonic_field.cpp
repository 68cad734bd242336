#include "hgdeform/harmonic_field.h"

#include <Eigen/CholmodSupport>
#include <Eigen/Sparse>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include "parallel.h"
#include "timer.h"

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
  // Stored normals with inconsistent signs (merged scans, resampled meshes) would make the
  // filter see thin gaps everywhere: re-oriented like estimated ones (a unit-length copy).
  reoriented_ = false;
  if (have_normals && options_.normal_filter && !ring && knn_.k > 0 &&
      !consistentlyOriented(pts, *normals_, knn_, options_.k_neighbors)) {
    pcl::PointCloud<pcl::Normal>::Ptr unit(new pcl::PointCloud<pcl::Normal>(*normals_));
    for (auto& v : *unit) {
      const float len = v.getNormalVector3fMap().norm();
      v.getNormalVector3fMap() =
          len > 0 ? Eigen::Vector3f(v.getNormalVector3fMap() / len) : Eigen::Vector3f::UnitZ();
    }
    orientNormals(pts, knn_, options_.k_normals, *unit);
    normals_ = unit;
    reoriented_ = true;
  }
  timings_.normals_ms = sw.lap();
  dropped_.clear();
  if (ring) {
    graph_ = ringGraph(pts.size(), polygons_);
  } else {
    graph_ = knnGraph(knn_, options_.k_neighbors, options_.normal_filter ? normals_.get() : nullptr, &pts,
                      &dropped_);
    // Mesh edges are never dropped: the mesh says those vertices are adjacent.
    if (mesh) graph_ = unionGraph(graph_, ringGraph(pts.size(), polygons_));
  }
  // Stray points of a cloud hang from the surface as leaves, so that they cannot carry the
  // field across a gap (meshes have none).
  outliers_ = mesh ? std::vector<char>{} : findOutliers(pts, knn_);
  if (std::find(outliers_.begin(), outliers_.end(), 1) != outliers_.end()) {
    graph_ = attachOutliers(pts, graph_, knn_, outliers_);
    dropped_.erase(std::remove_if(dropped_.begin(), dropped_.end(),
                                  [&](const std::pair<int, int>& e) {
                                    return outliers_[static_cast<std::size_t>(e.first)] ||
                                           outliers_[static_cast<std::size_t>(e.second)];
                                  }),
                   dropped_.end());
  } else {
    outliers_.clear();
  }
  base_piece_.clear();
  if (!dropped_.empty()) connectedComponents(graph_, base_piece_);
  timings_.graph_ms = sw.lap();
  graph_valid_ = true;
}

void HarmonicField::joinPieces(const std::vector<char>& constrained) {
  // The normal filter never splits the surface: a piece of the filtered graph that holds no
  // handle, and that the filter alone cut off, is joined back through the dropped pairs that
  // lead out of it. Pieces that each hold a handle stay apart (a handle on one layer of a
  // sheet does not pull the other), also through a piece between them (three stacked plates,
  // handles on the outer two): pieces are merged in pair order, and a pair that would merge
  // two groups that each hold a handle is left out.
  joined_.clear();
  if (dropped_.empty()) return;
  const std::size_t pieces =
      base_piece_.empty()
          ? 0
          : static_cast<std::size_t>(*std::max_element(base_piece_.begin(), base_piece_.end())) + 1;
  std::vector<char> has_handle(pieces, 0);
  for (std::size_t i = 0; i < constrained.size(); ++i)
    if (constrained[i]) has_handle[static_cast<std::size_t>(base_piece_[i])] = 1;
  std::vector<int> parent(pieces);
  std::iota(parent.begin(), parent.end(), 0);
  const auto find = [&](int x) {
    while (parent[static_cast<std::size_t>(x)] != x) {
      parent[static_cast<std::size_t>(x)] =
          parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(x)])];
      x = parent[static_cast<std::size_t>(x)];
    }
    return x;
  };
  for (const auto& [a, b] : dropped_) {
    const int pa = base_piece_[static_cast<std::size_t>(a)], pb = base_piece_[static_cast<std::size_t>(b)];
    if (pa == pb || (has_handle[static_cast<std::size_t>(pa)] && has_handle[static_cast<std::size_t>(pb)]))
      continue;
    const int ra = find(pa), rb = find(pb);
    if (ra != rb) {
      if (has_handle[static_cast<std::size_t>(ra)] && has_handle[static_cast<std::size_t>(rb)]) continue;
      parent[static_cast<std::size_t>(rb)] = ra;
      has_handle[static_cast<std::size_t>(ra)] |= has_handle[static_cast<std::size_t>(rb)];
    }
    joined_.emplace_back(a, b);
  }
  if (!joined_.empty()) graph_joined_ = addEdges(graph_, joined_);
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
  Stopwatch sw_join;
  (void)knn_ms;
  (void)normals_ms;
  (void)graph_ms;
  joinPieces(constrained);
  t.graph_ms += sw_join.ms();
  solveDirichlet(graph(), constrained, value, options_, unreachable_, t, &piece_);
  timings_ = t;
  phi.resize(n);
  for (std::size_t i = 0; i < n; ++i) phi[i] = static_cast<float>(std::clamp(value[i], 0.0, 1.0));
}

namespace {

using SpMat = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;
using RowMat = Eigen::SparseMatrix<double, Eigen::RowMajor, int>;

// Sums body(begin, end) over fixed chunks of [0, n), in parallel when n is large. The chunks'
// sums are added in chunk order, so a dot product comes out the same whatever the threads.
template <typename Body>
double chunkedSum(long long n, Body&& body) {
  constexpr long long kChunk = 8192;
  const long long chunks = (n + kChunk - 1) / kChunk;
  std::vector<double> partial(static_cast<std::size_t>(chunks), 0.0);
#pragma omp parallel for schedule(static) if (n > kParallelMin)
  for (long long c = 0; c < chunks; ++c)
    partial[static_cast<std::size_t>(c)] = body(c * kChunk, std::min(n, (c + 1) * kChunk));
  double sum = 0;
  for (const double v : partial) sum += v;
  return sum;
}

// Calls f(r, (A x)_r) for every row r of a row-major sparse matrix, in parallel, and returns
// the sum of what f returns (for the dot products that ride along). `unit`: the free block of
// the graph Laplacian, whose off-diagonal entries are all -1, so only the column indices are
// read (half the memory traffic of a general product). The solver's vector updates are fused
// into these passes: at a million points it is bound by memory traffic, not arithmetic.
template <typename F>
double forRows(const RowMat& a, bool unit, const Eigen::VectorXd& diag, const Eigen::VectorXd& x, F&& f) {
  const int* outer = a.outerIndexPtr();
  const int* inner = a.innerIndexPtr();
  const double* val = a.valuePtr();
  const double* xp = x.data();
  const double* dp = diag.data();
  return chunkedSum(a.rows(), [&](long long begin, long long end) {
    double sum = 0;
    if (unit) {
      for (long long r = begin; r < end; ++r) {
        double s = 0;
        for (int m = outer[r]; m < outer[r + 1]; ++m) s += xp[inner[m]];
        sum += f(r, (dp[r] + 1.0) * xp[r] - s);  // the diagonal's own column was summed with the rest
      }
    } else {
      for (long long r = begin; r < end; ++r) {
        double s = 0;
        for (int m = outer[r]; m < outer[r + 1]; ++m) s += val[m] * xp[inner[m]];
        sum += f(r, s);
      }
    }
    return sum;
  });
}

// y = P x (or P^T x given as a row-major matrix).
void apply(const RowMat& p, const Eigen::VectorXd& x, Eigen::VectorXd& y) {
  y.resize(p.rows());
  double* yp = y.data();
  forRows(p, false, x, x, [yp](long long r, double px) {
    yp[r] = px;
    return 0.0;
  });
}

// Coarse points: a maximal distance-2 independent set of the matrix graph (greedy), so that
// every point is within two hops of a coarse point and coarse points follow the graph's
// topology.
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

// Assembles a row-major matrix from per-thread blocks of consecutive rows.
RowMat fromBlocks(int rows, int cols, std::vector<int>& row_nnz, const std::vector<std::vector<int>>& inner,
                  const std::vector<std::vector<double>>& val) {
  for (int r = 0; r < rows; ++r)
    row_nnz[static_cast<std::size_t>(r) + 1] += row_nnz[static_cast<std::size_t>(r)];
  RowMat m(rows, cols);
  m.resizeNonZeros(row_nnz.back());
  std::copy(row_nnz.begin(), row_nnz.end(), m.outerIndexPtr());
  std::size_t at = 0;
  for (std::size_t t = 0; t < inner.size(); ++t) {
    std::copy(inner[t].begin(), inner[t].end(), m.innerIndexPtr() + at);
    std::copy(val[t].begin(), val[t].end(), m.valuePtr() + at);
    at += inner[t].size();
  }
  return m;
}

// Prolongation: each fine point takes its coarse value (coarse points), else the mean of the
// coarse points among its neighbours, else of those two hops away (the union of its
// neighbours' rows). Rows in parallel; columns come out sorted, as coarse indices grow with
// point indices.
RowMat prolongation(const RowMat& a, const std::vector<int>& coarse_of, int n_coarse) {
  const int n = static_cast<int>(a.rows());
  const int* ao = a.outerIndexPtr();
  const int* ai = a.innerIndexPtr();
  const int* co = coarse_of.data();
  const long long rows = n;
  // Rows of the coarse points and their neighbours.
  std::vector<int> near(static_cast<std::size_t>(n) + 1, 0);
#pragma omp parallel for schedule(static) if (rows > kParallelMin)
  for (long long i = 0; i < rows; ++i) {
    int c = 0;
    if (co[i] >= 0)
      c = 1;
    else
      for (int m = ao[i]; m < ao[i + 1]; ++m) c += co[ai[m]] >= 0;
    near[static_cast<std::size_t>(i) + 1] = c;
  }
  for (int i = 0; i < n; ++i) near[static_cast<std::size_t>(i) + 1] += near[static_cast<std::size_t>(i)];
  std::vector<int> near_cols(static_cast<std::size_t>(near.back()));
#pragma omp parallel for schedule(static) if (rows > kParallelMin)
  for (long long i = 0; i < rows; ++i) {
    int at = near[static_cast<std::size_t>(i)];
    if (co[i] >= 0)
      near_cols[static_cast<std::size_t>(at)] = co[i];
    else
      for (int m = ao[i]; m < ao[i + 1]; ++m)
        if (co[ai[m]] >= 0) near_cols[static_cast<std::size_t>(at++)] = co[ai[m]];
  }
  const int threads = blockCount(n);
  std::vector<std::vector<int>> inner(static_cast<std::size_t>(threads));
  std::vector<std::vector<double>> val(static_cast<std::size_t>(threads));
  std::vector<int> row_nnz(static_cast<std::size_t>(n) + 1, 0);
  forBlocks(n, threads, [&](int begin, int end, int t) {
    auto& my_inner = inner[static_cast<std::size_t>(t)];
    auto& my_val = val[static_cast<std::size_t>(t)];
    my_inner.reserve(static_cast<std::size_t>(end - begin) * 3 / 2);
    my_val.reserve(static_cast<std::size_t>(end - begin) * 3 / 2);
    std::vector<int> found;
    for (int i = begin; i < end; ++i) {
      const int* b = near_cols.data() + near[static_cast<std::size_t>(i)];
      const int* e = near_cols.data() + near[static_cast<std::size_t>(i) + 1];
      if (b == e) {  // two hops from the nearest coarse points
        found.clear();
        for (int m = ao[i]; m < ao[i + 1]; ++m)
          found.insert(found.end(), near_cols.data() + near[static_cast<std::size_t>(ai[m])],
                       near_cols.data() + near[static_cast<std::size_t>(ai[m]) + 1]);
        std::sort(found.begin(), found.end());
        found.erase(std::unique(found.begin(), found.end()), found.end());
        b = found.data();
        e = found.data() + found.size();
      }
      const double w = 1.0 / static_cast<double>(e - b);
      my_inner.insert(my_inner.end(), b, e);
      my_val.insert(my_val.end(), static_cast<std::size_t>(e - b), w);
      row_nnz[static_cast<std::size_t>(i) + 1] = static_cast<int>(e - b);
    }
  });
  return fromBlocks(n, n_coarse, row_nnz, inner, val);
}

// The Galerkin coarse operator P^T A P in one pass per coarse row (Eigen's two general sparse
// products cost three times as much): row I sums w_iI a_ij w_jJ over the fine rows i that I
// interpolates to, their neighbours j, and j's coarse points J. Rows run in parallel.
RowMat galerkin(const RowMat& a, const RowMat& p, const RowMat& pt) {
  const int nc = static_cast<int>(p.cols());
  const int threads = blockCount(a.rows());
  std::vector<std::vector<int>> cols(static_cast<std::size_t>(threads));
  std::vector<std::vector<double>> vals(static_cast<std::size_t>(threads));
  std::vector<int> row_nnz(static_cast<std::size_t>(nc) + 1, 0);
  forBlocks(nc, threads, [&](int begin, int end, int t) {
    std::vector<double> acc(static_cast<std::size_t>(nc), 0.0);
    std::vector<int> slot(static_cast<std::size_t>(nc), -1), touched;
    auto& my_cols = cols[static_cast<std::size_t>(t)];
    auto& my_vals = vals[static_cast<std::size_t>(t)];
    const int *po = p.outerIndexPtr(), *pi = p.innerIndexPtr(), *to = pt.outerIndexPtr(),
              *ti = pt.innerIndexPtr(), *ao = a.outerIndexPtr(), *ai = a.innerIndexPtr();
    const double *pv = p.valuePtr(), *tv = pt.valuePtr(), *av = a.valuePtr();
    for (int ci = begin; ci < end; ++ci) {
      touched.clear();
      for (int m = to[ci]; m < to[ci + 1]; ++m) {
        const int i = ti[m];
        for (int q = ao[i]; q < ao[i + 1]; ++q) {
          const double w = tv[m] * av[q];
          const int j = ai[q];
          for (int s = po[j]; s < po[j + 1]; ++s) {
            const int cj = pi[s];
            if (slot[static_cast<std::size_t>(cj)] < 0) {
              slot[static_cast<std::size_t>(cj)] = 1;
              touched.push_back(cj);
            }
            acc[static_cast<std::size_t>(cj)] += w * pv[s];
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
  });
  return fromBlocks(nc, nc, row_nnz, cols, vals);
}

// A multigrid hierarchy for the free block of the Laplacian: each level's coarse points are a
// distance-2 independent set of its graph, prolongation averages, and the coarse operator is
// Galerkin's P^T A P, down to a level small enough for a sparse Cholesky factor. One cycle
// (damped Jacobi before and after the coarse correction, so the cycle is symmetric; a W-cycle
// below the finest level) is the preconditioner of conjugate gradients.
class Hierarchy {
 public:
  static constexpr int kDirect = 4000;  ///< coarsest level: at most this many unknowns
  static constexpr int kMaxLevels = 8;

  Hierarchy() = default;
  Hierarchy(const Hierarchy&) = delete;  // levels point into each other
  Hierarchy& operator=(const Hierarchy&) = delete;

  /// False when the coarsest level's Cholesky factorisation fails.
  bool build(const RowMat& a0) {
    levels_.reserve(kMaxLevels);  // Levels hold Eigen matrices, whose moves may copy: no reallocation
    levels_.emplace_back();
    levels_.back().a = &a0;
    levels_.back().unit = true;
    for (;;) {
      Level& l = levels_.back();
      l.diag = l.a->diagonal();
      l.inv_diag = l.diag.cwiseInverse();
      if (l.a->rows() <= kDirect || levels_.size() >= static_cast<std::size_t>(kMaxLevels)) break;
      std::vector<int> coarse_of;
      const std::vector<int> coarse = coarsen(*l.a, coarse_of);
      // Coarsening that stalls (a dense graph) gains little from another level, and the W-cycle
      // visits level l 2^(l-1) times: a level must at least halve the unknowns.
      if (coarse.size() * 2 > static_cast<std::size_t>(l.a->rows())) break;
      l.p = prolongation(*l.a, coarse_of, static_cast<int>(coarse.size()));
      l.pt = l.p.transpose();
      levels_.emplace_back();
      levels_.back().own = galerkin(*l.a, l.p, l.pt);
      levels_.back().a = &levels_.back().own;
    }
    // AMD alone (CHOLMOD's default also tries METIS, which costs more than it saves here), and
    // CHOLMOD's own choice of simplicial or supernodal.
    direct_.setMode(Eigen::CholmodAuto);
    direct_.cholmod().nmethods = 1;
    direct_.cholmod().method[0].ordering = CHOLMOD_AMD;
    direct_.compute(SpMat(*levels_.back().a));
    return direct_.info() == Eigen::Success;
  }

  /// Calls f(i, (A x)_i) over the finest level's rows; returns the sum of f.
  template <typename F>
  double forFineRows(const Eigen::VectorXd& x, F&& f) const {
    return forRows(*levels_.front().a, true, levels_.front().diag, x, std::forward<F>(f));
  }

  /// z = one cycle from level li applied to r: damped Jacobi, the coarse correction (twice
  /// below the finest level: a W-cycle, cheap there, and symmetric like the V), damped Jacobi.
  void cycle(std::size_t li, const Eigen::VectorXd& r, Eigen::VectorXd& z) {
    Level& l = levels_[li];
    if (li + 1 == levels_.size()) {
      z = direct_.solve(r);
      return;
    }
    constexpr double omega = 0.6;
    const int sweeps = li == 0 ? 1 : 2;  // the coarse levels are small: smooth them twice
    const int corrections = li == 0 ? 1 : 2;
    const long long n = l.a->rows();
    z.resize(n);
    l.t.resize(n);
    l.u.resize(n);
    const double* rp = r.data();
    const double* ip = l.inv_diag.data();
    double* zw = z.data();
#pragma omp parallel for schedule(static) if (n > kParallelMin)
    for (long long i = 0; i < n; ++i) zw[i] = omega * ip[i] * rp[i];
    auto sweep = [&]() {
      double* up = l.u.data();
      const double* zp = z.data();
      forRows(*l.a, l.unit, l.diag, z, [=](long long i, double az) {
        up[i] = zp[i] + omega * ip[i] * (rp[i] - az);
        return 0.0;
      });
      z.swap(l.u);
    };
    for (int s = 1; s < sweeps; ++s) sweep();
    for (int c = 0; c < corrections; ++c) {
      double* tp = l.t.data();
      forRows(*l.a, l.unit, l.diag, z, [=](long long i, double az) {
        tp[i] = rp[i] - az;
        return 0.0;
      });
      apply(l.pt, l.t, l.rc);
      cycle(li + 1, l.rc, l.zc);
      double* zp = z.data();
      forRows(l.p, false, l.zc, l.zc, [=](long long i, double pz) {
        zp[i] += pz;
        return 0.0;
      });
    }
    for (int s = 0; s < sweeps; ++s) sweep();
  }

  /// The coarsest level's exact solution of the restricted system, prolonged to the finest.
  void coarseGuess(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
    std::vector<Eigen::VectorXd> rs(levels_.size());
    rs[0] = b;
    for (std::size_t li = 0; li + 1 < levels_.size(); ++li) apply(levels_[li].pt, rs[li], rs[li + 1]);
    x = direct_.solve(rs.back());
    for (std::size_t li = levels_.size() - 1; li-- > 0;) {
      Eigen::VectorXd up;
      apply(levels_[li].p, x, up);
      x = std::move(up);
    }
  }

 private:
  struct Level {
    const RowMat* a = nullptr;
    RowMat own, p, pt;
    bool unit = false;  ///< off-diagonals all -1 (the finest level)
    Eigen::VectorXd diag, inv_diag;
    Eigen::VectorXd t, u, rc, zc;  // work vectors
  };
  std::vector<Level> levels_;
  Eigen::CholmodDecomposition<SpMat, Eigen::Lower> direct_;
};

// Multigrid-preconditioned conjugate gradients; converges in a few iterations independently
// of the size. False when it does not reach the tolerance; throws when the coarsest level
// cannot be factorised.
bool solveMultilevel(const RowMat& a, const Eigen::VectorXd& b, Eigen::VectorXd& x, const FieldOptions& opt,
                     int& iterations) {
  Hierarchy h;
  if (!h.build(a))
    throw std::runtime_error("harmonic field: the coarsest level's Cholesky factorisation failed");
  h.coarseGuess(b, x);
  const long long n = b.size();
  Eigen::VectorXd r(n), z, d, q(n);
  {
    double* rp = r.data();
    const double* bp = b.data();
    h.forFineRows(x, [=](long long i, double ax) {
      rp[i] = bp[i] - ax;
      return 0.0;
    });
  }
  const double bnorm = std::max(b.norm(), 1e-300);
  double rnorm = r.norm();
  h.cycle(0, r, z);
  d = z;
  double rz = r.dot(z);
  iterations = 0;
  // The field's error for a given relative residual grows about as sqrt(n) (max |dphi| against
  // the exact solve at 1e-3: 7e-4 at 60k points, 4.8e-3 at 1M, 6.1e-3 at 4M), so above a
  // million unknowns the tolerance tightens as 1 / sqrt(n).
  const double tolerance = opt.tolerance * std::min(1.0, std::sqrt(1e6 / static_cast<double>(n)));
  while (rnorm / bnorm > tolerance && iterations < opt.max_iterations) {
    double* qp = q.data();
    const double* dp = d.data();
    const double dq = h.forFineRows(d, [=](long long i, double ad) {
      qp[i] = ad;
      return dp[i] * ad;
    });
    const double alpha = rz / dq;
    double* xw = x.data();
    double* rw = r.data();
    const double rr = chunkedSum(n, [&](long long begin, long long end) {
      double part = 0;
      for (long long i = begin; i < end; ++i) {
        xw[i] += alpha * dp[i];
        rw[i] -= alpha * qp[i];
        part += rw[i] * rw[i];
      }
      return part;
    });
    rnorm = std::sqrt(rr);
    h.cycle(0, r, z);
    const double rz_new = r.dot(z);
    const double beta = rz_new / rz;
    {
      double* dw = d.data();
      const double* zp = z.data();
#pragma omp parallel for schedule(static) if (n > kParallelMin)
      for (long long i = 0; i < n; ++i) dw[i] = zp[i] + beta * dw[i];
    }
    rz = rz_new;
    ++iterations;
  }
  return rnorm / bnorm <= tolerance * 10;
}

}  // namespace

void solveDirichlet(const NeighborGraph& graph, const std::vector<char>& constrained,
                    std::vector<double>& value, const FieldOptions& options, std::vector<int>& unreachable,
                    FieldTimings& timings, std::vector<int>* piece_out) {
  Stopwatch sw;
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
