// The local frame of a shape's points (io/frame.h).
#include "io/frame.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>

#include "hgdeform/io/io.h"

namespace hgd::frame {

RobustFrame robustFrame(const std::vector<Eigen::Vector3d>& world, const std::vector<int>& file_index,
                        std::size_t step) {
  const std::size_t m = world.size();
  std::vector<std::size_t> at;
  for (std::size_t k = 0; k < m; ++k)
    if (static_cast<std::size_t>(file_index[k]) % step == 0) at.push_back(k);
  if (at.empty())
    for (std::size_t k = 0; k < m; ++k) at.push_back(k);
  std::vector<double> v;
  v.reserve(at.size());
  RobustFrame f;
  for (int a = 0; a < 3; ++a) {
    v.clear();
    for (const std::size_t k : at) v.push_back(world[k][a]);
    const std::size_t s = v.size();
    auto at_rank = [&](std::size_t r) {
      std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(r), v.end());
      return v[r];
    };
    f.centre[a] = at_rank(s / 2);
    // Twice the interquartile range: the shape's size along the axis for an even sampling,
    // whatever a quarter of the points do (strays, a scanner's zero returns).
    const double q1 = at_rank(s / 4), q3 = at_rank(s - 1 - s / 4);
    f.extent = std::max(f.extent, 2 * (q3 - q1));
  }
  return f;
}

std::vector<std::size_t> aloneAmong(const std::vector<Eigen::Vector3d>& at, const Eigen::Vector3d& centre,
                                    double r) {
  // Cells of that size; a point's neighbours within r lie in the 27 around it.
  const auto cellOf = [&](const Eigen::Vector3d& w) {
    const Eigen::Vector3d q = ((w - centre) / r).array().floor();
    return std::array<long long, 3>{static_cast<long long>(q.x()), static_cast<long long>(q.y()),
                                    static_cast<long long>(q.z())};
  };
  std::map<std::array<long long, 3>, std::vector<std::size_t>> cells;
  for (std::size_t j = 0; j < at.size(); ++j) cells[cellOf(at[j])].push_back(j);
  std::vector<std::size_t> out;
  for (std::size_t j = 0; j < at.size(); ++j) {
    const std::array<long long, 3> home = cellOf(at[j]);
    bool alone = true;
    for (long long dx = -1; dx <= 1 && alone; ++dx)
      for (long long dy = -1; dy <= 1 && alone; ++dy)
        for (long long dz = -1; dz <= 1 && alone; ++dz) {
          const auto it = cells.find({home[0] + dx, home[1] + dy, home[2] + dz});
          if (it == cells.end()) continue;
          for (const std::size_t o : it->second)
            if (o != j && (at[o] - at[j]).norm() <= r) {
              alone = false;
              break;
            }
        }
    if (alone) out.push_back(j);
  }
  return out;
}

FrameLimits frameLimits(const RobustFrame& frame) {
  FrameLimits l;
  l.far = frame.extent > 0 ? std::min(kFarFactor * frame.extent, kMaxOffset) : kMaxOffset;
  l.stray = frame.extent > 0 ? std::min(kStrayFactor * frame.extent, l.far) : l.far;
  l.body = frame.extent > 0 ? 4 * frame.extent : INFINITY;
  return l;
}

void refuseExtent(const std::string& path, const RobustFrame& frame) {
  if (!(frame.extent > kMaxExtent)) return;
  char buf[200];
  std::snprintf(
      buf, sizeof buf,
      ": the points span %.3g units (the middle half of them, doubled): more than hgdeform can deform "
      "(%.0e); are the coordinates corrupt?",
      frame.extent, kMaxExtent);
  throw IoError(path + buf);
}

std::string noReturnWarning(const std::string& path, std::size_t zeros, double distance, double extent) {
  char buf[300];
  std::snprintf(buf, sizeof buf,
                "%zu %s at exactly (0, 0, 0), %.3g units from the shape (whose size is %.3g): a "
                "scanner's 'no return' points, left where they are, untouched",
                zeros, zeros == 1 ? "point lies" : "points lie", distance, extent);
  return (path.empty() ? std::string() : path + ": ") + buf;
}

std::string farWarning(const std::string& path, std::size_t count, double beyond, double extent,
                       double farthest) {
  char buf[300];
  std::snprintf(buf, sizeof buf,
                "%zu %s more than %.3g units from the shape (whose size is %.3g; the farthest "
                "%.3g away): left where they are, untouched",
                count, count == 1 ? "point lies" : "points lie", beyond, extent, farthest);
  return (path.empty() ? std::string() : path + ": ") + buf;
}

}  // namespace hgd::frame
