#include "hgdeform/graph/knn.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <flann/flann.hpp>
#include <limits>
#include <memory>
#include <stdexcept>
#include <vector>

#include "graph/grid_knn.h"
#include "graph/nearest.h"
#include "util/parallel.h"

namespace hgd {

namespace {
KnnTable knnOfDistinct(const pcl::PointCloud<pcl::PointXYZ>& points, int k, bool* coincident = nullptr);
}  // namespace

KnnTable computeKnn(const pcl::PointCloud<pcl::PointXYZ>& points, int k) {
  // Coincident copies of a point (scans merged twice, say) would fill each other's kNN rows
  // and cut the graph apart: the search runs on distinct positions, and every copy takes the
  // neighbours of its position (copies share them, so they stay connected).
  const std::size_t n = points.size();
  bool coincident = false;
  KnnTable plain = knnOfDistinct(points, k, &coincident);
  if (!coincident) return plain;
  std::vector<std::pair<std::array<float, 3>, int>> keyed(n);
  for (std::size_t i = 0; i < n; ++i)
    keyed[i] = {{points[i].x, points[i].y, points[i].z}, static_cast<int>(i)};
  std::sort(keyed.begin(), keyed.end());
  std::vector<int> rep(n);
  pcl::PointCloud<pcl::PointXYZ> distinct;
  std::vector<int> first_of;  // distinct point -> its first copy
  for (std::size_t m = 0; m < n; ++m) {
    if (m == 0 || keyed[m].first != keyed[m - 1].first) {
      distinct.push_back(points[static_cast<std::size_t>(keyed[m].second)]);
      first_of.push_back(keyed[m].second);
    }
    rep[static_cast<std::size_t>(keyed[m].second)] = static_cast<int>(distinct.size()) - 1;
  }
  if (distinct.size() == n) return plain;
  const KnnTable d = knnOfDistinct(distinct, k);
  KnnTable t;
  t.n = n;
  // One distinct position only: every copy links to the first one (a star keeps them whole).
  t.k = std::max(d.k, 1);
  t.index.resize(n * static_cast<std::size_t>(t.k));
  for (std::size_t i = 0; i < n; ++i) {
    const int* row = d.k > 0 ? d.row(static_cast<std::size_t>(rep[i])) : nullptr;
    for (int m = 0; m < t.k; ++m) {
      const int j = row ? row[m] : rep[i];
      // Self entries (fewer distinct neighbours than k) stay self-loops, ignored later; a
      // copy other than the first links to the first, so the copies hang together.
      t.index[i * static_cast<std::size_t>(t.k) + static_cast<std::size_t>(m)] =
          j == rep[i] ? (m == 0 ? first_of[static_cast<std::size_t>(j)] : static_cast<int>(i))
                      : first_of[static_cast<std::size_t>(j)];
    }
  }
  return t;
}

namespace {
// Up to this many far outliers are searched against every point: building a k-d tree over
// the cloud costs about as much as searching 40 to 50 points that way.
constexpr std::size_t kBruteFar = 48;

/// The rows of the points `far` (the grid's far outliers): each against every point when they
/// are few, else in a k-d tree over all points. Rows sorted by distance, self first.
void knnOfFar(const float* xyz, std::size_t n, std::size_t kk, const std::vector<std::uint32_t>& far,
              const flann::SearchParams& params, int* idx, float* d2) {
  const std::size_t nf = far.size();
  std::vector<float> q(nf * 3);
  std::vector<int> fi(nf * kk, -1);  // FLANN leaves slots unset when distances overflow
  std::vector<float> fd(nf * kk, std::numeric_limits<float>::infinity());
  for (std::size_t a = 0; a < nf; ++a) std::copy_n(xyz + 3 * std::size_t{far[a]}, 3, &q[3 * a]);
  if (nf <= kBruteFar) {
    const long long nfl = static_cast<long long>(nf);
#pragma omp parallel for schedule(dynamic, 1) if (nfl > 1)
    for (long long a = 0; a < nfl; ++a) {
      const std::size_t row = static_cast<std::size_t>(a) * kk;
      const float* p = &q[3 * static_cast<std::size_t>(a)];
      for (std::size_t j = 0; j < n; ++j) {
        const float dx = xyz[3 * j] - p[0], dy = xyz[3 * j + 1] - p[1], dz = xyz[3 * j + 2] - p[2];
        const float d = dx * dx + dy * dy + dz * dz;
        if (!(d < fd[row + kk - 1])) continue;
        std::size_t m = kk - 1;
        for (; m > 0 && fd[row + m - 1] > d; --m) {
          fd[row + m] = fd[row + m - 1];
          fi[row + m] = fi[row + m - 1];
        }
        fd[row + m] = d;
        fi[row + m] = static_cast<int>(j);
      }
    }
  } else {
    flann::Index<flann::L2_Simple<float>> index(flann::Matrix<float>(const_cast<float*>(xyz), n, 3),
                                                flann::KDTreeSingleIndexParams(15));
    index.buildIndex();
    const flann::Matrix<float> queries(q.data(), nf, 3);
    flann::Matrix<int> indices(fi.data(), nf, kk);
    flann::Matrix<float> dists(fd.data(), nf, kk);
    index.knnSearch(queries, indices, dists, kk, params);
  }
  for (std::size_t a = 0; a < nf; ++a) {
    std::copy_n(&fi[a * kk], kk, idx + std::size_t{far[a]} * kk);
    std::copy_n(&fd[a * kk], kk, d2 + std::size_t{far[a]} * kk);
  }
}
}  // namespace

namespace {
KnnTable knnOfDistinct(const pcl::PointCloud<pcl::PointXYZ>& points, int k, bool* coincident) {
  KnnTable t;
  t.n = points.size();
  const std::size_t n = points.size();
  t.k = std::max(0, std::min<int>(k, static_cast<int>(n) - 1));
  if (t.k == 0) return t;
  // One batch query over all points on every core (PCL's per-query wrapper would cost about
  // as much as the search itself). Buffers are not zero-filled: every slot read is written.
  const long long nn = static_cast<long long>(n);
  std::unique_ptr<float[]> xyz(new float[n * 3]);
#pragma omp parallel for schedule(dynamic, dynamicChunk(nn)) if (nn > kParallelMin)
  for (long long i = 0; i < nn; ++i) {
    xyz[3 * i] = points[static_cast<std::size_t>(i)].x;
    xyz[3 * i + 1] = points[static_cast<std::size_t>(i)].y;
    xyz[3 * i + 2] = points[static_cast<std::size_t>(i)].z;
  }
  const std::size_t kk = static_cast<std::size_t>(t.k) + 1;
  std::unique_ptr<int[]> idx(new int[n * kk]);
  std::unique_ptr<float[]> d2(new float[n * kk]);
  // A uniform grid first (scans: a few points per cell, several times faster than the k-d
  // tree); FLANN for clouds a grid does not suit (crowded cells, extreme extents), and for the
  // far outliers of a scan, whose neighbours lie beyond the shells the grid searches: those
  // alone are searched, in a k-d tree or against every point when they are few, so that 1%
  // strays no longer send the whole cloud to the tree.
  std::vector<std::uint32_t> far;
  const flann::Matrix<float> data(xyz.get(), n, 3);
  flann::SearchParams params(flann::FLANN_CHECKS_UNLIMITED, 0.0f, true);
  params.cores = 0;  // all cores
  if (!gridKnn(xyz.get(), n, static_cast<int>(kk), idx.get(), d2.get(), far)) {
    std::fill(idx.get(), idx.get() + n * kk, -1);  // FLANN leaves slots unset when distances overflow
    flann::Index<flann::L2_Simple<float>> index(data, flann::KDTreeSingleIndexParams(15));
    index.buildIndex();
    flann::Matrix<int> indices(idx.get(), n, kk);
    flann::Matrix<float> dists(d2.get(), n, kk);
    index.knnSearch(data, indices, dists, kk, params);
  } else if (!far.empty()) {
    knnOfFar(xyz.get(), n, kk, far, params, idx.get(), d2.get());
  }
  t.index.resize(n * static_cast<std::size_t>(t.k));
  bool any_coincident = false;
#pragma omp parallel for schedule(dynamic, kDynamicChunkCostly) \
    reduction(||                                                \
              : any_coincident) if (nn > kParallelMin)
  for (long long ii = 0; ii < nn; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    // Sorted by distance; drop the point itself (wherever duplicates put it).
    int* row = t.index.data() + i * static_cast<std::size_t>(t.k);
    int m = 0;
    for (std::size_t q = 0; q < kk && m < t.k; ++q) {
      const int j = idx[i * kk + q];
      if (j != static_cast<int>(i) && j >= 0 && static_cast<std::size_t>(j) < n) {
        if (d2[i * kk + q] == 0.0f) any_coincident = true;
        row[m++] = j;
      }
    }
    for (; m < t.k; ++m) row[m] = static_cast<int>(i);  // fewer found: self-loops are ignored later
  }
  if (coincident) *coincident = any_coincident;
  return t;
}

}  // namespace

}  // namespace hgd
