// The coarse level's voxel grid (internal; the multires stage's files): cells keyed by class and
// position, found as runs of the cloud's points, and the strays of sparse cells.
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "util/parallel.h"
#include "util/uninit.h"

namespace hgd::coarse {

inline int bitsFor(std::uint64_t v) {
  int b = 0;
  while (v >> b) ++b;
  return b;
}

/// The largest power of two not above v (1 for 0).
inline std::size_t pow2Floor(std::size_t v) {
  std::size_t p = 1;
  while (p <= v / 2) p *= 2;
  return p;
}

/// The grid's sizing subset: the points whose index in the file is a multiple of this (about
/// four a wanted cell). A power of two, so that a pass that collects the records of a finer
/// stride (before the point count, and so the target, is known) holds every one of them.
inline std::size_t gridSampleStride(std::size_t records, std::size_t target) {
  return pow2Floor(std::max<std::size_t>(1, records / (4 * std::max<std::size_t>(1, target))));
}

/// The strays' typical-distance sample: the points whose index in the file is a multiple of
/// this (about 2,000).
inline std::size_t straySampleStride(std::size_t records) {
  return std::max<std::size_t>(1, records / 2000);
}

/// A point's index in the file: file_index[k], or k where there is no such map.
inline std::uint32_t fileOf(const int* file_index, std::size_t k) {
  return file_index ? static_cast<std::uint32_t>(file_index[k]) : static_cast<std::uint32_t>(k);
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

/// At most 2^17 cells along an axis, so that a key fits 64 bits with the class.
constexpr int kMaxAxisBits = 17;

// Cell keys of a voxel grid: class in the high bits, then z, y, x.
struct Grid {
  Eigen::Vector3f lo;
  float h = 1;
  int axis_bits = 0;
  /// The largest key with `class_bits` bits of class.
  std::uint64_t maxKey(int class_bits) const {
    return (std::uint64_t{1} << (3 * axis_bits + class_bits)) - 1;
  }
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
  UninitVector<std::uint32_t>
      run_best;                    ///< its point nearest the cell's centre (the first in the file of equals)
  UninitVector<float> run_best_d;  ///< that point's squared distance to the centre
  UninitVector<std::uint32_t> run_cell;  ///< its cell
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
// (`file_index`: the points' indices in the file, null for their own; ties of the nearest go to
// the first in the file.)
Cells findCells(const pcl::PointCloud<pcl::PointXYZ>& points, const UninitVector<std::uint16_t>& cls,
                const Grid& grid, std::uint64_t max_key, const int* file_index);

// The grid over the box lo..hi whose side gives about `target` cells over the sampled points
// (the grid's sizing subset, positions and classes): from the diagonal, corrected up to eight
// times until the count is within 15%.
Grid sizeGrid(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, std::size_t target, int class_bits,
              const std::vector<Eigen::Vector3f>& sample_at, const std::vector<std::uint16_t>& sample_cls);

// The cells a grid would have over the sampled points (positions and classes, packed).
std::size_t countCells(const std::vector<Eigen::Vector3f>& points, const std::vector<std::uint16_t>& cls,
                       const Grid& grid, std::uint64_t max_key);

// Stray points of a scan are alone in their cells, and a coarse level of them would be mostly
// strays where the cloud holds a few (the field's own test for strays, findOutliers, expects
// them rare), and a stray between two parts would join them. So in cells that hold few points
// where a cell typically holds four or more, a free point with fewer than two other points
// within three times the typical distance to the second nearest (at most a cell side) is a
// stray: no coarse point (as findOutliers' strays hang from the surface at full resolution).
// The typical distance is measured at the points whose index in the file (`file_index`, null for
// their own) is a multiple of straySampleStride(records).
UninitVector<char> findStrays(const pcl::PointCloud<pcl::PointXYZ>& points, const Grid& grid,
                              std::size_t classes, const Cells& cell_points, const int* file_index,
                              std::size_t records);

}  // namespace hgd::coarse
