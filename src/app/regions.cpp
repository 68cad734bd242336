#include "hgdeform/app/regions.h"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <stdexcept>

#include "hgdeform/io/fields.h"
#include "util/parallel.h"

namespace hgd {

namespace {

/// The finite points whose field has the region's value or lies in its range.
std::vector<int> selectByField(const Region& region, const Geometry& geometry, const Shape& shape,
                               const std::string& where) {
  const pcl::PCLPointCloud2& cloud = shape.cloud;
  if (geometry.finite_index.size() != shape.size())
    throw std::invalid_argument(where + ": the geometry was not extracted from this shape");
  const std::string& name = region.field_name;
  const int k = findField(cloud, name);
  if (k < 0) {
    std::string list;
    for (const auto& f : cloud.fields)
      if (!f.name.empty() && f.name[0] != '_') list += (list.empty() ? "" : ", ") + f.name;
    throw ScenarioError(where + "/field/name: the shape has no field '" + name + "' (its fields: " + list +
                        ")");
  }
  const pcl::PCLPointField& field = cloud.fields[static_cast<std::size_t>(k)];
  const std::size_t size = datatypeSize(field.datatype);
  if (size == 0 || field.count > 1)
    throw ScenarioError(where + "/field/name: field '" + name + "' is not a scalar (" +
                        std::to_string(field.count) + " values per point)");
  std::vector<int> out;
  const bool packed = name == "rgb" || name == "rgba";
  if (packed) {
    // A packed colour: its 4 bytes as 0xAARRGGBB, whatever the declared type (float or uint32).
    if (!region.equals)
      throw ScenarioError(where + "/field: a packed colour (" + name +
                          ") has no order: select one colour with equals");
    if (size != 4)
      throw ScenarioError(where + "/field/name: field '" + name + "' is not a packed colour of 4 bytes");
    const std::uint32_t mask = name == "rgb" ? 0xFFFFFFu : 0xFFFFFFFFu;
    const auto want = static_cast<std::uint32_t>(*region.equals);
    for (std::size_t i = 0; i < geometry.size(); ++i) {
      std::uint32_t v;
      std::memcpy(&v,
                  cloud.data.data() + static_cast<std::size_t>(geometry.raw_index[i]) * cloud.point_step +
                      field.offset,
                  4);
      if ((v & mask) == want) out.push_back(static_cast<int>(i));
    }
    return out;
  }
  // A FLOAT32 field is compared in float, so that "equals": 0.1 finds the points stored as 0.1f
  // and a bound of 0.1 keeps them in its range.
  const bool single = field.datatype == pcl::PCLPointField::FLOAT32;
  const auto as = [single](double x) { return single ? static_cast<double>(static_cast<float>(x)) : x; };
  const double lo = as(region.equals ? *region.equals : region.field_min);
  const double hi = as(region.equals ? *region.equals : region.field_max);
  for (std::size_t i = 0; i < geometry.size(); ++i) {
    const double v = readValue(cloud, static_cast<std::size_t>(geometry.raw_index[i]), field);
    if (v >= lo && v <= hi) out.push_back(static_cast<int>(i));  // NaN values never match
  }
  return out;
}

std::vector<int> select(const Region& region, const Geometry& geometry, const Shape* shape,
                        const std::string& scenario_name) {
  std::vector<int> out;
  const std::string where = scenario_name + ": " + (region.json_path.empty() ? "region" : region.json_path);
  // Given the shape, regions test the file's own values (a double 0.3 is in a box whose max is
  // 0.3); else the geometry's float positions.
  const XyzFields xyz = shape ? findXyzFields(shape->cloud) : XyzFields{};
  const bool exact = shape && xyz.hasXyz() && geometry.finite_index.size() == shape->size();
  const auto at = [&](std::size_t i) -> Eigen::Vector3d {
    const pcl::PCLPointCloud2& c = shape->cloud;
    const auto r = static_cast<std::size_t>(geometry.raw_index[i]);
    return {readValue(c, r, c.fields[static_cast<std::size_t>(xyz.x)]),
            readValue(c, r, c.fields[static_cast<std::size_t>(xyz.y)]),
            readValue(c, r, c.fields[static_cast<std::size_t>(xyz.z)])};
  };
  const Eigen::Vector3d shift = exact ? Eigen::Vector3d::Zero() : geometry.origin;
  // Point i's position in the frame the region is compared in (world, or the geometry's local).
  const auto position = [&](std::size_t i) -> Eigen::Vector3d {
    return exact ? at(i) : (*geometry.points)[i].getVector3fMap().cast<double>();
  };
  switch (region.kind) {
    case Region::Kind::Sphere: {
      const double r2 = region.radius * region.radius;
      const Eigen::Vector3d c = region.centre - shift;
      out = indicesWhere(static_cast<long long>(geometry.size()),
                         [&](std::size_t i) { return (position(i) - c).squaredNorm() <= r2; });
      break;
    }
    case Region::Kind::Box: {
      const Eigen::Vector3d lo = region.min - shift, hi = region.max - shift;
      out = indicesWhere(static_cast<long long>(geometry.size()), [&](std::size_t i) {
        const Eigen::Vector3d p = position(i);
        return (p.array() >= lo.array()).all() && (p.array() <= hi.array()).all();
      });
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
    case Region::Kind::Cylinder: {
      // Within `radius` of the axis segment, the projection on the axis between its ends.
      const Eigen::Vector3d a = region.start - shift, d = region.end - region.start;
      const double len2 = d.squaredNorm(), r2 = region.radius * region.radius;
      out = indicesWhere(static_cast<long long>(geometry.size()), [&](std::size_t i) {
        const Eigen::Vector3d p = position(i) - a;
        const double t = p.dot(d) / len2;
        return t >= 0 && t <= 1 && (p - t * d).squaredNorm() <= r2;
      });
      break;
    }
    case Region::Kind::Field: {
      if (!shape)
        throw ScenarioError(where + "/field: a field region needs the shape's fields (resolve the " +
                            "handles with the shape: resolveHandles(scenario, geometry, shape))");
      out = selectByField(region, geometry, *shape, where);
      break;
    }
  }
  if (out.empty()) throw ScenarioError(where + ": selects no point of the shape");
  return out;
}

Handles resolve(const Scenario& scenario, const Geometry& geometry, const Shape* shape) {
  Handles h;
  // A scenario built in memory has no file: "scenario: /fixed/0: ...", never ": /fixed/0: ...".
  const std::string name = scenario.path.empty() ? "scenario" : scenario.path;
  h.manipulated = select(scenario.manipulated, geometry, shape, name);
  std::vector<char> role(geometry.size(), 0);  // 1 manipulated, 2 fixed
  for (int i : h.manipulated) role[static_cast<std::size_t>(i)] = 1;
  for (const auto& r : scenario.fixed) {
    h.fixed.push_back(select(r, geometry, shape, name));
    for (int i : h.fixed.back()) {
      if (role[static_cast<std::size_t>(i)] == 1)
        throw ScenarioError(name + ": " + r.json_path + ": point " +
                            std::to_string(geometry.raw_index[static_cast<std::size_t>(i)]) +
                            " is both fixed and manipulated");
      role[static_cast<std::size_t>(i)] = 2;
    }
  }
  for (const auto& r : scenario.joints) {
    h.joints.push_back(select(r, geometry, shape, name));
    for (int i : h.joints.back())
      if (role[static_cast<std::size_t>(i)] != 0)
        throw ScenarioError(name + ": " + r.json_path + ": joint overlaps a handle (point " +
                            std::to_string(geometry.raw_index[static_cast<std::size_t>(i)]) + ")");
  }
  return h;
}

}  // namespace

std::vector<int> selectRegion(const Region& region, const Geometry& geometry, const Shape& shape,
                              const std::string& scenario_name) {
  return select(region, geometry, &shape, scenario_name);
}

std::vector<int> selectRegion(const Region& region, const Geometry& geometry,
                              const std::string& scenario_name) {
  return select(region, geometry, nullptr, scenario_name);
}

Handles resolveHandles(const Scenario& scenario, const Geometry& geometry, const Shape& shape) {
  return resolve(scenario, geometry, &shape);
}

Handles resolveHandles(const Scenario& scenario, const Geometry& geometry) {
  return resolve(scenario, geometry, nullptr);
}

}  // namespace hgd
