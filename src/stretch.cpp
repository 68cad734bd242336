#include "hgdeform/stretch.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "parallel.h"

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

}  // namespace hgd
