#include "hgdeform/neighbors.h"

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

#include "grid_knn.h"
#include "nearest.h"
#include "parallel.h"
#include "timer.h"

namespace hgd {

namespace {
// The normal filter (docs/scans.md, "The neighbour graph and its normal filter"): a pair is across a thin gap
// when its normals face each other or away from each other within about 26 degrees (cos 26 = 0.9) and one
// point lies above the other along them by at least 0.10 of the offset (6 degrees out of the tangent plane:
// at the rim of two layers a third of a spacing apart, neighbours across the gap lie up to 2.5 spacings
// aside, 7.6 degrees out; a flipped normal on a smooth surface has its neighbours within a few degrees of
// its tangent plane).
constexpr float kThinGapCos = 0.9f;
constexpr float kThinGapOffset = 0.10f;

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
#pragma omp parallel for schedule(static) if (nn > kParallelMin)
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
#pragma omp parallel for schedule(static) reduction(|| : any_coincident) if (nn > kParallelMin)
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

namespace {
// Builds a symmetric CSR graph from a directed edge generator, removing self-loops and repeats.
template <typename ForEachEdge>
NeighborGraph symmetricGraph(std::size_t n, ForEachEdge&& for_each_edge) {
  NeighborGraph g;
  g.offsets.assign(n + 1, 0);
  for_each_edge([&](int i, int j) {
    ++g.offsets[static_cast<std::size_t>(i) + 1];
    ++g.offsets[static_cast<std::size_t>(j) + 1];
  });
  for (std::size_t i = 0; i < n; ++i) g.offsets[i + 1] += g.offsets[i];
  g.adj.resize(static_cast<std::size_t>(g.offsets[n]));
  std::vector<int> fill(g.offsets.begin(), g.offsets.end() - 1);
  for_each_edge([&](int i, int j) {
    g.adj[static_cast<std::size_t>(fill[static_cast<std::size_t>(i)]++)] = j;
    g.adj[static_cast<std::size_t>(fill[static_cast<std::size_t>(j)]++)] = i;
  });
  // Sort and deduplicate each row, compacting in place.
  int write = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const int b = g.offsets[i], e = g.offsets[i + 1];
    std::sort(g.adj.begin() + b, g.adj.begin() + e);
    const int row_start = write;
    for (int m = b; m < e; ++m)
      if (m == b || g.adj[static_cast<std::size_t>(m)] != g.adj[static_cast<std::size_t>(m - 1)])
        g.adj[static_cast<std::size_t>(write++)] = g.adj[static_cast<std::size_t>(m)];
    g.offsets[i] = row_start;
  }
  g.offsets[n] = write;
  g.adj.resize(static_cast<std::size_t>(write));
  g.adj.shrink_to_fit();
  return g;
}
}  // namespace

bool acrossThinGap(const Eigen::Vector3f& pi, const Eigen::Vector3f& ni, const Eigen::Vector3f& pj,
                   const Eigen::Vector3f& nj) {
  const float dot = ni.dot(nj);
  if (!(dot < 0)) return false;  // most pairs: the normals agree
  const float li2 = ni.squaredNorm(), lj2 = nj.squaredNorm();
  // A ridge or a crease: the normals turn, they do not face each other.
  if (!(li2 > 0) || !(lj2 > 0) || dot * dot < kThinGapCos * kThinGapCos * li2 * lj2) return false;
  const Eigen::Vector3f a = ni / std::sqrt(li2), b = nj / std::sqrt(lj2);
  const Eigen::Vector3f axis = a - b;  // the pair's common normal line, |axis| ~ 2
  const Eigen::Vector3f d = pj - pi;
  if (!(d.squaredNorm() > 0)) return false;  // copies of one point
  // Offset along the normal line (one side above the other), not beside it in the tangent
  // plane (a flipped normal on a smooth surface has its neighbours beside it).
  return std::abs(d.dot(axis)) >= kThinGapOffset * d.norm() * axis.norm();
}

NeighborGraph knnGraph(const KnnTable& knn, int k, const pcl::PointCloud<pcl::Normal>* normals,
                       const pcl::PointCloud<pcl::PointXYZ>* points,
                       std::vector<std::pair<int, int>>* dropped) {
  if (normals && (!points || points->size() != knn.size() || normals->size() != knn.size()))
    throw std::invalid_argument("knnGraph: the normal filter needs the points and one normal per point");
  // In parallel passes rather than through a generic edge list (this runs once per cloud on
  // a million points): each row's kept entries sorted; the reverse lists, sorted by
  // construction (filled in row order); then each row is the merge of the two.
  const std::size_t n = knn.size();
  const int kk = std::max(0, std::min(k, knn.k));
  const long long nn = static_cast<long long>(n);
  const auto ukk = static_cast<std::size_t>(kk);
  // Not zero-filled: every slot read is written first (the rows in parallel, first touch).
  std::unique_ptr<int[]> fwd(new int[n * ukk]), fwd_count(new int[n]);
  if (dropped) dropped->clear();
#pragma omp parallel if (nn > kParallelMin)
  {
    std::vector<std::pair<int, int>> mine;  // dropped pairs: few, listed by the thread that met them
#pragma omp for schedule(static) nowait
    for (long long ii = 0; ii < nn; ++ii) {
      const auto i = static_cast<std::size_t>(ii);
      const int* row = knn.row(i);
      int* out = fwd.get() + i * ukk;
      int c = 0;
      for (int m = 0; m < kk; ++m) {
        const int j = row[m];
        if (j == static_cast<int>(i)) continue;
        // (Most pairs' normals agree: that is decided here, without the call.)
        if (normals &&
            (*normals)[i].getNormalVector3fMap().dot(
                (*normals)[static_cast<std::size_t>(j)].getNormalVector3fMap()) < 0 &&
            acrossThinGap((*points)[i].getVector3fMap(), (*normals)[i].getNormalVector3fMap(),
                          (*points)[static_cast<std::size_t>(j)].getVector3fMap(),
                          (*normals)[static_cast<std::size_t>(j)].getNormalVector3fMap())) {
          if (dropped) mine.emplace_back(std::min(static_cast<int>(i), j), std::max(static_cast<int>(i), j));
          continue;
        }
        // Insertion into the sorted prefix (k is small), skipping repeats.
        int at = c;
        while (at > 0 && out[at - 1] > j) --at;
        if (at > 0 && out[at - 1] == j) continue;
        for (int q = c; q > at; --q) out[q] = out[q - 1];
        out[at] = j;
        ++c;
      }
      fwd_count[i] = c;
    }
    if (dropped && !mine.empty()) {
#pragma omp critical
      dropped->insert(dropped->end(), mine.begin(), mine.end());
    }
  }
  // Reverse lists: per-thread counts, so that each thread writes its own rows' entries to
  // slots reserved for it, in row order.
  // At most 8 blocks (each holds n + 1 counts).
  const int threads = std::min(8, blockCount(nn));
  std::vector<std::vector<int>> rcount(static_cast<std::size_t>(threads), std::vector<int>(n + 1, 0));
  forBlocks(nn, threads, [&](int b, int e, int t) {
    auto& cnt = rcount[static_cast<std::size_t>(t)];
    for (auto i = static_cast<std::size_t>(b); i < static_cast<std::size_t>(e); ++i)
      for (int m = 0; m < fwd_count[i]; ++m)
        ++cnt[static_cast<std::size_t>(fwd[i * ukk + static_cast<std::size_t>(m)])];
  });
  std::vector<int> roff(n + 1, 0);
  for (std::size_t j = 0; j < n; ++j) {
    int at = roff[j];
    for (int t = 0; t < threads; ++t) {
      const int c = rcount[static_cast<std::size_t>(t)][j];
      rcount[static_cast<std::size_t>(t)][j] = at;  // this block's first slot in row j
      at += c;
    }
    roff[j + 1] = at;
  }
  std::unique_ptr<int[]> rev(new int[static_cast<std::size_t>(roff[n])]);
  forBlocks(nn, threads, [&](int b, int e, int t) {
    auto& slot = rcount[static_cast<std::size_t>(t)];
    for (auto i = static_cast<std::size_t>(b); i < static_cast<std::size_t>(e); ++i)
      for (int m = 0; m < fwd_count[i]; ++m) {
        const auto j = static_cast<std::size_t>(fwd[i * ukk + static_cast<std::size_t>(m)]);
        rev[static_cast<std::size_t>(slot[j]++)] = static_cast<int>(i);
      }
  });
  rcount.clear();
  rcount.shrink_to_fit();
  // Each row: the union of its sorted forward and reverse lists; counted, then written.
  auto merge = [&](std::size_t i, int* out) {
    const int *a = fwd.get() + i * ukk, *ae = a + fwd_count[i];
    const int *b = rev.get() + roff[i], *be = rev.get() + roff[i + 1];
    int c = 0;
    while (a != ae || b != be) {
      int v;
      if (b == be || (a != ae && *a < *b))
        v = *a++;
      else if (a == ae || *b < *a)
        v = *b++;
      else {
        v = *a++;
        ++b;
      }
      if (out) out[c] = v;
      ++c;
    }
    return c;
  };
  NeighborGraph g;
  g.offsets.assign(n + 1, 0);
#pragma omp parallel for schedule(static) if (nn > kParallelMin)
  for (long long i = 0; i < nn; ++i)
    g.offsets[static_cast<std::size_t>(i) + 1] = merge(static_cast<std::size_t>(i), nullptr);
  for (std::size_t i = 0; i < n; ++i) g.offsets[i + 1] += g.offsets[i];
  g.adj.resize(static_cast<std::size_t>(g.offsets[n]));
#pragma omp parallel for schedule(static) if (nn > kParallelMin)
  for (long long i = 0; i < nn; ++i)
    merge(static_cast<std::size_t>(i), g.adj.data() + g.offsets[static_cast<std::size_t>(i)]);
  if (dropped) {  // the rule is symmetric: a pair dropped from one side is dropped from both
    std::sort(dropped->begin(), dropped->end());
    dropped->erase(std::unique(dropped->begin(), dropped->end()), dropped->end());
  }
  return g;
}

std::vector<char> findOutliers(const pcl::PointCloud<pcl::PointXYZ>& points, const KnnTable& knn) {
  // A point whose k-th neighbour is more than 3 times as far as the typical point's: stray
  // returns of a scan, far from any surface, alone or in clumps of fewer than k (noise on the
  // surface is not flagged). The k-th, not the nearest: two strays side by side are each
  // other's nearest neighbour.
  const std::size_t n = points.size();
  if (knn.k == 0 || knn.size() != n) return {};
  std::vector<float> nearest(n, INFINITY);  // squared distance to the k-th neighbour
  const long long nn = static_cast<long long>(n);
#pragma omp parallel for schedule(static) if (nn > kParallelMin)
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
  // Squared distances: 3 times the median distance; but outliers are few by definition, so
  // never more than the sparsest 3% (a scan whose density falls off with range is no outlier).
  const auto at = [&](std::size_t k) {
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(k), sorted.end());
    return sorted[k];
  };
  const float limit = std::max(9.0f * at(sorted.size() / 2), at(sorted.size() * 97 / 100));
  // Also a stray: a point that none of its k nearest neighbours counts among theirs (it is
  // farther from each than that neighbour's own k-th). A point of the surface, however noisy,
  // is someone's neighbour; a stray between two parts of the surface (the prongs of a fork),
  // within the noise's reach of both and so not far by the rule above, is nobody's, and joined
  // to both it would carry the field across the gap.
#pragma omp parallel for schedule(static) if (nn > kParallelMin)
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
  const flann::Matrix<float> data(xyz.data(), targets.size(), 3);
  flann::Index<flann::L2_Simple<float>> index(data, flann::KDTreeSingleIndexParams(15));
  index.buildIndex();
  flann::Matrix<float> mq(q.data(), queries.size(), 3), md(d2.data(), queries.size(), 1);
  flann::Matrix<int> mi(hit.data(), queries.size(), 1);
  const flann::SearchParams params(flann::FLANN_CHECKS_UNLIMITED, 0.0f, true);
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

NeighborGraph unionGraph(const NeighborGraph& a, const NeighborGraph& b) {
  const std::size_t n = a.size();
  NeighborGraph g;
  g.offsets.assign(n + 1, 0);
  g.adj.reserve(a.adj.size() + b.adj.size());
  for (std::size_t i = 0; i < n; ++i) {
    const int *x = a.begin(i), *xe = a.end(i), *y = b.begin(i), *ye = b.end(i);
    while (x != xe || y != ye) {
      int v;
      if (y == ye || (x != xe && *x < *y))
        v = *x++;
      else if (x == xe || *y < *x)
        v = *y++;
      else {
        v = *x++;
        ++y;
      }
      g.adj.push_back(v);
    }
    g.offsets[i + 1] = static_cast<int>(g.adj.size());
  }
  return g;
}

NeighborGraph addEdges(const NeighborGraph& graph, const std::vector<std::pair<int, int>>& edges) {
  return unionGraph(graph, symmetricGraph(graph.size(), [&](auto&& emit) {
                      for (const auto& [a, b] : edges)
                        if (a != b) emit(a, b);
                    }));
}

NeighborGraph ringGraph(std::size_t n, const std::vector<pcl::Vertices>& faces) {
  return symmetricGraph(n, [&](auto&& emit) {
    for (const auto& f : faces) {
      const auto& v = f.vertices;
      for (std::size_t m = 0; m < v.size(); ++m) {
        const int a = static_cast<int>(v[m]), b = static_cast<int>(v[(m + 1) % v.size()]);
        if (a != b) emit(a, b);
      }
    }
  });
}

int connectedComponents(const NeighborGraph& graph, std::vector<int>& label) {
  // A concurrent union-find over the edges, in parallel (lock-free: a root is linked under a
  // smaller index by compare-and-swap, so every root ends as its piece's smallest index);
  // pieces are then numbered in the order of their smallest index.
  const std::size_t n = graph.size();
  const long long nn = static_cast<long long>(n);
  std::unique_ptr<std::atomic<int>[]> parent(new std::atomic<int>[n]);
#pragma omp parallel for schedule(static) if (nn > kParallelMin)
  for (long long i = 0; i < nn; ++i) parent[i].store(static_cast<int>(i), std::memory_order_relaxed);
  auto find = [&](int x) {
    for (;;) {
      int p = parent[x].load(std::memory_order_relaxed);
      if (p == x) return x;
      const int gp = parent[p].load(std::memory_order_relaxed);
      if (gp != p) parent[x].compare_exchange_weak(p, gp, std::memory_order_relaxed);  // halving
      x = gp;
    }
  };
#pragma omp parallel for schedule(dynamic, 4096) if (nn > kParallelMin)
  for (long long i = 0; i < nn; ++i)
    for (const int* j = graph.begin(static_cast<std::size_t>(i)); j != graph.end(static_cast<std::size_t>(i));
         ++j) {
      if (*j == i) continue;
      int a = find(static_cast<int>(i)), b = find(*j);
      while (a != b) {
        if (a < b) std::swap(a, b);  // link the larger root under the smaller
        int expected = a;
        if (parent[a].compare_exchange_strong(expected, b)) break;
        a = find(a);
        b = find(b);
      }
    }
  label.resize(n);
#pragma omp parallel for schedule(static) if (nn > kParallelMin)
  for (long long i = 0; i < nn; ++i) label[static_cast<std::size_t>(i)] = find(static_cast<int>(i));
  int count = 0;
  for (std::size_t i = 0; i < n; ++i)  // a root precedes the rest of its piece
    label[i] = label[i] == static_cast<int>(i) ? count++ : label[static_cast<std::size_t>(label[i])];
  return count;
}

}  // namespace hgd
