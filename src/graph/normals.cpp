// Normals of a point cloud: PCA estimates oriented along a spanning tree (or towards a sensor),
// normals of a mesh from its faces, and the check whether a file's normals are oriented.
#include "hgdeform/graph/normals.h"

#include <pcl/features/normal_3d.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <queue>
#include <stdexcept>

#include "hgdeform/graph/knn.h"
#include "hgdeform/graph/neighbor_graph.h"
#include "hgdeform/graph/normal_filter.h"
#include "util/parallel.h"
#include "util/timer.h"

namespace hgd {

namespace {
// Stored normals are re-oriented when more than this fraction of side-by-side neighbours
// disagree (random signs: about half).
constexpr double kInconsistentFraction = 0.02;
}  // namespace

pcl::PointCloud<pcl::Normal>::Ptr estimateNormals(const pcl::PointCloud<pcl::PointXYZ>& points,
                                                  const KnnTable& knn, int k_normals, bool use_viewpoint,
                                                  const Eigen::Vector3f& viewpoint) {
  const std::size_t n = points.size();
  pcl::PointCloud<pcl::Normal>::Ptr normals(new pcl::PointCloud<pcl::Normal>);
  normals->resize(n);
  const int kn = std::min(k_normals, knn.k);
  const long long nn = static_cast<long long>(n);
#pragma omp parallel if (nn > kParallelMinCostly)
  {
    pcl::Indices idx;
#pragma omp for schedule(dynamic, kDynamicChunkCostly)
    for (long long i = 0; i < nn; ++i) {
      idx.assign(1, static_cast<int>(i));
      const int* row = knn.row(static_cast<std::size_t>(i));
      idx.insert(idx.end(), row, row + kn);
      Eigen::Vector4f plane(0, 0, 1, 0);
      float curvature = 0;
      if (idx.size() < 3 || !pcl::computePointNormal(points, idx, plane, curvature) || !plane.allFinite())
        plane = Eigen::Vector4f(0, 0, 1, 0);  // degenerate neighbourhood: any direction will do
      auto& out = (*normals)[static_cast<std::size_t>(i)];
      out.normal_x = plane[0];
      out.normal_y = plane[1];
      out.normal_z = plane[2];
      out.curvature = curvature;
    }
  }
  if (use_viewpoint) {
    for (std::size_t i = 0; i < n; ++i) {
      auto& nv = (*normals)[i];
      if (nv.getNormalVector3fMap().dot(viewpoint - points[i].getVector3fMap()) < 0)
        nv.getNormalVector3fMap() *= -1.0f;
    }
    return normals;
  }

  orientNormals(points, knn, kn, *normals);
  return normals;
}

void orientNormals(const pcl::PointCloud<pcl::PointXYZ>& points, const KnnTable& knn, int k_normals,
                   pcl::PointCloud<pcl::Normal>& normals) {
  const std::size_t n = points.size();
  const int kn = std::min(k_normals, knn.k);
  // Minimum-spanning-tree propagation (Prim) over the symmetric kNN graph with weights
  // 1 - |n_i . n_j|: flips follow the smoothest path, so creases are crossed last. Weights lie
  // in [0, 1], so a bucket queue (256 levels) stands in for the heap: same order up to 1/256,
  // at a fraction of the cost.
  const NeighborGraph g = knnGraph(knn, std::min(kn, 8), nullptr);
  // Seeds: each connected piece's outermost point (largest x), whose outward direction is
  // known (one pass over the pieces instead of sorting every point by x).
  std::vector<int> label;
  const int pieces = connectedComponents(g, label);
  std::vector<int> order(static_cast<std::size_t>(pieces), -1);
  for (std::size_t i = 0; i < n; ++i) {
    int& best = order[static_cast<std::size_t>(label[i])];
    if (best < 0 || points[i].x > points[static_cast<std::size_t>(best)].x) best = static_cast<int>(i);
  }
  constexpr int kBuckets = 256;
  // Each edge's bucket, on every thread: |n_i . n_j| does not depend on the signs the tree
  // gives, so the serial walk below only looks them up.
  std::vector<unsigned char> edge_bucket(g.adj.size());
  const long long nn = static_cast<long long>(n);
#pragma omp parallel for schedule(dynamic, kDynamicChunkCostly) if (nn > kParallelMinCostly)
  for (long long ii = 0; ii < nn; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    const auto ni = normals[i].getNormalVector3fMap();
    for (int m = g.offsets[i]; m < g.offsets[i + 1]; ++m) {
      const float w =
          1.0f -
          std::abs(ni.dot(
              normals[static_cast<std::size_t>(g.adj[static_cast<std::size_t>(m)])].getNormalVector3fMap()));
      // (A NaN weight, from a normal the library was given with an infinite component: first.)
      edge_bucket[static_cast<std::size_t>(m)] =
          w > 0 ? static_cast<unsigned char>(std::min(kBuckets - 1, static_cast<int>(w * kBuckets))) : 0;
    }
  }
  // The walk reads and flips a packed copy (12 bytes a point rather than PCL's 32, so that a
  // 65,536-point level's normals stay in a core's cache), written back on every thread after.
  std::vector<Eigen::Vector3f> packed(n);
#pragma omp parallel for schedule(dynamic, dynamicChunk(nn)) if (nn > kParallelMin)
  for (long long ii = 0; ii < nn; ++ii)
    packed[static_cast<std::size_t>(ii)] = normals[static_cast<std::size_t>(ii)].getNormalVector3fMap();
  std::vector<std::vector<std::pair<int, int>>> bucket(kBuckets);  // (to, from)
  int lowest = kBuckets;
  // A point waiting in bucket b is taken from there before any later entry of a higher
  // bucket, which would then find it done: such entries are not queued (entries of the same
  // bucket are, as the last one queued is taken first and decides the flip). A point's state:
  // the lowest bucket it waits in (the last at first), or -1 once done, which no entry passes:
  // one test per neighbour.
  constexpr std::int16_t kDone = -1;
  std::vector<std::int16_t> state(n, static_cast<std::int16_t>(kBuckets - 1));
  auto push = [&](int b, int to, int from) {
    std::int16_t& q = state[static_cast<std::size_t>(to)];
    if (b > q) return;
    q = static_cast<std::int16_t>(b);
    bucket[static_cast<std::size_t>(b)].emplace_back(to, from);
    lowest = std::min(lowest, b);
    // What taking it will read, fetched now: it is often taken soon (the last entry of the
    // lowest bucket is), and the walk otherwise waits on memory the threads wrote (0.3-1 ms of
    // a 4M build's 5 ms walk).
    const int row = g.offsets[static_cast<std::size_t>(to)];
    __builtin_prefetch(g.adj.data() + row);
    __builtin_prefetch(edge_bucket.data() + row);
    __builtin_prefetch(packed.data() + to);
  };
  for (int seed : order) {
    if (state[static_cast<std::size_t>(seed)] == kDone) continue;
    auto& sn = packed[static_cast<std::size_t>(seed)];
    if (sn.x() < 0) sn *= -1.0f;
    push(0, seed, seed);
    while (lowest < kBuckets) {
      auto& bk = bucket[static_cast<std::size_t>(lowest)];
      if (bk.empty()) {
        ++lowest;
        continue;
      }
      const auto [to, from] = bk.back();
      bk.pop_back();
      if (state[static_cast<std::size_t>(to)] == kDone) continue;
      state[static_cast<std::size_t>(to)] = kDone;
      Eigen::Vector3f& nt = packed[static_cast<std::size_t>(to)];
      if (to != from && nt.dot(packed[static_cast<std::size_t>(from)]) < 0) nt *= -1.0f;
      for (int m = g.offsets[static_cast<std::size_t>(to)]; m < g.offsets[static_cast<std::size_t>(to) + 1];
           ++m) {
        const int j = g.adj[static_cast<std::size_t>(m)];
        push(edge_bucket[static_cast<std::size_t>(m)], j, to);
      }
    }
    lowest = kBuckets;
  }
#pragma omp parallel for schedule(dynamic, dynamicChunk(nn)) if (nn > kParallelMin)
  for (long long ii = 0; ii < nn; ++ii)
    normals[static_cast<std::size_t>(ii)].getNormalVector3fMap() = packed[static_cast<std::size_t>(ii)];
}

pcl::PointCloud<pcl::Normal>::Ptr meshNormals(const pcl::PointCloud<pcl::PointXYZ>& points,
                                              const std::vector<pcl::Vertices>& faces) {
  const std::size_t n = points.size();
  std::vector<Eigen::Vector3f> acc(n, Eigen::Vector3f::Zero());
  for (const auto& f : faces) {
    const auto& v = f.vertices;
    // Fan triangulation; the cross product's length is twice the area: area weighting.
    for (std::size_t t = 1; t + 1 < v.size(); ++t) {
      const Eigen::Vector3f a = points[v[0]].getVector3fMap(), b = points[v[t]].getVector3fMap(),
                            c = points[v[t + 1]].getVector3fMap();
      const Eigen::Vector3f fn = (b - a).cross(c - a);
      acc[v[0]] += fn;
      acc[v[t]] += fn;
      acc[v[t + 1]] += fn;
    }
  }
  pcl::PointCloud<pcl::Normal>::Ptr normals(new pcl::PointCloud<pcl::Normal>);
  normals->resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const float len = acc[i].norm();
    (*normals)[i].getNormalVector3fMap() =
        len > 0 ? Eigen::Vector3f(acc[i] / len)
                : Eigen::Vector3f::Constant(std::numeric_limits<float>::quiet_NaN());
  }
  return normals;
}

bool consistentlyOriented(const pcl::PointCloud<pcl::PointXYZ>& points,
                          const pcl::PointCloud<pcl::Normal>& normals, const KnnTable& knn, int k) {
  // Neighbours beside each other on a smooth surface (offset in both tangent planes) have
  // normals that agree when the orientation is consistent; with random signs half disagree.
  // A statistic: every point of a small cloud; of a large one, about 12,000 points in runs of
  // 256 spread evenly through it (about 100,000 pairs: 2% of them is 2,000 +- 45, and random
  // signs give half). Runs, not single points: the geometry is in space-filling-curve order,
  // so a run and its neighbours are a patch in cache, where scattered points each miss it.
  const std::size_t n = points.size();
  const int kk = std::max(0, std::min(k, knn.k));
  constexpr std::size_t kRun = 256, kSample = 12000;
  const std::size_t runs = n <= kSample ? 1 : kSample / kRun, run_len = n <= kSample ? n : kRun;
  const std::size_t gap = n / runs;  // run r starts at r * gap
  const long long nn = static_cast<long long>(runs * run_len);
  long long beside = 0, disagree = 0;
#pragma omp parallel for schedule(static) reduction(+ : beside, disagree) if (nn > kParallelMinCostly)
  for (long long ii = 0; ii < nn; ++ii) {
    const auto i = static_cast<std::size_t>(ii) / run_len * gap + static_cast<std::size_t>(ii) % run_len;
    const Eigen::Vector3f ni = normals[i].getNormalVector3fMap();
    const float li = ni.norm();
    if (!(li > 0)) continue;
    for (int m = 0; m < kk; ++m) {
      const auto j = static_cast<std::size_t>(knn.row(i)[m]);
      if (j == i) continue;
      const Eigen::Vector3f nj = normals[j].getNormalVector3fMap();
      const float lj = nj.norm();
      const Eigen::Vector3f d = points[j].getVector3fMap() - points[i].getVector3fMap();
      const float ld = d.norm();
      if (!(lj > 0) || !(ld > 0)) continue;
      if (std::abs(d.dot(ni)) > 0.3f * ld * li || std::abs(d.dot(nj)) > 0.3f * ld * lj) continue;
      // A pair the filter sees across a thin gap (layers a third of a spacing apart have such
      // pairs within 17 degrees of the tangent plane) is no disagreement: correct normals there
      // face apart.
      if (acrossThinGap(points[i].getVector3fMap(), ni, points[j].getVector3fMap(), nj)) continue;
      ++beside;
      disagree += ni.dot(nj) < 0;
    }
  }
  return static_cast<double>(disagree) <= kInconsistentFraction * static_cast<double>(beside);
}

}  // namespace hgd
