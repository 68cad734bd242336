// The coarse level of the multi-resolution build: its grid's side, each cell's coarse point and
// anchors, the strays hung from the nearest coarse point, and the handles on the coarse level.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>

#include "graph/nearest.h"
#include "hgdeform/io/geometry.h"
#include "hgdeform/multires/multires.h"
#include "multires/coarse_grid.h"
#include "util/parallel.h"
#include "util/phases.h"
#include "util/uninit.h"

namespace hgd {

using coarse::bitsFor;
using coarse::Cells;
using coarse::countCells;
using coarse::findCells;
using coarse::findStrays;
using coarse::Grid;
using coarse::zeros;

namespace coarse {

Grid sizeGrid(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, std::size_t target, int class_bits,
              const std::vector<Eigen::Vector3f>& sample_at, const std::vector<std::uint16_t>& sample_cls) {
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
  // A surface's cells grow as 1/h^2: start from the diagonal and correct a few times, counting
  // on the subset (about four points per wanted cell; a cell the subset misses is rare).
  setH(diag / std::sqrt(static_cast<float>(target)));
  for (int round = 0; round < 8; ++round) {
    const double ratio =
        static_cast<double>(countCells(sample_at, sample_cls, grid, grid.maxKey(class_bits))) / target;
    if (ratio > 0.85 && ratio < 1.15) break;
    const float before = grid.h;
    // Curves grow as 1/h, volumes as 1/h^3; the square root is a safe middle.
    setH(grid.h * static_cast<float>(std::clamp(std::sqrt(ratio), 0.25, 4.0)));
    if (grid.h == before) break;  // at the finest grid allowed
  }
  return grid;
}

}  // namespace coarse

CoarseLevel coarsen(const pcl::PointCloud<pcl::PointXYZ>& points, const Handles& handles, std::size_t target,
                    bool find_strays, const std::vector<int>* file_index, std::size_t records) {
  CoarseLevel out;
  const std::size_t n = points.size();
  if (file_index && file_index->size() != n)
    throw std::invalid_argument("coarsen: the file indices and the points differ in size");
  const int* const fidx = file_index ? file_index->data() : nullptr;
  records = std::max(records, n);
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
  if (3 * coarse::kMaxAxisBits + class_bits >= 64 || classes > 65535) return out;
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
  // The grid's sizing subset (see sizeGrid): the points whose index in the file is a multiple
  // of a stride, a set that does not depend on the order the points come in here.
  const std::size_t stride = coarse::gridSampleStride(records, target);
  const std::vector<int> picked = indicesWhere(
      static_cast<long long>(n), [&](std::size_t i) { return coarse::fileOf(fidx, i) % stride == 0; });
  // Gathered once (a strided read of every round's subset cost a cache miss a point).
  const std::size_t sampled = picked.size();
  std::vector<Eigen::Vector3f> sample_at(sampled);
  std::vector<std::uint16_t> sample_cls(sampled);
  const long long ns = static_cast<long long>(sampled);
#pragma omp parallel for schedule(static) if (ns > kParallelMin)
  for (long long k = 0; k < ns; ++k) {
    const auto i = static_cast<std::size_t>(picked[static_cast<std::size_t>(k)]);
    sample_at[static_cast<std::size_t>(k)] = points[i].getVector3fMap();
    sample_cls[static_cast<std::size_t>(k)] = cls[i];
  }
  const Grid grid = coarse::sizeGrid(box.min(), box.max(), target, class_bits, sample_at, sample_cls);
  const auto maxKey = [&] { return grid.maxKey(class_bits); };
  clock.lap("coarsen.grid");
  // Every point's cell, as runs of points; the cells in key order (neighbouring cells stay near
  // in memory).
  Cells cell_points = findCells(points, cls, grid, maxKey(), fidx);
  clock.lap("coarsen.cells");
  out.cell = grid.h;
  const UninitVector<char> stray =
      find_strays ? findStrays(points, grid, classes, cell_points, fidx, records) : zeros<char>(n);
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

  // The point nearest its cell's centre stands for the cell (of equals, the first in the file);
  // every point of the cell (but its strays) is anchored there. (A cell without strays: the
  // nearest of its runs' nearest.)
  const auto earlier = [fidx](std::size_t i, int than) {
    return coarse::fileOf(fidx, i) < coarse::fileOf(fidx, static_cast<std::size_t>(than));
  };
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
        if (best[c] < 0 || cell_points.run_best_d[r] < best_d ||
            (cell_points.run_best_d[r] == best_d && earlier(cell_points.run_best[r], best[c]))) {
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
      if (best[c] < 0 || d < best_d || (d == best_d && earlier(i, best[c]))) {
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

}  // namespace hgd
