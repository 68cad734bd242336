// The strays of the coarse level's sparse cells (multires/coarse_grid.h).
#include <algorithm>
#include <cmath>
#include <limits>

#include "graph/stray_rule.h"
#include "multires/coarse_grid.h"

namespace hgd::coarse {

UninitVector<char> findStrays(const pcl::PointCloud<pcl::PointXYZ>& points, const Grid& grid,
                              std::size_t classes, const Cells& cell_points, const int* file_index,
                              std::size_t records) {
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
  // The typical distance to the second nearest point, over about 2,000 points: those whose index
  // in the file is a multiple of the stride (on every thread, kept in the points' order; the
  // limit below is the same whatever the order).
  const std::size_t stride = straySampleStride(std::max(records, n));
  const std::vector<int> sampled = indicesWhere(
      static_cast<long long>(n), [&](std::size_t i) { return fileOf(file_index, i) % stride == 0; });
  const long long samples = static_cast<long long>(sampled.size());
  std::vector<float> second(sampled.size(), INFINITY);
#pragma omp parallel for schedule(dynamic, 16) if (samples > 256 && n > kParallelMin)
  for (long long s = 0; s < samples; ++s) {
    const auto i = static_cast<std::size_t>(sampled[static_cast<std::size_t>(s)]);
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
  // The stray rule findOutliers follows, at most a cell side.
  const float limit2 = std::min(grid.h * grid.h, strayLimit2(typical));
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

}  // namespace hgd::coarse
