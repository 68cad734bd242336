#include "hgdeform/deformer/stretch.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "util/parallel.h"

namespace hgd {

SurfaceStretch measureStretch(const pcl::PointCloud<pcl::PointXYZ>& rest,
                              const std::vector<Eigen::Vector3f>& deformed, const NeighborGraph& pairs,
                              double move_distance, const std::vector<char>* skip) {
  const std::size_t n = rest.size();
  if (deformed.size() != n || pairs.size() != n || (skip && skip->size() != n))
    throw std::invalid_argument("measureStretch: rest, deformed and pairs differ in size");
  SurfaceStretch s;
  const double grow = 0.02 * move_distance;
  const long long nn = static_cast<long long>(n);
  double worst = 1;
  std::size_t split = 0, measured = 0;
#pragma omp parallel for schedule(static) reduction(max : worst) reduction(+ : split, measured) if (nn > kParallelMin)
  for (long long ii = 0; ii < nn; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    if (skip && (*skip)[i]) continue;
    bool is_split = false;
    for (const int* j = pairs.begin(i); j != pairs.end(i); ++j) {
      const auto u = static_cast<std::size_t>(*j);
      if (skip && (*skip)[u]) continue;
      const double r0 = (rest[u].getVector3fMap() - rest[i].getVector3fMap()).cast<double>().norm();
      if (!(r0 > 0)) continue;
      const double r1 = (deformed[u] - deformed[i]).cast<double>().norm();
      if (u > i) {
        ++measured;
        worst = std::max(worst, r1 / r0);
      }
      is_split = is_split || (r1 > 3 * r0 && r1 - r0 > grow);
    }
    split += is_split;
  }
  s.split_points = split;
  s.max_stretch = worst;
  s.pairs = measured;
  return s;
}

std::string stretchWarning(const SurfaceStretch& s) {
  if (s.split_points == 0) return "";
  char buf[300];
  std::snprintf(buf, sizeof buf,
                "the surface is pulled apart at %zu points (a neighbour pair stretched %.3gx; more than "
                "3x and by more than 2%% of the move counts): look there before using the result",
                s.split_points, s.max_stretch);
  return buf;
}

SurfaceStretch measureSurfaceStretch(const Geometry& geometry, const std::vector<Eigen::Vector3f>& deformed,
                                     const SurfaceGraph& graph, const CoarseLevel& coarse, double min_move) {
  const auto& rest = *geometry.points;
  // The scale of "grew by more than 2% of the move": the largest displacement of any point
  // (the handle's own can be near zero when it turns about its centre while the limb beyond it
  // swings).
  double moved = min_move;
  for (std::size_t u = 0; u < deformed.size(); ++u)
    moved = std::max(moved, static_cast<double>((deformed[u] - rest[u].getVector3fMap()).norm()));
  // Mesh edges where there are faces (what the user sees joined), else the neighbour graph.
  if (!geometry.faces.empty())
    return measureStretch(rest, deformed, ringGraph(geometry.size(), geometry.faces), moved);
  // A stray's one pair to the surface point it hangs from is no surface pair (a stray inside
  // the dragged handle moves with it, its anchor maybe not).
  const std::vector<char>& strays = graph.outliers();
  if (coarse.empty())
    return measureStretch(rest, deformed, graph.graph(), moved, strays.empty() ? nullptr : &strays);
  // The coarse graph's pairs, between the points that stand for their cells.
  const NeighborGraph& g = graph.graph();
  std::vector<std::pair<int, int>> pairs;
  for (std::size_t a = 0; a < g.size(); ++a)
    for (const int* j = g.begin(a); j != g.end(a); ++j)
      if (static_cast<int>(a) < *j)
        pairs.emplace_back(coarse.points[a], coarse.points[static_cast<std::size_t>(*j)]);
  NeighborGraph none;
  none.offsets.assign(geometry.size() + 1, 0);
  std::vector<char> shape_strays;
  if (!strays.empty() || !coarse.strays.empty()) {
    shape_strays.assign(geometry.size(), 0);
    for (std::size_t a = 0; a < strays.size(); ++a)
      if (strays[a]) shape_strays[static_cast<std::size_t>(coarse.points[a])] = 1;
    for (const int i : coarse.strays) shape_strays[static_cast<std::size_t>(i)] = 1;
  }
  return measureStretch(rest, deformed, addEdges(none, pairs), moved,
                        shape_strays.empty() ? nullptr : &shape_strays);
}

}  // namespace hgd
