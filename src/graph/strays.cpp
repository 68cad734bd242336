#include "hgdeform/graph/strays.h"

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

#include "graph/graph_build.h"
#include "graph/stray_rule.h"
#include "util/parallel.h"

namespace hgd {

std::vector<char> findOutliers(const pcl::PointCloud<pcl::PointXYZ>& points, const KnnTable& knn) {
  // A point whose k-th neighbour is more than 3 times as far as the typical point's: stray
  // returns of a scan, far from any surface, alone or in clumps of fewer than k (noise on the
  // surface is not flagged). The k-th, not the nearest: two strays side by side are each
  // other's nearest neighbour.
  const std::size_t n = points.size();
  if (knn.k == 0 || knn.size() != n) return {};
  std::vector<float> nearest(n, INFINITY);  // squared distance to the k-th neighbour
  const long long nn = static_cast<long long>(n);
#pragma omp parallel for schedule(dynamic, kDynamicChunkCostly) if (nn > kParallelMin)
  for (long long ii = 0; ii < nn; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    // Rows are sorted by distance.
    nearest[i] = (points[static_cast<std::size_t>(knn.row(i)[knn.k - 1])].getVector3fMap() -
                  points[i].getVector3fMap())
                     .squaredNorm();
  }
  std::vector<char> out(n, 0);
  if (n == 0) return out;
  std::vector<float> sorted;
  const std::size_t stride = std::max<std::size_t>(1, n / 65536);
  for (std::size_t i = 0; i < n; i += stride)
    if (std::isfinite(nearest[i])) sorted.push_back(nearest[i]);
  if (sorted.empty()) return out;
  // The stray rule (graph/stray_rule.h), on the distances to the k-th neighbour.
  const float limit = strayLimit2(sorted);
  // Also a stray: a point that none of its k nearest neighbours counts among theirs (it is
  // farther from each than that neighbour's own k-th). A point of the surface, however noisy,
  // is someone's neighbour; a stray between two parts of the surface (the prongs of a fork),
  // within the noise's reach of both and so not far by the rule above, is nobody's, and joined
  // to both it would carry the field across the gap.
#pragma omp parallel for schedule(dynamic, kDynamicChunkCostly) if (nn > kParallelMinCostly)
  for (long long ii = 0; ii < nn; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    if (!std::isfinite(nearest[i])) continue;
    // (A row the search could not fill holds the point itself: no neighbour, no verdict.)
    bool far = nearest[i] > limit, listed = false, any = false;
    for (int m = 0; m < knn.k && !far && !listed; ++m) {
      const auto j = static_cast<std::size_t>(knn.row(i)[m]);
      if (j == i) continue;
      any = true;
      listed = (points[j].getVector3fMap() - points[i].getVector3fMap()).squaredNorm() <= nearest[j];
    }
    out[i] = far || (any && !listed);
  }
  return out;
}

namespace {
constexpr std::size_t kBruteForceQueries = 64;
}  // namespace

std::vector<int> nearestAmong(const pcl::PointCloud<pcl::PointXYZ>& points, const std::vector<int>& targets,
                              const std::vector<int>& queries) {
  std::vector<float> xyz(targets.size() * 3), q(queries.size() * 3), d2(queries.size());
  std::vector<int> hit(queries.size(), -1);
  if (targets.empty() || queries.empty()) return hit;
  for (std::size_t m = 0; m < targets.size(); ++m)
    for (int a = 0; a < 3; ++a)
      xyz[m * 3 + static_cast<std::size_t>(a)] = points[static_cast<std::size_t>(targets[m])].data[a];
  for (std::size_t m = 0; m < queries.size(); ++m)
    for (int a = 0; a < 3; ++a)
      q[m * 3 + static_cast<std::size_t>(a)] = points[static_cast<std::size_t>(queries[m])].data[a];
  // A few queries (a scan's stray or two) are cheaper against every target than a k-d tree's
  // build over them (16 ms for 68,000 targets, on one thread, for a single stray at 4M points).
  // The scan answers only when each query's nearest is clearly nearer than every other target:
  // of targets at (nearly) the same distance the tree keeps the one its descent meets first,
  // which a scan cannot tell, so such a call is the tree's, as before.
  if (queries.size() <= kBruteForceQueries) {
    const long long nq = static_cast<long long>(queries.size());
    std::vector<char> clear(queries.size(), 0);
#pragma omp parallel for schedule(static) if (nq * static_cast <long long>(targets.size()) > (1 << 20))
    for (long long m = 0; m < nq; ++m) {
      const float* p = &q[static_cast<std::size_t>(m) * 3];
      float best = std::numeric_limits<float>::infinity(), second = best;
      for (std::size_t t = 0; t < targets.size(); ++t) {
        const float dx = xyz[t * 3] - p[0], dy = xyz[t * 3 + 1] - p[1], dz = xyz[t * 3 + 2] - p[2];
        const float d = dx * dx + dy * dy + dz * dz;
        if (d < best) {
          second = best;
          best = d;
          hit[static_cast<std::size_t>(m)] = static_cast<int>(t);
        } else if (d < second) {
          second = d;
        }
      }
      clear[static_cast<std::size_t>(m)] = second > best * (1 + 1e-4f) + std::numeric_limits<float>::min();
    }
    if (std::find(clear.begin(), clear.end(), 0) == clear.end()) return hit;
    std::fill(hit.begin(), hit.end(), -1);
  }
  const flann::Matrix<float> data(xyz.data(), targets.size(), 3);
  flann::Index<flann::L2_Simple<float>> index(data, flann::KDTreeSingleIndexParams(15));
  index.buildIndex();
  flann::Matrix<float> mq(q.data(), queries.size(), 3), md(d2.data(), queries.size(), 1);
  flann::Matrix<int> mi(hit.data(), queries.size(), 1);
  flann::SearchParams params(flann::FLANN_CHECKS_UNLIMITED, 0.0f, true);
  // Exact, and each query on its own: the same hits on any number of threads.
#ifdef _OPENMP
  params.cores = static_cast<long long>(queries.size()) > kParallelMinCostly ? omp_get_max_threads() : 1;
#endif
  index.knnSearch(mq, mi, md, 1, params);
  return hit;
}

NeighborGraph attachOutliers(const pcl::PointCloud<pcl::PointXYZ>& points, const NeighborGraph& graph,
                             const KnnTable& knn, const std::vector<char>& outlier) {
  const std::size_t n = graph.size();
  // Each outlier hangs from the nearest inlier among its kNN, or, when all of those are strays
  // too, from the nearest of an even subsample of the inliers (at most 65,536: a leaf's pair
  // carries nothing, so it need not be the very nearest). Each outlier adds exactly one pair,
  // so no path between two inliers runs through outliers (it would need one pair more than
  // its outliers add).
  std::vector<int> anchor(n, -1);
  std::vector<int> far;
  for (std::size_t i = 0; i < n; ++i) {
    if (!outlier[i]) continue;
    for (int m = 0; m < knn.k && anchor[i] < 0; ++m) {
      const int j = knn.row(i)[m];
      if (j != static_cast<int>(i) && !outlier[static_cast<std::size_t>(j)]) anchor[i] = j;
    }
    if (anchor[i] < 0) far.push_back(static_cast<int>(i));
  }
  if (!far.empty()) {
    std::vector<int> inliers;
    for (std::size_t i = 0; i < n; ++i)
      if (!outlier[i]) inliers.push_back(static_cast<int>(i));
    const std::size_t stride = std::max<std::size_t>(1, inliers.size() / 65536);
    std::vector<int> pick;
    for (std::size_t m = 0; m < inliers.size(); m += stride) pick.push_back(inliers[m]);
    if (!pick.empty()) {
      const std::vector<int> hit = nearestAmong(points, pick, far);
      for (std::size_t m = 0; m < far.size(); ++m)
        if (hit[m] >= 0) anchor[static_cast<std::size_t>(far[m])] = pick[static_cast<std::size_t>(hit[m])];
    }
  }
  return symmetricGraph(n, [&](auto&& emit) {
    for (std::size_t i = 0; i < n; ++i) {
      if (outlier[i]) {
        if (anchor[i] >= 0) emit(static_cast<int>(i), anchor[i]);
        continue;
      }
      for (const int* j = graph.begin(i); j != graph.end(i); ++j)
        if (*j > static_cast<int>(i) && !outlier[static_cast<std::size_t>(*j)]) emit(static_cast<int>(i), *j);
    }
  });
}

}  // namespace hgd
