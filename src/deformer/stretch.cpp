#include "hgdeform/deformer/stretch.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "util/parallel.h"

namespace hgd {

namespace {

// measureStretch over a graph whose rows are the points `point[row]` (null: row r is point r;
// `skip` is by row), each pair once: a coarse level's graph is measured between the points that stand for its
// cells without a graph over every point (at 1M points that cost 30 ms of a 45 ms report).
SurfaceStretch stretchOver(const pcl::PointCloud<pcl::PointXYZ>& rest,
                           const std::vector<Eigen::Vector3f>& deformed, const NeighborGraph& pairs,
                           const std::vector<int>* point, double move_distance,
                           const std::vector<char>* skip) {
  SurfaceStretch s;
  const double grow = 0.02 * move_distance;
  const long long rows = static_cast<long long>(pairs.size());
  auto at = [point](std::size_t row) { return point ? static_cast<std::size_t>((*point)[row]) : row; };
  double worst = 1;
  std::size_t split = 0, measured = 0;
#pragma omp parallel for schedule(static) reduction(max : worst) reduction(+ : split, measured) if (rows > kParallelMin)
  for (long long rr = 0; rr < rows; ++rr) {
    const auto r = static_cast<std::size_t>(rr);
    const std::size_t i = at(r);
    if (skip && (*skip)[r]) continue;
    bool is_split = false;
    for (const int* j = pairs.begin(r); j != pairs.end(r); ++j) {
      if (skip && (*skip)[static_cast<std::size_t>(*j)]) continue;
      const std::size_t u = at(static_cast<std::size_t>(*j));
      const double r0 = (rest[u].getVector3fMap() - rest[i].getVector3fMap()).cast<double>().norm();
      if (!(r0 > 0)) continue;
      const double r1 = (deformed[u] - deformed[i]).cast<double>().norm();
      if (static_cast<std::size_t>(*j) > r) {
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

}  // namespace

SurfaceStretch measureStretch(const pcl::PointCloud<pcl::PointXYZ>& rest,
                              const std::vector<Eigen::Vector3f>& deformed, const NeighborGraph& pairs,
                              double move_distance, const std::vector<char>* skip) {
  const std::size_t n = rest.size();
  if (deformed.size() != n || pairs.size() != n || (skip && skip->size() != n))
    throw std::invalid_argument("measureStretch: rest, deformed and pairs differ in size");
  return stretchOver(rest, deformed, pairs, nullptr, move_distance, skip);
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
  if (deformed.size() != rest.size())
    throw std::invalid_argument("measureSurfaceStretch: rest and deformed differ in size");
  // The scale of "grew by more than 2% of the move": the largest displacement of any point
  // (the handle's own can be near zero when it turns about its centre while the limb beyond it
  // swings).
  double moved = min_move;
  const long long count = static_cast<long long>(deformed.size());
#pragma omp parallel for schedule(static) reduction(max : moved) if (count > kParallelMin)
  for (long long uu = 0; uu < count; ++uu) {
    const auto u = static_cast<std::size_t>(uu);
    moved = std::max(moved, static_cast<double>((deformed[u] - rest[u].getVector3fMap()).norm()));
  }
  // Mesh edges where there are faces (what the user sees joined), else the neighbour graph.
  if (!geometry.faces.empty())
    return measureStretch(rest, deformed, ringGraph(geometry.size(), geometry.faces), moved);
  // A stray's one pair to the surface point it hangs from is no surface pair (a stray inside
  // the dragged handle moves with it, its anchor maybe not).
  const std::vector<char>& strays = graph.outliers();
  if (coarse.empty())
    return measureStretch(rest, deformed, graph.graph(), moved, strays.empty() ? nullptr : &strays);
  // The coarse graph's pairs, between the points that stand for their cells (the coarse level's
  // own strays: its graph's outliers; the full resolution's are in no pair of it).
  const NeighborGraph& g = graph.graph();
  if (g.size() != coarse.points.size() || (!strays.empty() && strays.size() != g.size()))
    throw std::logic_error("measureSurfaceStretch: the graph is not the coarse level's");
  return stretchOver(rest, deformed, g, &coarse.points, moved, strays.empty() ? nullptr : &strays);
}

}  // namespace hgd
