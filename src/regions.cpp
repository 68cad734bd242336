#include "hgdeform/regions.h"

#include <algorithm>

namespace hgd {

std::vector<int> selectRegion(const Region& region, const Geometry& geometry,
                              const std::string& scenario_name) {
  std::vector<int> out;
  const std::string where = scenario_name + ": " + (region.json_path.empty() ? "region" : region.json_path);
  switch (region.kind) {
    case Region::Kind::Sphere: {
      const double r2 = region.radius * region.radius;
      const Eigen::Vector3d c = region.center - geometry.origin;
      for (std::size_t i = 0; i < geometry.size(); ++i)
        if (((*geometry.points)[i].getVector3fMap().cast<double>() - c).squaredNorm() <= r2)
          out.push_back(static_cast<int>(i));
      break;
    }
    case Region::Kind::Box: {
      const Eigen::Vector3d lo = region.min - geometry.origin, hi = region.max - geometry.origin;
      for (std::size_t i = 0; i < geometry.size(); ++i) {
        const Eigen::Vector3d p = (*geometry.points)[i].getVector3fMap().cast<double>();
        if ((p.array() >= lo.array()).all() && (p.array() <= hi.array()).all())
          out.push_back(static_cast<int>(i));
      }
      break;
    }
    case Region::Kind::Indices: {
      const long long n = static_cast<long long>(geometry.finite_index.size());
      for (long long idx : region.indices) {
        if (idx < 0 || idx >= n)
          throw ScenarioError(where + ": index " + std::to_string(idx) + " is out of range (the shape has " +
                              std::to_string(n) + " points)");
        const int fi = geometry.finite_index[static_cast<std::size_t>(idx)];
        if (fi >= 0) out.push_back(fi);
      }
      std::sort(out.begin(), out.end());
      out.erase(std::unique(out.begin(), out.end()), out.end());
      break;
    }
  }
  if (out.empty()) throw ScenarioError(where + ": selects no point of the shape");
  return out;
}

Handles resolveHandles(const Scenario& scenario, const Geometry& geometry) {
  Handles h;
  const std::string& name = scenario.path;
  h.manipulated = selectRegion(scenario.manipulated, geometry, name);
  std::vector<char> role(geometry.size(), 0);  // 1 manipulated, 2 fixed
  for (int i : h.manipulated) role[static_cast<std::size_t>(i)] = 1;
  for (const auto& r : scenario.fixed) {
    h.fixed.push_back(selectRegion(r, geometry, name));
    for (int i : h.fixed.back()) {
      if (role[static_cast<std::size_t>(i)] == 1)
        throw ScenarioError(name + ": " + r.json_path + ": point " +
                            std::to_string(geometry.raw_index[static_cast<std::size_t>(i)]) +
                            " is both fixed and manipulated");
      role[static_cast<std::size_t>(i)] = 2;
    }
  }
  for (const auto& r : scenario.joints) {
    h.joints.push_back(selectRegion(r, geometry, name));
    for (int i : h.joints.back())
      if (role[static_cast<std::size_t>(i)] != 0)
        throw ScenarioError(name + ": " + r.json_path + ": joint overlaps a handle (point " +
                            std::to_string(geometry.raw_index[static_cast<std::size_t>(i)]) + ")");
  }
  return h;
}

}  // namespace hgd
