// One way to fill an interpolation table from per-point brackets, for buildInterpolation (a
// clustering's per-point labels) and for the multi-resolution build (each point's anchor's,
// without per-point labels in between): the pairs, the records and the handle pins.
#pragma once

#include <algorithm>
#include <cstdint>
#include <utility>
#include <vector>

#include "hgdeform/interp/interpolation.h"
#include "util/parallel.h"
#include "util/phases.h"
#include "util/timer.h"

namespace hgd::detail {

/// buildTable's candidates from a clustering's per-point labels: (lower, upper) of every point,
/// a run of one pair kept once (neighbours in space-filling-curve order repeat their pair).
inline std::vector<std::pair<int, int>> labelPairs(const Clustering& c) {
  std::vector<std::pair<int, int>> pairs;
  pairs.reserve(c.adjacency.size() * 2 + c.clusters.size());
  for (std::size_t i = 0; i < c.lower.size(); ++i)
    if (pairs.empty() || pairs.back() != std::make_pair(c.lower[i], c.upper[i]))
      pairs.emplace_back(c.lower[i], c.upper[i]);
  return pairs;
}

/// The table of `points` under the clusters of `c` (their barycentres and kinds; not its per-point
/// labels). `candidates`: every (lower, upper) pair a point may take, in any order, repeats
/// allowed. `bracket(i, lower, upper, alpha)` gives point i's; it is called in parallel. Then
/// `adjust(table)` may change records, before handle points are pinned to their handle's cluster
/// (so that the pins hold whatever it does). Normals are left to the caller.
/// (`pin_fixed`, `pin_manipulated`: when given, the points pinned, in place of the handles',
/// whose lists then only say which handles have points.)
template <class Bracket, class Adjust>
InterpolationTable buildTable(const Handles& handles, const Clustering& c,
                              const pcl::PointCloud<pcl::PointXYZ>& points,
                              std::vector<std::pair<int, int>> candidates, Bracket&& bracket, Adjust&& adjust,
                              const std::vector<std::vector<int>>* pin_fixed = nullptr,
                              const std::vector<int>* pin_manipulated = nullptr) {
  const std::size_t n = points.size();
  PhaseClock clock;
  InterpolationTable t;
  std::vector<int> fixed_cluster(handles.fixed.size(), -1);
  for (const auto& cl : c.clusters)
    if (cl.kind == ClusterKind::Fixed) fixed_cluster[static_cast<std::size_t>(cl.handle)] = cl.id;
  // Pairs: sorted unique (lower, upper), looked up by binary search.
  t.pairs = std::move(candidates);
  for (std::size_t k = 0; k < handles.fixed.size(); ++k)
    if (!handles.fixed[k].empty()) t.pairs.emplace_back(fixed_cluster[k], fixed_cluster[k]);
  if (!handles.manipulated.empty()) t.pairs.emplace_back(c.manipulated, c.manipulated);
  std::sort(t.pairs.begin(), t.pairs.end());
  t.pairs.erase(std::unique(t.pairs.begin(), t.pairs.end()), t.pairs.end());
  auto pairOf = [&](int lo, int hi) {
    return static_cast<std::uint32_t>(
        std::lower_bound(t.pairs.begin(), t.pairs.end(), std::make_pair(lo, hi)) - t.pairs.begin());
  };
  clock.lap("table.pairs");
  t.points.resize(n);  // (not zeroed: the records' pages are first written in parallel below)
  const long long nn = static_cast<long long>(n);
#pragma omp parallel for schedule(dynamic, dynamicChunk(nn)) if (nn > kParallelMin)
  for (long long ii = 0; ii < nn; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    InterpolationTable::Point& r = t.points[i];
    for (int a = 0; a < 3; ++a) r.p[a] = points[i].data[a];
    int lo = -1, hi = -1;
    float alpha = 0;
    bracket(i, lo, hi, alpha);
    r.pair = pairOf(lo, hi);
    r.alpha = alpha;
  }
  clock.lap("table.records");
  adjust(t);
  // Handle points take their handle's transform exactly (a handle's points on every thread: a
  // scan's handle can hold a tenth of its points; the handles one after the other). On one
  // thread where a list is not strictly increasing: a point listed twice would be written by
  // two threads at once.
  auto pin = [&](const std::vector<int>& idx, int cluster) {
    const std::uint32_t pair = pairOf(cluster, cluster);
    const long long m = static_cast<long long>(idx.size());
    bool increasing = true;
#pragma omp parallel for schedule(static) reduction(&& : increasing) if (m > kParallelMin)
    for (long long k = 1; k < m; ++k)
      increasing = increasing && idx[static_cast<std::size_t>(k - 1)] < idx[static_cast<std::size_t>(k)];
#pragma omp parallel for schedule(dynamic, dynamicChunk(m)) if (increasing && m > kParallelMin)
    for (long long k = 0; k < m; ++k) {
      const auto i = static_cast<std::size_t>(idx[static_cast<std::size_t>(k)]);
      t.points[i].pair = pair;
      t.points[i].alpha = 0.0f;
    }
  };
  for (std::size_t k = 0; k < handles.fixed.size(); ++k)
    pin(pin_fixed ? (*pin_fixed)[k] : handles.fixed[k], fixed_cluster[k]);
  pin(pin_manipulated ? *pin_manipulated : handles.manipulated,
      c.manipulated);  // last: a point in both keeps the manipulated one
  for (const auto& [a, b] : t.pairs)
    t.pair_centre.push_back((0.5 * (c.clusters[static_cast<std::size_t>(a)].barycentre +
                                    c.clusters[static_cast<std::size_t>(b)].barycentre))
                                .cast<float>());
  clock.lap("table.pins");
  return t;
}

}  // namespace hgd::detail
