#include "hgdeform/graph/normal_filter.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <stdexcept>
#include <vector>

#include "util/parallel.h"

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
#pragma omp parallel if (nn > kParallelMinCostly)
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
#pragma omp parallel for schedule(dynamic, kDynamicChunkCostly) if (nn > kParallelMinCostly)
  for (long long i = 0; i < nn; ++i)
    g.offsets[static_cast<std::size_t>(i) + 1] = merge(static_cast<std::size_t>(i), nullptr);
  for (std::size_t i = 0; i < n; ++i) g.offsets[i + 1] += g.offsets[i];
  g.adj.resize(static_cast<std::size_t>(g.offsets[n]));
#pragma omp parallel for schedule(dynamic, kDynamicChunkCostly) if (nn > kParallelMinCostly)
  for (long long i = 0; i < nn; ++i)
    merge(static_cast<std::size_t>(i), g.adj.data() + g.offsets[static_cast<std::size_t>(i)]);
  if (dropped) {  // the rule is symmetric: a pair dropped from one side is dropped from both
    std::sort(dropped->begin(), dropped->end());
    dropped->erase(std::unique(dropped->begin(), dropped->end()), dropped->end());
  }
  return g;
}

}  // namespace hgd
