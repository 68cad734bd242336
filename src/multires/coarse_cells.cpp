// The coarse level's cells (multires/coarse_grid.h): every point's cell as runs of points, and
// the count of cells a grid side would give.
#include <cstring>

#include "multires/coarse_grid.h"
#include "util/radix_sort.h"

namespace hgd::coarse {

Cells findCells(const pcl::PointCloud<pcl::PointXYZ>& points, const UninitVector<std::uint16_t>& cls,
                const Grid& grid, std::uint64_t max_key, const int* file_index) {
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
    std::uint32_t start = 0, best = 0, best_d = 0, best_f = 0;
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
      // Nearer, or as near and earlier in the file (a new run's first point is always nearer).
      const std::uint32_t f = fileOf(file_index, i);
      const std::uint32_t nearer =
          0u - static_cast<std::uint32_t>((bits < so_far) | ((bits == so_far) & (f < best_f)));
      best = (i & nearer) | (best & ~nearer);
      best_f = (f & nearer) | (best_f & ~nearer);
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
  const std::vector<int> changes = runStarts(sorted_key);
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
  return runStarts(keys).size();
}

}  // namespace hgd::coarse
