#include "hgdeform/multires/multires.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <numeric>
#include <stdexcept>
#include <string>

#include "graph/nearest.h"
#include "hgdeform/io/geometry.h"
#include "interp/table_build.h"
#include "multires/prolong_labels.h"
#include "util/parallel.h"
#include "util/phases.h"
#include "util/radix_sort.h"
#include "util/uninit.h"

namespace hgd {

namespace {

int bitsFor(std::uint64_t v) {
  int b = 0;
  while (v >> b) ++b;
  return b;
}

// n zeros, written on every thread (a vector's own zeroing is one serial pass that also takes
// every page fault of the fresh memory: 4 MB of flags at 4M points).
template <typename T>
UninitVector<T> zeros(std::size_t n) {
  UninitVector<T> v(n);
  const long long nn = static_cast<long long>(n);
#pragma omp parallel for schedule(dynamic, dynamicChunk(nn)) if (nn > kParallelMin)
  for (long long i = 0; i < nn; ++i) v[static_cast<std::size_t>(i)] = T{0};
  return v;
}

// Cell keys of a voxel grid: class in the high bits, then z, y, x.
struct Grid {
  Eigen::Vector3f lo;
  float h = 1;
  int axis_bits = 0;
  /// p's place in cell sides from lo: its cell along an axis is cellOf of that coordinate.
  Eigen::Vector3f sides(const Eigen::Vector3f& p) const { return (p - lo) / h; }
  std::uint64_t key(const Eigen::Vector3f& p, int cls) const {
    const Eigen::Vector3f r = sides(p);
    return keyOf(cellOf(r.x()), cellOf(r.y()), cellOf(r.z()), cls);
  }
  /// key(p, cls), and in `centre2` the squared distance from p to its cell's centre, in sides.
  std::uint64_t key(const Eigen::Vector3f& p, int cls, float& centre2) const {
    const Eigen::Vector3f r = sides(p);
    const std::uint64_t x = cellOf(r.x()), y = cellOf(r.y()), z = cellOf(r.z());
    const Eigen::Vector3f q(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
    centre2 = (r - q - Eigen::Vector3f::Constant(0.5f)).squaredNorm();
    return keyOf(x, y, z, cls);
  }

  // The cell along an axis: r's floor, at least 0. Every point is at or above lo (the cloud's
  // lowest corner: coarsen() sets it), so r >= 0, and a non-negative r's floor is its truncation
  // (r < 2^18: at most 2^17 cells an axis); a negative or NaN r takes 0 (for a negative r the
  // centre distance would then be measured from cell 0's centre, not floor(r)'s). Truncation,
  // not floor() and max(): without SSE4.1 those compiled to branches each and kept key() out of
  // line, and the pass over every point took 12 ns a point (7 now).
  static std::uint64_t cellOf(float r) {
    return r > 0 ? static_cast<std::uint64_t>(static_cast<std::int32_t>(r)) : 0;
  }

 private:
  std::uint64_t keyOf(std::uint64_t x, std::uint64_t y, std::uint64_t z, int cls) const {
    return (((static_cast<std::uint64_t>(cls) << axis_bits | z) << axis_bits | y) << axis_bits) | x;
  }
};

// The cells of a grid over a cloud, kept as runs: consecutive points (in the cloud's order) in
// one cell. A shape's points come in Morton order (Geometry), so a cell's points lie in a few
// runs (870,000 for 4,000,000 points in 68,000 cells), and the cells are found by sorting the
// runs, not the points: no key or sorted position is stored per point, and each run keeps its
// point nearest the cell's centre, found in the same pass.
struct Cells {
  // The runs, in the cloud's order (cut where the blocks of the pass that found them end).
  // (Not zeroed first: every element is written, on every thread, before it is read.)
  UninitVector<std::uint32_t> run_start;  ///< run r: points run_start[r] .. run_start[r + 1] - 1
  UninitVector<std::uint32_t> run_best;   ///< its point nearest the cell's centre (the first of equals)
  UninitVector<float> run_best_d;         ///< that point's squared distance to the centre
  UninitVector<std::uint32_t> run_cell;   ///< its cell
  // The cells in key order (neighbouring cells near in memory), each with its runs in order.
  UninitVector<std::uint32_t> runs;  ///< run indices, by cell
  std::vector<std::uint32_t> first;  ///< cell c's runs: runs[first[c]] .. runs[first[c + 1] - 1]
  std::vector<std::uint64_t> key;    ///< cell c's key
  std::vector<std::uint32_t> size;   ///< its points
  std::size_t count() const { return key.size(); }
  /// Calls fn(i) for each point i of cell c, ascending, until fn returns false; false then.
  template <typename Fn>
  bool eachPoint(std::size_t c, Fn&& fn) const {
    for (std::uint32_t s = first[c]; s < first[c + 1]; ++s)
      for (std::uint32_t i = run_start[runs[s]]; i < run_start[runs[s] + 1]; ++i)
        if (!fn(static_cast<std::size_t>(i))) return false;
    return true;
  }
};

// Every point's cell, as runs (each with its point nearest the cell's centre), then the cells
// from the runs sorted by key (stably: a cell's runs, and so its points, stay in order).
Cells findCells(const pcl::PointCloud<pcl::PointXYZ>& points, const UninitVector<std::uint16_t>& cls,
                const Grid& grid, std::uint64_t max_key) {
  Cells out;
  const long long n = static_cast<long long>(points.size());
  const int blocks = chunkCount(n);
  // Each block's runs, written without a branch per point: whether a point starts a run, and
  // whether it is the nearest so far, follow no pattern, and with branches this pass took 82 ms
  // on 4,000,000 points, without 42 ms (one thread). The run being read is written at its place
  // on every point; the next run starts one place on.
  // Block b writes its runs from blockStart(n, blocks, b) on, in arrays with room for a run per
  // point, one array for all blocks: only the pages the runs found fall in are touched, by the
  // thread that finds them, and the arrays are freed once the runs are copied out. (An array per
  // block cost 4.5 ms a build at 4,000,000 points on the main thread: malloc writes a header at
  // each array's end, and each such first touch zeroes a huge page there.)
  // (Allocated here, not in the loop, so that running out of memory throws to the caller rather
  // than ending the program from a worker thread.)
  const auto nn = static_cast<std::size_t>(n);
  UninitVector<std::uint32_t> all_start(nn), all_best(nn), all_best_d(nn);  // (best_d: a float's bits)
  UninitVector<std::uint64_t> all_key(nn);
  std::vector<std::size_t> found(static_cast<std::size_t>(blocks), 0);
  forChunks(n, blocks, [&](int begin, int end, int b) {
    std::uint32_t* const p_start = all_start.data() + begin;
    std::uint32_t* const p_best = all_best.data() + begin;
    std::uint32_t* const p_best_d = all_best_d.data() + begin;
    std::uint64_t* const p_key = all_key.data() + begin;
    // The squared distances are not negative, so their bits order as they do; a new run's
    // distance so far is all ones, above every distance. No key is all ones (at most 63 bits).
    std::size_t r = ~std::size_t{0};
    std::uint64_t key = ~std::uint64_t{0};
    std::uint32_t start = 0, best = 0, best_d = 0;
    for (auto i = static_cast<std::uint32_t>(begin); i < static_cast<std::uint32_t>(end); ++i) {
      float d = 0;
      const std::uint64_t k = grid.key(points[i].getVector3fMap(), cls[i], d);
      std::uint32_t bits = 0;
      std::memcpy(&bits, &d, sizeof bits);
      const auto fresh = static_cast<std::uint32_t>(k != key);
      const std::uint32_t all = 0u - fresh;  // all ones where a run starts
      r += fresh;
      key = k;
      start = (i & all) | (start & ~all);
      const std::uint32_t so_far = best_d | all;
      const std::uint32_t nearer = 0u - static_cast<std::uint32_t>(bits < so_far);
      best = (i & nearer) | (best & ~nearer);
      best_d = (bits & nearer) | (so_far & ~nearer);
      p_start[r] = start;
      p_key[r] = key;
      p_best[r] = best;
      p_best_d[r] = best_d;
    }
    found[static_cast<std::size_t>(b)] = r + 1;  // (none: ~0 + 1)
  });
  std::vector<std::size_t> at(static_cast<std::size_t>(blocks) + 1, 0);
  for (std::size_t b = 0; b < found.size(); ++b) at[b + 1] = at[b] + found[b];
  const std::size_t runs = at.back();
  out.run_start.resize(runs + 1);
  out.run_best.resize(runs);
  out.run_best_d.resize(runs);
  UninitVector<std::uint64_t> sorted_key(runs);
  out.runs.resize(runs);
  forChunks(n, blocks, [&](int begin, int, int b) {
    const auto from = static_cast<std::size_t>(begin), m = found[static_cast<std::size_t>(b)];
    const std::size_t o = at[static_cast<std::size_t>(b)];
    std::memcpy(out.run_start.data() + o, all_start.data() + from, m * sizeof(std::uint32_t));
    std::memcpy(sorted_key.data() + o, all_key.data() + from, m * sizeof(std::uint64_t));
    std::memcpy(out.run_best.data() + o, all_best.data() + from, m * sizeof(std::uint32_t));
    std::memcpy(out.run_best_d.data() + o, all_best_d.data() + from, m * sizeof(float));
    for (std::size_t k = 0; k < m; ++k) out.runs[o + k] = static_cast<std::uint32_t>(o + k);
  });
  all_start = {};
  all_best = {};
  all_best_d = {};
  all_key = {};
  out.run_start[runs] = static_cast<std::uint32_t>(n);
  radixSort(sorted_key, out.runs, max_key, 11);
  // The cells: where the sorted keys change.
  const std::vector<int> changes = indicesWhere(static_cast<long long>(runs), [&](std::size_t s) {
    return s == 0 || sorted_key[s] != sorted_key[s - 1];
  });
  out.first.assign(changes.begin(), changes.end());
  const std::size_t cells = out.first.size();
  out.first.push_back(static_cast<std::uint32_t>(runs));
  out.key.resize(cells);
  out.size.resize(cells);
  out.run_cell.resize(runs);
  const long long cc = static_cast<long long>(cells);
#pragma omp parallel for schedule(dynamic, kDynamicChunkCostly) if (n > kParallelMin)
  for (long long c = 0; c < cc; ++c) {
    const auto cell = static_cast<std::size_t>(c);
    out.key[cell] = sorted_key[out.first[cell]];
    std::uint32_t size = 0;
    for (std::uint32_t s = out.first[cell]; s < out.first[cell + 1]; ++s) {
      const std::uint32_t r = out.runs[s];
      out.run_cell[r] = static_cast<std::uint32_t>(cell);
      size += out.run_start[r + 1] - out.run_start[r];
    }
    out.size[cell] = size;
  }
  return out;
}

// The cells a grid would have over the sampled points (positions and classes, packed).
std::size_t countCells(const std::vector<Eigen::Vector3f>& points, const std::vector<std::uint16_t>& cls,
                       const Grid& grid, std::uint64_t max_key) {
  // (Every step on every thread: up to eight rounds of this size the grid before the build.)
  const std::size_t m = points.size();
  if (m == 0) return 0;
  UninitVector<std::uint64_t> keys(m);
  UninitVector<std::uint32_t> payload(m);
  const long long mm = static_cast<long long>(m);
#pragma omp parallel for schedule(static) if (mm > kParallelMin)
  for (long long k = 0; k < mm; ++k) {
    keys[static_cast<std::size_t>(k)] =
        grid.key(points[static_cast<std::size_t>(k)], cls[static_cast<std::size_t>(k)]);
    payload[static_cast<std::size_t>(k)] = static_cast<std::uint32_t>(k);
  }
  radixSort(keys, payload, max_key, 11);
  long long changes = 0;
#pragma omp parallel for schedule(static) reduction(+ : changes) if (mm > kParallelMin)
  for (long long k = 1; k < mm; ++k)
    changes += keys[static_cast<std::size_t>(k)] != keys[static_cast<std::size_t>(k - 1)];
  return static_cast<std::size_t>(changes) + 1;
}

// Stray points of a scan are alone in their cells, and a coarse level of them would be mostly
// strays where the cloud holds a few (the field's own test for strays, findOutliers, expects
// them rare), and a stray between two parts would join them. So in cells that hold few points
// where a cell typically holds four or more, a free point with fewer than two other points
// within three times the typical distance to the second nearest (at most a cell side) is a
// stray: no coarse point (as findOutliers' strays hang from the surface at full resolution).
UninitVector<char> findStrays(const pcl::PointCloud<pcl::PointXYZ>& points, const Grid& grid,
                              std::size_t classes, const Cells& cell_points) {
  const std::size_t n = points.size(), cells = cell_points.count();
  UninitVector<char> stray = zeros<char>(n);
  const std::vector<std::uint64_t>& cell_key = cell_points.key;
  std::vector<std::uint32_t> size = cell_points.size;
  std::nth_element(size.begin(), size.begin() + static_cast<long>(cells / 2), size.end());
  const std::size_t median = size[cells / 2];
  if (median < 4) return stray;
  const int ab = grid.axis_bits;
  const std::uint64_t axis_mask = (std::uint64_t{1} << ab) - 1;
  // Calls fn(j) for every point j in the 3 x 3 x 3 cells around point i, of every class, until
  // fn returns false, but for the cells that cannot hold a point within sqrt(reach()) of point i
  // (asked before each row: it may shrink as fn finds points). What fn is given differs, not
  // what it concludes: the second nearest distance, or whether two points lie within a limit.
  // Its own row first, then the rows beside it (the 27 cells, each with a binary search, took
  // 10 us a point on one thread at 4M points).
  auto around = [&](std::size_t i, auto&& reach, auto&& fn) {
    // Its cell, as its key has it.
    const Eigen::Vector3f r = grid.sides(points[i].getVector3fMap());
    const long long cell[3] = {static_cast<long long>(Grid::cellOf(r.x())),
                               static_cast<long long>(Grid::cellOf(r.y())),
                               static_cast<long long>(Grid::cellOf(r.z()))};
    const long long x = cell[0], y = cell[1], z = cell[2];
    const auto top = static_cast<long long>(axis_mask);
    // gap2[a][d + 1]: the squared distance, in cell sides, from p to the cells at offset d along
    // axis a, less a margin above what rounding can move a point (r is computed as every key
    // is, to a few units in the last place of r): never more than a point there can be from p.
    // (A side whose square is not a normal float skips nothing: the products below could round
    // to infinity or lose their margin.)
    const float h2 = grid.h * grid.h;
    const bool skips = std::isfinite(h2) && h2 >= std::numeric_limits<float>::min();
    float gap2[3][3];
    for (int a = 0; a < 3; ++a) {
      const float margin = 1e-3f + 1e-6f * r[a], below = r[a] - static_cast<float>(cell[a]);
      const float lower = std::max(0.0f, below - margin), upper = std::max(0.0f, 1.0f - below - margin);
      gap2[a][0] = skips ? lower * lower : 0.0f;
      gap2[a][1] = 0;
      gap2[a][2] = skips ? upper * upper : 0.0f;
    }
    constexpr int kOrder[3] = {0, -1, 1};
    for (const int dz : kOrder)
      for (const int dy : kOrder) {
        if (y + dy < 0 || z + dz < 0 || y + dy > top || z + dz > top) continue;
        const float row2 = gap2[2][dz + 1] + gap2[1][dy + 1], limit = reach();
        if (row2 * h2 > limit) continue;
        // x is the lowest field of a key: the cells of a row are one run of keys.
        const long long x0 = std::max(0LL, x - ((row2 + gap2[0][0]) * h2 > limit ? 0 : 1)),
                        x1 = std::min(top, x + ((row2 + gap2[0][2]) * h2 > limit ? 0 : 1));
        const auto row = static_cast<std::uint64_t>(((z + dz) << (2 * ab)) | ((y + dy) << ab));
        for (std::size_t c = 0; c < classes; ++c) {
          const std::uint64_t base = (static_cast<std::uint64_t>(c) << (3 * ab)) | row;
          const std::uint64_t first = base | static_cast<std::uint64_t>(x0),
                              last = base | static_cast<std::uint64_t>(x1);
          for (auto it = std::lower_bound(cell_key.begin(), cell_key.end(), first);
               it != cell_key.end() && *it <= last; ++it)
            if (!cell_points.eachPoint(static_cast<std::size_t>(it - cell_key.begin()), fn)) return;
        }
      }
  };
  // The typical distance to the second nearest point, over about 2,000 points of full cells
  // (on every thread, kept in sample order): every stride-th point, the cells in key order.
  const std::size_t stride = std::max<std::size_t>(1, n / 2000);
  const long long samples = static_cast<long long>((n + stride - 1) / stride);
  std::vector<std::size_t> cell_at(cells + 1, 0);  // where each cell's points start in that order
  for (std::size_t c = 0; c < cells; ++c) cell_at[c + 1] = cell_at[c] + cell_points.size[c];
  std::vector<float> second(static_cast<std::size_t>(samples), INFINITY);
#pragma omp parallel for schedule(dynamic, 16) if (samples > 256 && n > kParallelMin)
  for (long long s = 0; s < samples; ++s) {
    const std::size_t at = static_cast<std::size_t>(s) * stride;
    const auto c =
        static_cast<std::size_t>(std::upper_bound(cell_at.begin(), cell_at.end(), at) - cell_at.begin()) - 1;
    std::size_t i = 0, k = cell_at[c];
    cell_points.eachPoint(c, [&](std::size_t j) {
      i = j;
      return k++ < at;
    });
    float d1 = INFINITY, d2 = INFINITY;
    around(
        i, [&] { return d2; },
        [&](std::size_t j) {
          if (j == i) return true;
          const float d = (points[j].getVector3fMap() - points[i].getVector3fMap()).squaredNorm();
          if (d < d1) {
            d2 = d1;
            d1 = d;
          } else if (d < d2) {
            d2 = d;
          }
          return true;
        });
    second[static_cast<std::size_t>(s)] = d2;
  }
  std::vector<float> typical;
  for (const float d2 : second)
    if (std::isfinite(d2) && d2 > 0) typical.push_back(d2);
  if (typical.empty()) return stray;
  // Three times the median distance, but never under the sparsest 3%'s (a scan whose density
  // falls off with range has no strays for that, as findOutliers rules), at most a cell side.
  const auto at = [&](std::size_t k) {
    std::nth_element(typical.begin(), typical.begin() + static_cast<long>(k), typical.end());
    return typical[k];
  };
  const float limit2 =
      std::min(grid.h * grid.h, std::max(9.0f * at(typical.size() / 2), at(typical.size() * 97 / 100)));
  if (!(limit2 > 0)) return stray;  // duplicates everywhere: no verdict
  const std::size_t few = std::max<std::size_t>(2, median / 4);
  const long long nc = static_cast<long long>(cells);
#pragma omp parallel for schedule(dynamic, 256) if (nc > kParallelMin / 16)
  for (long long cc = 0; cc < nc; ++cc) {
    const auto c = static_cast<std::size_t>(cc);
    if (cell_points.size[c] > few || (cell_key[c] >> (3 * ab)) != 0) continue;  // full, or a handle's
    cell_points.eachPoint(c, [&](std::size_t i) {
      int near = 0;
      // Its own cell first: two near points there settle it (most points of a sparse cell at
      // the surface's edge), without the search of the 27 cells of every class.
      cell_points.eachPoint(c, [&](std::size_t j) {
        near += j != i && (points[j].getVector3fMap() - points[i].getVector3fMap()).squaredNorm() <= limit2;
        return near < 2;
      });
      if (near >= 2) return true;  // (stray[i] stays 0)
      near = 0;
      around(
          i, [&] { return limit2; },
          [&](std::size_t j) {
            if (j != i && (points[j].getVector3fMap() - points[i].getVector3fMap()).squaredNorm() <= limit2)
              ++near;
            return near < 2;
          });
      stray[i] = near < 2;
      return true;
    });
  }
  return stray;
}

}  // namespace

CoarseLevel coarsen(const pcl::PointCloud<pcl::PointXYZ>& points, const Handles& handles, std::size_t target,
                    bool find_strays) {
  CoarseLevel out;
  const std::size_t n = points.size();
  if (n == 0 || target == 0) return out;
  // Points are indexed by int here, as everywhere in the library (handles, coarse points).
  if (n > static_cast<std::size_t>(std::numeric_limits<int>::max()))
    throw std::invalid_argument("coarsen: " + std::to_string(n) + " points, more than 2,147,483,647");
  PhaseClock clock;
  // The class of a point: 0 free, 1 the manipulated handle, 2 + k the fixed handle k, then the
  // joints (free points of joint k: 2 + fixed + k), so that a joint's phi range is measured on
  // its own points and a joint smaller than a cell keeps one.
  const std::size_t classes = 2 + handles.fixed.size() + handles.joints.size();
  const int class_bits = bitsFor(classes - 1);
  constexpr int kMaxAxisBits = 17;
  if (3 * kMaxAxisBits + class_bits >= 64 || classes > 65535) return out;
  // (Each list on every thread, the lists in this order: a later class wins, as before.)
  UninitVector<std::uint16_t> cls = zeros<std::uint16_t>(n);
  const auto mark = [&cls](const std::vector<int>& list, std::size_t value) {
    const long long m = static_cast<long long>(list.size());
#pragma omp parallel for schedule(static) if (m > kParallelMin)
    for (long long k = 0; k < m; ++k)
      cls[static_cast<std::size_t>(list[static_cast<std::size_t>(k)])] = static_cast<std::uint16_t>(value);
  };
  for (std::size_t k = 0; k < handles.joints.size(); ++k)
    mark(handles.joints[k], 2 + handles.fixed.size() + k);
  for (std::size_t k = 0; k < handles.fixed.size(); ++k) mark(handles.fixed[k], 2 + k);
  mark(handles.manipulated, 1);

  const Eigen::AlignedBox3f box = boundingBox(points);
  const Eigen::Vector3f lo = box.min(), hi = box.max();
  const Eigen::Vector3f extent = hi - lo;
  const float diag = std::max(extent.norm(), 1e-12f);
  Grid grid;
  grid.lo = lo;
  // At most 2^17 cells along an axis, so that a key fits 64 bits with the class.
  const float min_h = std::max(extent.maxCoeff(), 1e-12f) / static_cast<float>((1 << kMaxAxisBits) - 2);
  auto setH = [&](float h) {
    grid.h = std::max(h, min_h);
    const auto dims = static_cast<std::uint64_t>(std::floor(extent.maxCoeff() / grid.h)) + 1;
    grid.axis_bits = std::max(1, bitsFor(dims));
  };
  auto maxKey = [&] { return (std::uint64_t{1} << (3 * grid.axis_bits + class_bits)) - 1; };
  // A surface's cells grow as 1/h^2: start from the diagonal and correct a few times, counting on
  // a strided subset of about four points per wanted cell (a cell the subset misses is rare).
  setH(diag / std::sqrt(static_cast<float>(target)));
  const std::size_t stride = std::max<std::size_t>(1, n / (4 * target));
  // Gathered once (a strided read of every round's subset cost a cache miss a point).
  const std::size_t sampled = (n + stride - 1) / stride;
  std::vector<Eigen::Vector3f> sample_at(sampled);
  std::vector<std::uint16_t> sample_cls(sampled);
  const long long ns = static_cast<long long>(sampled);
#pragma omp parallel for schedule(static) if (ns > kParallelMin)
  for (long long k = 0; k < ns; ++k) {
    const std::size_t i = static_cast<std::size_t>(k) * stride;
    sample_at[static_cast<std::size_t>(k)] = points[i].getVector3fMap();
    sample_cls[static_cast<std::size_t>(k)] = cls[i];
  }
  for (int round = 0; round < 8; ++round) {
    const double ratio = static_cast<double>(countCells(sample_at, sample_cls, grid, maxKey())) / target;
    if (ratio > 0.85 && ratio < 1.15) break;
    const float before = grid.h;
    // Curves grow as 1/h, volumes as 1/h^3; the square root is a safe middle.
    setH(grid.h * static_cast<float>(std::clamp(std::sqrt(ratio), 0.25, 4.0)));
    if (grid.h == before) break;  // at the finest grid allowed
  }

  clock.lap("coarsen.grid");
  // Every point's cell, as runs of points; the cells in key order (neighbouring cells stay near
  // in memory).
  Cells cell_points = findCells(points, cls, grid, maxKey());
  clock.lap("coarsen.cells");
  out.cell = grid.h;
  const UninitVector<char> stray =
      find_strays ? findStrays(points, grid, classes, cell_points) : zeros<char>(n);
  clock.lap("coarsen.strays");
  // The strays in order, listed on every thread (a serial pass over every point before).
  out.strays = indicesWhere(static_cast<long long>(n), [&stray](std::size_t i) { return stray[i] != 0; });
  const std::size_t cells = cell_points.count();
  std::vector<char> has_stray(cells, 0);
  for (const int i : out.strays) {
    const auto r =
        static_cast<std::size_t>(std::upper_bound(cell_points.run_start.begin(), cell_points.run_start.end(),
                                                  static_cast<std::uint32_t>(i)) -
                                 cell_points.run_start.begin()) -
        1;
    has_stray[cell_points.run_cell[r]] = 1;
  }

  // The point nearest its cell's centre stands for the cell; every point of the cell (but its
  // strays) is anchored there. (A cell without strays: the nearest of its runs' nearest.)
  const long long cc_count = static_cast<long long>(cells);
  std::vector<int> best(cells, -1);
  std::vector<std::uint32_t> count(cells, 0);
#pragma omp parallel for schedule(dynamic, kDynamicChunkCostly) if (cc_count > kParallelMin / 16)
  for (long long cc = 0; cc < cc_count; ++cc) {
    const auto c = static_cast<std::size_t>(cc);
    float best_d = INFINITY;
    if (!has_stray[c]) {
      for (std::uint32_t s = cell_points.first[c]; s < cell_points.first[c + 1]; ++s) {
        const std::uint32_t r = cell_points.runs[s];
        if (cell_points.run_best_d[r] < best_d || best[c] < 0) {
          best_d = cell_points.run_best_d[r];
          best[c] = static_cast<int>(cell_points.run_best[r]);
        }
      }
      count[c] = cell_points.size[c];
      continue;
    }
    cell_points.eachPoint(c, [&](std::size_t i) {
      if (stray[i]) return true;
      float d = 0;
      grid.key(points[i].getVector3fMap(), 0, d);  // (the distance to the centre alone)
      if (d < best_d || best[c] < 0) {
        best_d = d;
        best[c] = static_cast<int>(i);
      }
      ++count[c];
      return true;
    });
  }
  std::vector<std::uint32_t> id(cells, 0);
  for (std::size_t c = 0; c < cells; ++c) {
    if (best[c] < 0) continue;
    id[c] = static_cast<std::uint32_t>(out.points.size());
    out.points.push_back(best[c]);
    out.weight.push_back(count[c]);
  }
  // Anchors run by run, in the cloud's order.
  out.anchor.assign(n, 0);
  const long long runs = static_cast<long long>(cell_points.runs.size());
#pragma omp parallel for schedule(dynamic, kDynamicChunkCostly) if (runs > kParallelMin / 16)
  for (long long rr = 0; rr < runs; ++rr) {
    const auto r = static_cast<std::size_t>(rr);
    const std::uint32_t a = id[cell_points.run_cell[r]];
    for (std::uint32_t i = cell_points.run_start[r]; i < cell_points.run_start[r + 1]; ++i)
      if (!stray[i]) out.anchor[i] = a;
  }
  cell_points = {};
  clock.lap("coarsen.anchors");
  if (out.points.empty()) return {};
  if (out.strays.empty()) return out;
  // A stray hangs from the nearest coarse point.
  const std::vector<int> nearest = nearestAmong(points, out.points, out.strays);
  for (std::size_t s = 0; s < out.strays.size(); ++s) {
    const auto a = static_cast<std::size_t>(std::max(0, nearest[s]));  // (the targets are not empty)
    out.anchor[static_cast<std::size_t>(out.strays[s])] = static_cast<std::uint32_t>(a);
    ++out.weight[a];
  }
  clock.lap("coarsen.stray_anchors");
  return out;
}

Handles coarseHandles(const Handles& handles, const CoarseLevel& level) {
  // The anchors in order, each once. A large handle's are marked and collected (sorting every
  // point's anchor cost more than the rest of the coarse level's set-up), a small one's sorted.
  // (Marked on every thread: atomic bytes, as points of one cell mark the same anchor.)
  const std::size_t m = level.points.size();
  std::unique_ptr<std::atomic<unsigned char>[]> mark(new std::atomic<unsigned char>[m]);
  for (std::size_t a = 0; a < m; ++a) mark[a].store(0, std::memory_order_relaxed);
  auto map = [&](const std::vector<int>& idx) {
    std::vector<int> out;
    if (idx.size() < m / 16) {
      out.reserve(idx.size());
      for (int i : idx) out.push_back(static_cast<int>(level.anchor[static_cast<std::size_t>(i)]));
      std::sort(out.begin(), out.end());
      out.erase(std::unique(out.begin(), out.end()), out.end());
      return out;
    }
    const long long count = static_cast<long long>(idx.size());
#pragma omp parallel for schedule(static) if (count > kParallelMin)
    for (long long k = 0; k < count; ++k)
      mark[level.anchor[static_cast<std::size_t>(idx[static_cast<std::size_t>(k)])]].store(
          1, std::memory_order_relaxed);
    for (std::size_t a = 0; a < m; ++a)
      if (mark[a].load(std::memory_order_relaxed)) {
        out.push_back(static_cast<int>(a));
        mark[a].store(0, std::memory_order_relaxed);
      }
    return out;
  };
  Handles c;
  for (const auto& f : handles.fixed) c.fixed.push_back(map(f));
  c.manipulated = map(handles.manipulated);
  for (const auto& j : handles.joints) c.joints.push_back(map(j));
  return c;
}

std::vector<float> prolongField(const pcl::PointCloud<pcl::PointXYZ>& points, const CoarseLevel& level,
                                const NeighborGraph& graph, const std::vector<float>& coarse_phi,
                                const std::vector<char>& constrained) {
  // Each coarse point's linear model: its value, its gradient and the range of values around it.
  struct Linear {
    Eigen::Vector3f grad = Eigen::Vector3f::Zero();
    float lo = 0, hi = 0;
  };
  const std::size_t m = level.points.size();
  std::vector<Linear> model(m);
  const long long mm = static_cast<long long>(m);
#pragma omp parallel for schedule(dynamic, kDynamicChunkCostly) if (mm > kParallelMinCostly)
  for (long long aa = 0; aa < mm; ++aa) {
    const auto a = static_cast<std::size_t>(aa);
    Linear& l = model[a];
    const float va = coarse_phi[a];
    l.lo = l.hi = va;
    if (constrained[a]) continue;  // a handle's cell keeps the handle's value
    const Eigen::Vector3d xa =
        points[static_cast<std::size_t>(level.points[a])].getVector3fMap().cast<double>();
    Eigen::Matrix3d mat = Eigen::Matrix3d::Zero();
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    int count = 0;
    for (const int* j = graph.begin(a); j != graph.end(a); ++j) {
      const auto u = static_cast<std::size_t>(*j);
      const Eigen::Vector3d d =
          points[static_cast<std::size_t>(level.points[u])].getVector3fMap().cast<double>() - xa;
      mat += d * d.transpose();
      rhs += d * static_cast<double>(coarse_phi[u] - va);
      l.lo = std::min(l.lo, coarse_phi[u]);
      l.hi = std::max(l.hi, coarse_phi[u]);
      ++count;
    }
    const double trace = mat.trace();
    if (count < 2 || !(trace > 0)) continue;
    // Neighbours on a surface leave the normal direction undetermined: a small ridge keeps the
    // gradient in the tangent plane.
    l.grad = (mat + 1e-3 * trace / 3 * Eigen::Matrix3d::Identity()).ldlt().solve(rhs).cast<float>();
    if (!l.grad.allFinite()) l.grad.setZero();
  }
  const std::size_t n = level.anchor.size();
  std::vector<float> phi(n);
  const long long nn = static_cast<long long>(n);
#pragma omp parallel for schedule(dynamic, dynamicChunk(nn)) if (nn > kParallelMin)
  for (long long ii = 0; ii < nn; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    const std::uint32_t a = level.anchor[i];
    const Linear& l = model[a];
    const Eigen::Vector3f d =
        points[i].getVector3fMap() - points[static_cast<std::size_t>(level.points[a])].getVector3fMap();
    phi[i] = std::clamp(coarse_phi[a] + l.grad.dot(d), l.lo, l.hi);
  }
  for (const int i : level.strays)
    phi[static_cast<std::size_t>(i)] = coarse_phi[level.anchor[static_cast<std::size_t>(i)]];
  return phi;
}

namespace {

// The blend factor a shape point takes from the coarse level: a coarse point between two bands
// whose factor is its place in the gap hands that rule on (the point's own φ placed in the same
// gap); one that copied its factor from elsewhere (see buildClusters) hands on the factor.
class AlphaRule {
 public:
  AlphaRule(const Clustering& c, const std::vector<float>& coarse_phi)
      : c_(c), own_gap_(coarse_phi.size(), -1) {
    const auto& bands = c.bands;
    for (std::size_t a = 0; a < own_gap_.size(); ++a) {
      const int lower = c.lower[a], upper = c.upper[a];
      if (lower < 0 || upper < 0 || lower == upper) continue;
      const int g = c.clusters[static_cast<std::size_t>(lower)].level;
      if (g < 0 || static_cast<std::size_t>(g) + 1 >= bands.size() ||
          c.clusters[static_cast<std::size_t>(upper)].level != g + 1)
        continue;
      // Inside its gap, not clamped at an end (an α of 0 or 1 copied from elsewhere would match a
      // clamped one by chance).
      const double v = coarse_phi[a];
      const auto gs = static_cast<std::size_t>(g);
      if (v > bands[gs].hi && v < bands[gs + 1].lo && std::abs(gapAlpha(gs, v) - c.alpha[a]) <= 1e-6f)
        own_gap_[a] = g;
    }
  }
  /// The factor of a point anchored at coarse point a with field value v.
  float operator()(std::uint32_t a, float v) const {
    return own_gap_[a] >= 0 ? gapAlpha(static_cast<std::size_t>(own_gap_[a]), v) : c_.alpha[a];
  }

 private:
  float gapAlpha(std::size_t g, double v) const {
    const double a = c_.bands[g].hi, b = c_.bands[g + 1].lo;
    return b > a ? static_cast<float>(std::clamp((v - a) / (b - a), 0.0, 1.0)) : 0.0f;
  }
  const Clustering& c_;
  std::vector<int> own_gap_;
};

void checkCoarseLabels(const Clustering& c, const CoarseLevel& level, const std::vector<float>& coarse_phi,
                       const std::vector<float>& phi) {
  const std::size_t m = level.points.size();
  if (c.lower.size() != m || c.upper.size() != m || c.alpha.size() != m || coarse_phi.size() != m ||
      phi.size() != level.anchor.size())
    throw std::invalid_argument(
        "prolong: the coarse clustering, the fields and the coarse level differ in size");
}

}  // namespace

Clustering prolongClusters(Clustering c, const CoarseLevel& level) {
  const auto& to_shape = level.points;
  auto map = [&](std::vector<int>& idx) {
    for (int& i : idx) i = to_shape[static_cast<std::size_t>(i)];
    std::sort(idx.begin(), idx.end());
  };
  map(c.sample);
  for (auto& cl : c.clusters) map(cl.members);
  return withoutPointLabels(std::move(c));
}

Clustering prolongClustering(Clustering c, const CoarseLevel& level, const std::vector<float>& coarse_phi,
                             const std::vector<float>& phi) {
  checkCoarseLabels(c, level, coarse_phi, phi);
  const std::size_t n = level.anchor.size();
  std::vector<int> lower(n), upper(n), nearest(n);
  std::vector<float> alpha(n);
  {
    const AlphaRule rule(c, coarse_phi);
    const long long nn = static_cast<long long>(n);
#pragma omp parallel for schedule(dynamic, dynamicChunk(nn)) if (nn > kParallelMin)
    for (long long ii = 0; ii < nn; ++ii) {
      const auto i = static_cast<std::size_t>(ii);
      const std::uint32_t a = level.anchor[i];
      lower[i] = c.lower[a];
      upper[i] = c.upper[a];
      alpha[i] = rule(a, phi[i]);
    }
    for (const int i : level.strays) {  // a stray moves as the point it hangs from
      const auto x = static_cast<std::size_t>(i);
      alpha[x] = c.alpha[level.anchor[x]];
    }
#pragma omp parallel for schedule(dynamic, dynamicChunk(nn)) if (nn > kParallelMin)
    for (long long ii = 0; ii < nn; ++ii) {
      const auto i = static_cast<std::size_t>(ii);
      nearest[i] = alpha[i] < 0.5f ? lower[i] : upper[i];
    }
  }
  c = prolongClusters(std::move(c), level);
  c.lower = std::move(lower);
  c.upper = std::move(upper);
  c.alpha = std::move(alpha);
  c.nearest = std::move(nearest);
  return c;
}

InterpolationTable prolongInterpolation(const Clustering& c, const CoarseLevel& level,
                                        const std::vector<float>& coarse_phi, const std::vector<float>& phi,
                                        const Handles& handles,
                                        const pcl::PointCloud<pcl::PointXYZ>& points) {
  checkCoarseLabels(c, level, coarse_phi, phi);
  if (points.size() != phi.size())
    throw std::invalid_argument("prolongInterpolation: the points and the field differ in size");
  const AlphaRule rule(c, coarse_phi);
  InterpolationTable t = detail::buildTable(
      handles, c, points, detail::labelPairs(c),
      [&](std::size_t i, int& lo, int& hi, float& alpha) {
        const std::uint32_t a = level.anchor[i];
        lo = c.lower[a];
        hi = c.upper[a];
        alpha = rule(a, phi[i]);
      },
      [&](InterpolationTable& table) {  // a stray moves as the point it hangs from
        for (const int x : level.strays)
          table.points[static_cast<std::size_t>(x)].alpha =
              c.alpha[level.anchor[static_cast<std::size_t>(x)]];
      });
  return t;
}

}  // namespace hgd
