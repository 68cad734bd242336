#include "graph/grid_knn.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

#include "util/parallel.h"
#include "util/radix_sort.h"
#include "util/timer.h"

namespace hgd {

namespace {

// Points per occupied cell aimed at: a surface crossing a cell of side h puts about m points
// in it and about 2.4 m within distance h of a point; m = 0.6 kk keeps the kk nearest inside
// the 3 x 3 x 3 block around a point (which reaches at least h from it) nearly always, so the
// search rarely widens, while the block stays small (about 100 candidates at kk = 17).
double targetPerCell(int kk) {
  return std::max(2.0, kk * 0.6);
}

constexpr int kMaxDim = 1 << 20;  // cells per axis (keys pack into 60 bits)
constexpr int kMaxRing = 8;       // widest shell a crowd's own grid searches cell by cell
constexpr int kMaxRingFar = 5;    // the same for the whole cloud: beyond it a point is far
constexpr double kCrowded = 8;    // a cell with this many times the target is crowded

struct Grid {
  double lo[3] = {0, 0, 0};
  double h = 1, inv_h = 1;
  std::int64_t dim[3] = {1, 1, 1};
  std::vector<std::uint64_t> cell_key;    // occupied cells, in key order
  std::vector<std::uint32_t> cell_start;  // their points: sorted[cell_start[c] .. cell_start[c+1])
  std::vector<std::uint32_t> order;       // sorted position -> point index
  std::vector<std::int32_t> table;        // open-addressing hash: cell key -> cell id (-1 empty)
  std::uint64_t mask = 0;

  std::uint64_t key(std::int64_t x, std::int64_t y, std::int64_t z) const {
    return static_cast<std::uint64_t>(x + dim[0] * (y + dim[1] * z));
  }
  static std::uint64_t hash(std::uint64_t k) { return (k * 0x9E3779B97F4A7C15ull) >> 20; }
  int find(std::int64_t x, std::int64_t y, std::int64_t z) const {
    if (x < 0 || y < 0 || z < 0 || x >= dim[0] || y >= dim[1] || z >= dim[2]) return -1;
    const std::uint64_t k = key(x, y, z);
    for (std::uint64_t s = hash(k) & mask;; s = (s + 1) & mask) {
      const int c = table[s];
      if (c < 0 || cell_key[static_cast<std::size_t>(c)] == k) return c;
    }
  }
};

/// Sorts the points into cells of side h (radix sort on the cell keys). Returns false when
/// h gives too many cells per axis.
bool bin(const float* xyz, std::size_t n, double h, Grid& g, const double hi[3]) {
  g.h = h;
  g.inv_h = 1.0 / h;
  for (int a = 0; a < 3; ++a) {
    const double cells = std::floor((hi[a] - g.lo[a]) * g.inv_h) + 1;
    if (!(cells <= kMaxDim)) return false;
    g.dim[a] = static_cast<std::int64_t>(cells);
  }
  std::vector<std::uint64_t> keys(n);
  g.order.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    std::int64_t c[3];
    for (int a = 0; a < 3; ++a)
      c[a] = std::clamp<std::int64_t>(static_cast<std::int64_t>((xyz[3 * i + a] - g.lo[a]) * g.inv_h), 0,
                                      g.dim[a] - 1);
    keys[i] = g.key(c[0], c[1], c[2]);
    g.order[i] = static_cast<std::uint32_t>(i);
  }
  radixSort(keys, g.order, g.key(g.dim[0] - 1, g.dim[1] - 1, g.dim[2] - 1), 11);
  const std::vector<int> starts = runStarts(keys);
  g.cell_key.resize(starts.size());
  g.cell_start.resize(starts.size() + 1);
  for (std::size_t c = 0; c < starts.size(); ++c) {
    g.cell_key[c] = keys[static_cast<std::size_t>(starts[c])];
    g.cell_start[c] = static_cast<std::uint32_t>(starts[c]);
  }
  g.cell_start.back() = static_cast<std::uint32_t>(n);
  return true;
}

/// The kk best so far, sorted by distance.
struct Best {
  float* d;
  int* id;
  int kk;
  void insert(float dist, int who) {
    if (!(dist < d[kk - 1])) return;
    int m = kk - 1;
    while (m > 0 && d[m - 1] > dist) {
      d[m] = d[m - 1];
      id[m] = id[m - 1];
      --m;
    }
    d[m] = dist;
    id[m] = who;
  }
};

}  // namespace

namespace {

// gridKnn with the cell side given (h > 0) or chosen from the points (h = 0), for the points
// whose `query` entry is set (null: every point; the other rows are left as they were),
// widening the search up to shell `max_ring` before a point counts as far.
bool gridKnnAt(const float* xyz, std::size_t n, int kk, int* idx, float* d2, std::vector<std::uint32_t>& far,
               double fixed_h, const char* query, int max_ring) {
  far.clear();
  if (n == 0 || kk <= 0) return true;
  if (static_cast<std::size_t>(kk) > n || n >= (1ull << 31)) return false;
  Grid g;
  double hi[3];
  for (int a = 0; a < 3; ++a) {
    g.lo[a] = std::numeric_limits<double>::infinity();
    hi[a] = -std::numeric_limits<double>::infinity();
  }
  for (std::size_t i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) {
      const double v = xyz[3 * i + a];
      if (!std::isfinite(v)) return false;
      g.lo[a] = std::min(g.lo[a], v);
      hi[a] = std::max(hi[a], v);
    }
  const double ex = hi[0] - g.lo[0], ey = hi[1] - g.lo[1], ez = hi[2] - g.lo[2];
  const double extent = std::max({ex, ey, ez});
  if (!(extent > 0) || !std::isfinite(extent)) return false;
  // First guess: a surface about as large as the box's faces; then rescale h until the cells
  // hold about the target (a surface's count per cell grows as h squared).
  const double target = targetPerCell(kk);
  const double area = std::max(ex * ey + ey * ez + ez * ex, 1e-6 * extent * extent);
  double h = std::sqrt(target * area / static_cast<double>(n));
  if (fixed_h > 0) h = fixed_h;
  h = std::max(h, extent / (kMaxDim - 2));
  for (int attempt = 0;; ++attempt) {
    if (!bin(xyz, n, h, g, hi)) return false;
    if (fixed_h > 0) break;
    const double per_cell = static_cast<double>(n) / static_cast<double>(g.cell_key.size());
    if (attempt == 3 || (per_cell > target / 2 && per_cell < target * 2)) break;
    const double next =
        std::max(h * std::clamp(std::sqrt(target / per_cell), 0.125, 8.0), extent / (kMaxDim - 2));
    if (next == h) break;
    h = next;
  }
  const std::size_t cells = g.cell_key.size();
  // A query costs its block's population, so a cell costs its population squared. When that
  // is too much, cells far more crowded than the target (a small dense piece beside a large
  // sparse one, as the eyes and teeth of a character mesh) get a grid of their own (below); the
  // rest must suit this one, else a grid is the wrong tool for the cloud.
  std::vector<char> crowded(cells, 0);
  std::size_t crowded_points = 0;
  double cost = 0, crowded_cost = 0;
  for (std::size_t c = 0; c < cells; ++c) {
    const double m = g.cell_start[c + 1] - g.cell_start[c];
    cost += m * m;
    if (m > kCrowded * target) {
      crowded[c] = 1;
      crowded_points += static_cast<std::size_t>(m);
      crowded_cost += m * m;
    }
  }
  // A uniform surface costs about 2 target per point; the crowd's own grid pays from about 16.
  const double affordable = 64.0 * target * static_cast<double>(n);
  if (cost <= 16.0 * target * static_cast<double>(n)) {
    std::fill(crowded.begin(), crowded.end(), 0);
    crowded_points = 0;
  } else if (cost - crowded_cost > affordable) {
    return false;
  }
  std::size_t table_size = 1;
  while (table_size < 2 * cells) table_size <<= 1;
  g.mask = table_size - 1;
  g.table.assign(table_size, -1);
  for (std::size_t c = 0; c < cells; ++c) {
    std::uint64_t s = Grid::hash(g.cell_key[c]) & g.mask;
    while (g.table[s] >= 0) s = (s + 1) & g.mask;
    g.table[s] = static_cast<std::int32_t>(c);
  }
  // Positions in cell order (structure of arrays) for contiguous scans.
  std::vector<float> px(n), py(n), pz(n);
  for (std::size_t s = 0; s < n; ++s) {
    const std::size_t i = g.order[s];
    px[s] = xyz[3 * i];
    py[s] = xyz[3 * i + 1];
    pz[s] = xyz[3 * i + 2];
  }

  // The crowded cells' queries: in a grid over their points and those of the cells around
  // them, which holds every point within h of a crowded point. A row whose kk-th distance is
  // under h is therefore exact; the others are left to the far outliers' search. Only the
  // crowded points are queried there (the others are candidates only).
  std::vector<std::uint32_t> unsettled;  // point indices
  bool crowd_queried = false;
  for (std::size_t c = 0; c < cells && crowded_points > 0 && !crowd_queried; ++c)
    if (crowded[c])
      for (std::uint32_t q = g.cell_start[c]; q < g.cell_start[c + 1] && !crowd_queried; ++q)
        crowd_queried = query == nullptr || query[g.order[q]];
  // Returns false, having written no row, when no finer grid suits the crowd either.
  const auto searchCrowd = [&]() {
    std::vector<char> in_sub(cells, 0);
    for (std::size_t c = 0; c < cells; ++c) {
      if (!crowded[c]) continue;
      const std::uint64_t key = g.cell_key[c];
      const std::int64_t cx = static_cast<std::int64_t>(key % static_cast<std::uint64_t>(g.dim[0]));
      const std::uint64_t rest = key / static_cast<std::uint64_t>(g.dim[0]);
      const std::int64_t cy = static_cast<std::int64_t>(rest % static_cast<std::uint64_t>(g.dim[1]));
      const std::int64_t cz = static_cast<std::int64_t>(rest / static_cast<std::uint64_t>(g.dim[1]));
      for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int f = g.find(cx + dx, cy + dy, cz + dz);
            if (f >= 0) in_sub[static_cast<std::size_t>(f)] = 1;
          }
    }
    std::vector<std::uint32_t> sub;  // sorted positions
    std::vector<char> sub_query;     // crowded and queried
    for (std::size_t c = 0; c < cells; ++c)
      if (in_sub[c])
        for (std::uint32_t q = g.cell_start[c]; q < g.cell_start[c + 1]; ++q) {
          sub.push_back(q);
          sub_query.push_back(crowded[c] && (query == nullptr || query[g.order[q]]));
        }
    if (sub.size() > n - n / 16) return false;  // the crowd is the cloud
    // Cells as fine as the crowd needs: a crowded point's cell holds crowded_cost /
    // crowded_points points on average, and a surface's count per cell goes as h squared. (The
    // points around the crowd would make an occupancy-based choice too coarse.)
    const double sub_h =
        g.h * std::max(1.0 / 64, std::sqrt(target * static_cast<double>(crowded_points) / crowded_cost));
    const std::size_t ns = sub.size();
    std::vector<float> sxyz(3 * ns);
    for (std::size_t a = 0; a < ns; ++a) {
      sxyz[3 * a] = px[sub[a]];
      sxyz[3 * a + 1] = py[sub[a]];
      sxyz[3 * a + 2] = pz[sub[a]];
    }
    const std::size_t skk = static_cast<std::size_t>(kk);
    std::vector<int> sidx(ns * skk);
    std::vector<float> sd2(ns * skk);
    std::vector<std::uint32_t> sfar;
    if (!gridKnnAt(sxyz.data(), ns, kk, sidx.data(), sd2.data(), sfar, sub_h, sub_query.data(), kMaxRing))
      return false;  // (rows are written below only)
    const double reach = g.h * (1 - 1e-6);
    std::size_t next_far = 0;
    for (std::size_t a = 0; a < ns; ++a) {
      const bool listed = next_far < sfar.size() && sfar[next_far] == a;
      next_far += listed;
      if (!sub_query[a]) continue;
      const std::uint32_t i = g.order[sub[a]];
      if (listed || !(static_cast<double>(sd2[a * skk + skk - 1]) <= reach * reach)) {
        unsettled.push_back(i);
        continue;
      }
      for (std::size_t m = 0; m < skk; ++m) {
        idx[std::size_t{i} * skk + m] =
            static_cast<int>(g.order[sub[static_cast<std::size_t>(sidx[a * skk + m])]]);
        d2[std::size_t{i} * skk + m] = sd2[a * skk + m];
      }
    }
    return true;
  };
  if (crowd_queried && !searchCrowd()) {
    // This grid then, crowd and all, if it can afford that (duplicates: a crowd no grid splits).
    if (cost > affordable) return false;
    std::fill(crowded.begin(), crowded.end(), 0);
  }

  const long long ncells = static_cast<long long>(cells);
  // Parallel with enough queries (each costs a microsecond or two): kParallelMinCostly.
  bool parallel = static_cast<long long>(n) > kParallelMinCostly;
  if (query) parallel = std::count_if(query, query + n, [](char q) { return q != 0; }) > kParallelMinCostly;
#pragma omp parallel if (parallel)
  {
    std::vector<std::uint32_t> my_far;  // this thread's far outliers
    std::vector<float> bd(static_cast<std::size_t>(kk));
    std::vector<int> bi(static_cast<std::size_t>(kk));
    std::vector<std::uint32_t> prev_slot(static_cast<std::size_t>(kk));
    std::vector<float> cand_x, cand_y, cand_z, dist;
    std::vector<std::uint32_t> cand_id;
    std::vector<std::uint64_t> keys;
#pragma omp for schedule(dynamic, 64)
    for (long long c = 0; c < ncells; ++c) {
      if (crowded[static_cast<std::size_t>(c)]) continue;  // searched above
      const std::uint32_t q0 = g.cell_start[static_cast<std::size_t>(c)];
      const std::uint32_t q1 = g.cell_start[static_cast<std::size_t>(c) + 1];
      if (query && std::none_of(g.order.begin() + q0, g.order.begin() + q1,
                                [&](std::uint32_t i) { return query[i] != 0; }))
        continue;
      const std::uint64_t key = g.cell_key[static_cast<std::size_t>(c)];
      const std::int64_t cx = static_cast<std::int64_t>(key % static_cast<std::uint64_t>(g.dim[0]));
      const std::uint64_t rest = key / static_cast<std::uint64_t>(g.dim[0]);
      const std::int64_t cy = static_cast<std::int64_t>(rest % static_cast<std::uint64_t>(g.dim[1]));
      const std::int64_t cz = static_cast<std::int64_t>(rest / static_cast<std::uint64_t>(g.dim[1]));
      // The 3 x 3 x 3 block as 9 runs: cells along x are consecutive keys, so consecutive in
      // the sorted points.
      std::uint32_t run_begin[9], run_end[9];
      int runs = 0;
      for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy) {
          std::uint32_t b = 0, e = 0;
          bool any = false;
          for (int dx = -1; dx <= 1; ++dx) {
            const int f = g.find(cx + dx, cy + dy, cz + dz);
            if (f < 0) continue;
            if (!any) b = g.cell_start[static_cast<std::size_t>(f)];
            e = g.cell_start[static_cast<std::size_t>(f) + 1];
            any = true;
          }
          if (any) {
            run_begin[runs] = b;
            run_end[runs++] = e;
          }
        }
      // The block's points, gathered once for all the cell's queries.
      cand_x.clear();
      cand_y.clear();
      cand_z.clear();
      cand_id.clear();
      for (int r = 0; r < runs; ++r)
        for (std::uint32_t s = run_begin[r]; s < run_end[r]; ++s) {
          cand_x.push_back(px[s]);
          cand_y.push_back(py[s]);
          cand_z.push_back(pz[s]);
          cand_id.push_back(s);
        }
      const std::size_t nc = cand_id.size();
      dist.resize(nc);
      keys.resize(nc);
      float prev_x = 0, prev_y = 0, prev_z = 0;
      bool have_prev = false;
      bool prev_in_block = false;  // the previous query's kk best are all block slots (prev_slot)
      for (std::uint32_t q = q0; q < q1; ++q) {
        if (query && !query[g.order[q]]) continue;
        Best best{bd.data(), bi.data(), kk};
        const float x = px[q], y = py[q], z = pz[q];
        for (std::size_t m = 0; m < nc; ++m) {
          const float dx = cand_x[m] - x, dy = cand_y[m] - y, dz = cand_z[m] - z;
          dist[m] = dx * dx + dy * dy + dz * dz;
        }
        // Only candidates within a bound on this query's kk-th distance take part in the
        // selection: the farthest of the previous query's kk best when they are block slots
        // (kk distinct candidates), else the previous query's kk-th distance plus the step
        // from it (triangle inequality; bd still holds that query's kk best: real points, so
        // its kk-th distance bounds that query's true one from above).
        float bound = std::numeric_limits<float>::infinity();
        if (prev_in_block) {
          bound = 0;
          for (int m = 0; m < kk; ++m) bound = std::max(bound, dist[prev_slot[static_cast<std::size_t>(m)]]);
        } else if (have_prev) {
          const float step = std::sqrt((x - prev_x) * (x - prev_x) + (y - prev_y) * (y - prev_y) +
                                       (z - prev_z) * (z - prev_z));
          bound = (std::sqrt(bd[static_cast<std::size_t>(kk) - 1]) + step) * (1 + 1e-5f);
          bound *= bound;
        }
        prev_x = x;
        prev_y = y;
        prev_z = z;
        have_prev = true;
        std::size_t nk = 0;
        for (std::size_t m = 0; m < nc; ++m) {
          std::uint32_t bits;
          std::memcpy(&bits, &dist[m], sizeof bits);
          keys[nk] = (static_cast<std::uint64_t>(bits) << 32) | m;
          nk += dist[m] <= bound;
        }
        if (nk >= static_cast<std::size_t>(kk)) {
          // Select on (distance bits, slot): non-negative floats order as their bit patterns.
          // Many candidates: first keep only the distance buckets (of 32 over [0, the largest])
          // that hold the kk nearest, as a bucket never decreases with the distance, so that
          // the sort below sees a few more than kk keys.
          std::size_t ns = nk;
          if (nk > static_cast<std::size_t>(kk) + 8) {
            std::uint64_t top = 0;
            for (std::size_t m = 0; m < nk; ++m) top = std::max(top, keys[m] >> 32);
            float range;
            const auto top_bits = static_cast<std::uint32_t>(top);
            std::memcpy(&range, &top_bits, sizeof range);
            const float scale = 32.0f / range;
            if (range > 0 && std::isfinite(range) && std::isfinite(scale)) {
              const auto bucket = [scale](std::uint64_t k64) {
                const auto bits = static_cast<std::uint32_t>(k64 >> 32);
                float d;
                std::memcpy(&d, &bits, sizeof d);
                return static_cast<int>(std::min(d * scale, 32.0f));
              };
              std::uint32_t count[33] = {};
              for (std::size_t m = 0; m < nk; ++m) ++count[bucket(keys[m])];
              int last = 0;
              for (std::uint32_t seen = count[0]; seen < static_cast<std::uint32_t>(kk);)
                seen += count[++last];
              ns = 0;
              for (std::size_t m = 0; m < nk; ++m) {
                keys[ns] = keys[m];
                ns += bucket(keys[m]) <= last;
              }
            }
          }
          if (ns > static_cast<std::size_t>(kk) + 16) {
            std::nth_element(keys.begin(), keys.begin() + (kk - 1),
                             keys.begin() + static_cast<std::ptrdiff_t>(ns));
            ns = static_cast<std::size_t>(kk);
          }
          std::sort(keys.begin(), keys.begin() + static_cast<std::ptrdiff_t>(ns));
          for (int m = 0; m < kk; ++m) {
            const std::size_t slot = keys[static_cast<std::size_t>(m)] & 0xffffffffu;
            bd[static_cast<std::size_t>(m)] = dist[slot];
            bi[static_cast<std::size_t>(m)] = static_cast<int>(cand_id[slot]);
            prev_slot[static_cast<std::size_t>(m)] = static_cast<std::uint32_t>(slot);
          }
          prev_in_block = true;
        } else {
          prev_in_block = false;
          std::fill(bd.begin(), bd.end(), std::numeric_limits<float>::infinity());
          std::fill(bi.begin(), bi.end(), -1);
          for (std::size_t m = 0; m < nc; ++m) best.insert(dist[m], static_cast<int>(cand_id[m]));
        }
        // Nothing outside the block is nearer than its boundary; otherwise widen shell by shell.
        double margin = 1;
        const double pos[3] = {x, y, z};
        const std::int64_t cc[3] = {cx, cy, cz};
        for (int a = 0; a < 3; ++a) {
          const double f = (pos[a] - g.lo[a]) * g.inv_h - static_cast<double>(cc[a]);
          margin = std::min({margin, std::max(0.0, f), std::max(0.0, 1.0 - f)});
        }
        auto safe = [&](int ring) {
          const double reach = (ring + margin) * g.h * (1 - 1e-6);
          return static_cast<double>(bd[static_cast<std::size_t>(kk) - 1]) <= reach * reach;
        };
        int ring = 1;
        // (Shell r has about 24 r^2 cells: up to shell 8, some 4,900 look-ups.)
        while (!safe(ring) && ring < max_ring) {
          ++ring;
          prev_in_block = false;  // best may now hold points beyond the block
          for (int dz = -ring; dz <= ring; ++dz)
            for (int dy = -ring; dy <= ring; ++dy) {
              const bool face = std::abs(dz) == ring || std::abs(dy) == ring;
              for (int dx = -ring; dx <= ring; dx += face ? 1 : 2 * ring) {
                const int f = g.find(cx + dx, cy + dy, cz + dz);
                if (f < 0) continue;
                for (std::uint32_t s = g.cell_start[static_cast<std::size_t>(f)];
                     s < g.cell_start[static_cast<std::size_t>(f) + 1]; ++s) {
                  const float ddx = px[s] - x, ddy = py[s] - y, ddz = pz[s] - z;
                  best.insert(ddx * ddx + ddy * ddy + ddz * ddz, static_cast<int>(s));
                }
              }
            }
        }
        if (!safe(ring)) {  // a far outlier: the caller's
          my_far.push_back(g.order[q]);
          continue;
        }
        const std::size_t out = static_cast<std::size_t>(g.order[q]) * static_cast<std::size_t>(kk);
        for (int m = 0; m < kk; ++m) {
          idx[out + static_cast<std::size_t>(m)] = static_cast<int>(g.order[static_cast<std::size_t>(bi[m])]);
          d2[out + static_cast<std::size_t>(m)] = bd[static_cast<std::size_t>(m)];
        }
      }
    }
    if (!my_far.empty()) {
#pragma omp critical(hgd_grid_knn_far)
      far.insert(far.end(), my_far.begin(), my_far.end());
    }
  }
  // Crowded points the sub-grid could not settle go with the far outliers.
  far.insert(far.end(), unsettled.begin(), unsettled.end());
  std::sort(far.begin(), far.end());
  return true;
}

}  // namespace

bool gridKnn(const float* xyz, std::size_t n, int kk, int* idx, float* d2, std::vector<std::uint32_t>& far) {
  // The caller's far points cost a k-d tree over the whole cloud, once: a stray in an empty
  // region is better sent there than widened around shell by shell. A crowd's own grid widens
  // further (its sparse edge at a finer cell side), as its far rows end up with the caller's.
  return gridKnnAt(xyz, n, kk, idx, d2, far, 0, nullptr, kMaxRingFar);
}

}  // namespace hgd
