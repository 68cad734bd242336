#include "hgdeform/multires/multires.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <numeric>
#include <stdexcept>

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

// Cell keys of a voxel grid: class in the high bits, then z, y, x.
struct Grid {
  Eigen::Vector3f lo;
  float h = 1;
  int axis_bits = 0;
  std::uint64_t key(const Eigen::Vector3f& p, int cls) const {
    const Eigen::Vector3f q = ((p - lo) / h).array().floor();
    const std::uint64_t x = static_cast<std::uint64_t>(std::max(0.0f, q.x()));
    const std::uint64_t y = static_cast<std::uint64_t>(std::max(0.0f, q.y()));
    const std::uint64_t z = static_cast<std::uint64_t>(std::max(0.0f, q.z()));
    return (((static_cast<std::uint64_t>(cls) << axis_bits | z) << axis_bits | y) << axis_bits) | x;
  }
};

// The cells a grid would have over the sampled points (positions and classes, packed).
std::size_t countCells(const std::vector<Eigen::Vector3f>& points, const std::vector<std::uint16_t>& cls,
                       const Grid& grid, std::uint64_t max_key) {
  const std::size_t m = points.size();
  std::vector<std::uint64_t> keys(m);
  const long long mm = static_cast<long long>(m);
#pragma omp parallel for schedule(static) if (mm > kParallelMin)
  for (long long k = 0; k < mm; ++k)
    keys[static_cast<std::size_t>(k)] =
        grid.key(points[static_cast<std::size_t>(k)], cls[static_cast<std::size_t>(k)]);
  std::vector<std::uint32_t> payload(m, 0);
  radixSort(keys, payload, max_key, 11);
  return static_cast<std::size_t>(std::unique(keys.begin(), keys.end()) - keys.begin());
}

// Stray points of a scan are alone in their cells, and a coarse level of them would be mostly
// strays where the cloud holds a few (the field's own test for strays, findOutliers, expects
// them rare), and a stray between two parts would join them. So in cells that hold few points
// where a cell typically holds four or more, a free point with fewer than two other points
// within three times the typical distance to the second nearest (at most a cell side) is a
// stray: no coarse point (as findOutliers' strays hang from the surface at full resolution).
std::vector<char> findStrays(const pcl::PointCloud<pcl::PointXYZ>& points, const Grid& grid,
                             std::size_t classes, const UninitVector<std::uint64_t>& keys,
                             const UninitVector<std::uint32_t>& order,
                             const std::vector<std::size_t>& starts) {
  const std::size_t n = keys.size(), cells = starts.size() - 1;
  std::vector<char> stray(n, 0);
  std::vector<std::uint64_t> cell_key(cells);  // searched instead of every point's key
  for (std::size_t c = 0; c < cells; ++c) cell_key[c] = keys[starts[c]];
  std::vector<std::size_t> size(cells);
  for (std::size_t c = 0; c < cells; ++c) size[c] = starts[c + 1] - starts[c];
  std::nth_element(size.begin(), size.begin() + static_cast<long>(cells / 2), size.end());
  const std::size_t median = size[cells / 2];
  if (median < 4) return stray;
  const int ab = grid.axis_bits;
  const std::uint64_t axis_mask = (std::uint64_t{1} << ab) - 1;
  // Calls fn(j) for every point j in the 3 x 3 x 3 cells around point i, of every class, until
  // fn returns false.
  auto around = [&](std::size_t i, auto&& fn) {
    const std::uint64_t key = grid.key(points[i].getVector3fMap(), 0);
    const auto x = static_cast<long long>(key & axis_mask),
               y = static_cast<long long>((key >> ab) & axis_mask),
               z = static_cast<long long>((key >> (2 * ab)) & axis_mask);
    const auto top = static_cast<long long>(axis_mask);
    // x is the lowest field of a key: the three cells of a row are one run of keys.
    const long long x0 = std::max(0LL, x - 1), x1 = std::min(top, x + 1);
    for (long long dz = -1; dz <= 1; ++dz)
      for (long long dy = -1; dy <= 1; ++dy) {
        if (y + dy < 0 || z + dz < 0 || y + dy > top || z + dz > top) continue;
        const auto row = static_cast<std::uint64_t>(((z + dz) << (2 * ab)) | ((y + dy) << ab));
        for (std::size_t c = 0; c < classes; ++c) {
          const std::uint64_t base = (static_cast<std::uint64_t>(c) << (3 * ab)) | row;
          const std::uint64_t first = base | static_cast<std::uint64_t>(x0),
                              last = base | static_cast<std::uint64_t>(x1);
          for (auto it = std::lower_bound(cell_key.begin(), cell_key.end(), first);
               it != cell_key.end() && *it <= last; ++it) {
            const auto cell = static_cast<std::size_t>(it - cell_key.begin());
            for (std::size_t k = starts[cell]; k < starts[cell + 1]; ++k)
              if (!fn(static_cast<std::size_t>(order[k]))) return;
          }
        }
      }
  };
  // The typical distance to the second nearest point, over about 2,000 points of full cells
  // (on every thread, kept in sample order).
  const std::size_t stride = std::max<std::size_t>(1, n / 2000);
  const long long samples = static_cast<long long>((n + stride - 1) / stride);
  std::vector<float> second(static_cast<std::size_t>(samples), INFINITY);
#pragma omp parallel for schedule(dynamic, 16) if (samples > 256 && n > kParallelMin)
  for (long long s = 0; s < samples; ++s) {
    const std::size_t i = order[static_cast<std::size_t>(s) * stride];
    float d1 = INFINITY, d2 = INFINITY;
    around(i, [&](std::size_t j) {
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
    if (starts[c + 1] - starts[c] > few || (keys[starts[c]] >> (3 * ab)) != 0)
      continue;  // full, or a handle's
    for (std::size_t k = starts[c]; k < starts[c + 1]; ++k) {
      const std::size_t i = order[k];
      int near = 0;
      // Its own cell first: two near points there settle it (most points of a sparse cell at
      // the surface's edge), without the search of the 27 cells of every class.
      for (std::size_t m = starts[c]; m < starts[c + 1] && near < 2; ++m) {
        const std::size_t j = order[m];
        near += j != i && (points[j].getVector3fMap() - points[i].getVector3fMap()).squaredNorm() <= limit2;
      }
      if (near >= 2) continue;  // (stray[i] stays 0)
      near = 0;
      around(i, [&](std::size_t j) {
        if (j != i && (points[j].getVector3fMap() - points[i].getVector3fMap()).squaredNorm() <= limit2)
          ++near;
        return near < 2;
      });
      stray[i] = near < 2;
    }
  }
  return stray;
}

/// Sorts `keys` (stably) and sets order[k] to the position the k-th sorted key came from, as
/// radixSort on every point would, but sorting runs of equal consecutive keys instead of points:
/// the points come in Morton order, so a cell's points lie in a few runs (357,000 runs for
/// 1,000,000 points at 15 points a cell). Runs are cut at block boundaries; the sort is stable, so
/// the pieces of a run stay in order.
void sortByRuns(UninitVector<std::uint64_t>& keys, UninitVector<std::uint32_t>& order,
                std::uint64_t max_key) {
  const std::size_t n = keys.size();
  const int blocks = blockCount(static_cast<long long>(n));
  std::vector<std::vector<std::uint32_t>> part(static_cast<std::size_t>(blocks));
  forBlocks(static_cast<long long>(n), blocks, [&](int begin, int end, int b) {
    auto& starts = part[static_cast<std::size_t>(b)];
    for (auto k = static_cast<std::size_t>(begin); k < static_cast<std::size_t>(end); ++k)
      if (k == static_cast<std::size_t>(begin) || keys[k] != keys[k - 1])
        starts.push_back(static_cast<std::uint32_t>(k));
  });
  std::vector<std::uint32_t> run_start;
  for (const auto& p : part) run_start.insert(run_start.end(), p.begin(), p.end());
  const std::size_t runs = run_start.size();
  run_start.push_back(static_cast<std::uint32_t>(n));
  std::vector<std::uint64_t> run_key(runs);
  std::vector<std::uint32_t> run(runs);
  const long long rr = static_cast<long long>(runs);
#pragma omp parallel for schedule(static) if (static_cast <long long>(n) > kParallelMin)
  for (long long r = 0; r < rr; ++r) {
    run_key[static_cast<std::size_t>(r)] = keys[run_start[static_cast<std::size_t>(r)]];
    run[static_cast<std::size_t>(r)] = static_cast<std::uint32_t>(r);
  }
  radixSort(run_key, run, max_key, 11);
  // Where each block of sorted runs starts (its runs' lengths, read at random, summed on every
  // thread), then each block's runs written out.
  std::vector<std::uint32_t> block_to(static_cast<std::size_t>(blocks) + 1, 0);
  auto length = [&](std::size_t s) { return run_start[run[s] + 1] - run_start[run[s]]; };
  forBlocks(rr, blocks, [&](int begin, int end, int b) {
    std::uint32_t sum = 0;
    for (auto s = static_cast<std::size_t>(begin); s < static_cast<std::size_t>(end); ++s) sum += length(s);
    block_to[static_cast<std::size_t>(b) + 1] = sum;
  });
  for (std::size_t b = 0; b < static_cast<std::size_t>(blocks); ++b) block_to[b + 1] += block_to[b];
  forBlocks(rr, blocks, [&](int begin, int end, int b) {
    std::uint32_t w = block_to[static_cast<std::size_t>(b)];
    for (auto s = static_cast<std::size_t>(begin); s < static_cast<std::size_t>(end); ++s)
      for (std::uint32_t k = run_start[run[s]]; k < run_start[run[s] + 1]; ++k) {
        keys[w] = run_key[s];
        order[w++] = k;
      }
  });
}

}  // namespace

CoarseLevel coarsen(const pcl::PointCloud<pcl::PointXYZ>& points, const Handles& handles, std::size_t target,
                    bool find_strays) {
  CoarseLevel out;
  const std::size_t n = points.size();
  if (n == 0 || target == 0) return out;
  PhaseClock clock;
  // The class of a point: 0 free, 1 the manipulated handle, 2 + k the fixed handle k, then the
  // joints (free points of joint k: 2 + fixed + k), so that a joint's phi range is measured on
  // its own points and a joint smaller than a cell keeps one.
  const std::size_t classes = 2 + handles.fixed.size() + handles.joints.size();
  const int class_bits = bitsFor(classes - 1);
  constexpr int kMaxAxisBits = 17;
  if (3 * kMaxAxisBits + class_bits >= 64 || classes > 65535) return out;
  // (Each list on every thread, the lists in this order: a later class wins, as before.)
  std::vector<std::uint16_t> cls(n, 0);
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
  // Every point's cell; the cells in key order (neighbouring cells stay near in memory).
  // (Uninitialised: every key is computed below, every position written by sortByRuns.)
  UninitVector<std::uint64_t> keys(n);
  UninitVector<std::uint32_t> order(n);
  const long long nn = static_cast<long long>(n);
#pragma omp parallel for schedule(static) if (nn > kParallelMin)
  for (long long i = 0; i < nn; ++i)
    keys[static_cast<std::size_t>(i)] =
        grid.key(points[static_cast<std::size_t>(i)].getVector3fMap(), cls[static_cast<std::size_t>(i)]);
  clock.lap("coarsen.keys");
  sortByRuns(keys, order, maxKey());
  clock.lap("coarsen.sort");
  out.cell = grid.h;
  std::vector<std::size_t> starts;  // of each cell's run in keys / order
  {
    const int blocks = blockCount(static_cast<long long>(n));
    std::vector<std::vector<std::size_t>> part(static_cast<std::size_t>(blocks));
    forBlocks(static_cast<long long>(n), blocks, [&](int begin, int end, int b) {
      for (auto k = static_cast<std::size_t>(begin); k < static_cast<std::size_t>(end); ++k)
        if (k == 0 || keys[k] != keys[k - 1]) part[static_cast<std::size_t>(b)].push_back(k);
    });
    for (const auto& p : part) starts.insert(starts.end(), p.begin(), p.end());
    starts.push_back(n);
  }
  const std::vector<char> stray =
      find_strays ? findStrays(points, grid, classes, keys, order, starts) : std::vector<char>(n, 0);
  clock.lap("coarsen.strays");

  // The point nearest its cell's centre stands for the cell; every point of the cell (but its
  // strays) is anchored there.
  const std::size_t cells = starts.size() - 1;
  const long long cc_count = static_cast<long long>(cells);
  std::vector<int> best(cells, -1);
  std::vector<std::uint32_t> count(cells, 0);
#pragma omp parallel for schedule(static) if (cc_count > kParallelMin / 16)
  for (long long cc = 0; cc < cc_count; ++cc) {
    const auto c = static_cast<std::size_t>(cc);
    float best_d = INFINITY;
    for (std::size_t k = starts[c]; k < starts[c + 1]; ++k) {
      if (stray[order[k]]) continue;
      const Eigen::Vector3f q = (points[order[k]].getVector3fMap() - lo) / grid.h;
      const float d = (q - q.array().floor().matrix() - Eigen::Vector3f::Constant(0.5f)).squaredNorm();
      if (d < best_d || best[c] < 0) {
        best_d = d;
        best[c] = static_cast<int>(order[k]);
      }
      ++count[c];
    }
  }
  std::vector<std::uint32_t> id(cells, 0);
  for (std::size_t c = 0; c < cells; ++c) {
    if (best[c] < 0) continue;
    id[c] = static_cast<std::uint32_t>(out.points.size());
    out.points.push_back(best[c]);
    out.weight.push_back(count[c]);
  }
  out.anchor.assign(n, 0);
#pragma omp parallel for schedule(static) if (cc_count > kParallelMin / 16)
  for (long long cc = 0; cc < cc_count; ++cc) {
    const auto c = static_cast<std::size_t>(cc);
    for (std::size_t k = starts[c]; k < starts[c + 1]; ++k)
      if (!stray[order[k]]) out.anchor[order[k]] = id[c];
  }
  keys = {};
  order = {};
  clock.lap("coarsen.anchors");
  if (out.points.empty()) return {};
  // The strays in order, listed on every thread (a serial pass over every point before).
  out.strays = indicesWhere(static_cast<long long>(n), [&stray](std::size_t i) { return stray[i] != 0; });
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
#pragma omp parallel for schedule(static) if (mm > kParallelMinCostly)
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
#pragma omp parallel for schedule(static) if (nn > kParallelMin)
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
#pragma omp parallel for schedule(static) if (nn > kParallelMin)
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
#pragma omp parallel for schedule(static) if (nn > kParallelMin)
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
