#include "hgdeform/geometry.h"

#include <cmath>

#include "hgdeform/fields.h"
#include "hgdeform/io.h"

namespace hgd {

Geometry extractGeometry(const Shape& shape) {
  const pcl::PCLPointCloud2& c = shape.cloud;
  const XyzFields f = findXyzFields(c);
  if (!f.hasXyz()) throw IoError(shape.path + ": no x/y/z fields");
  const std::size_t n = shape.size();
  if (n == 0) throw IoError(shape.path + ": no points");

  Geometry g;
  g.finite_index.assign(n, -1);
  g.raw_index.reserve(n);
  std::vector<Eigen::Vector3d> world;
  world.reserve(n);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d p(readValue(c, i, c.fields[f.x]), readValue(c, i, c.fields[f.y]),
                            readValue(c, i, c.fields[f.z]));
    if (!p.allFinite()) continue;
    g.finite_index[i] = static_cast<int>(g.raw_index.size());
    g.raw_index.push_back(static_cast<int>(i));
    world.push_back(p);
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  if (world.empty())
    throw IoError(shape.path + ": no finite points (all " + std::to_string(n) + " are NaN/inf)");

  // Centre of the bounding box, rounded so that the offset itself is exact in float output.
  g.origin = (0.5 * (lo + hi)).array().round().matrix();
  g.points->resize(world.size());
  for (std::size_t i = 0; i < world.size(); ++i)
    (*g.points)[i].getVector3fMap() = (world[i] - g.origin).cast<float>();
  g.points->width = static_cast<std::uint32_t>(world.size());
  g.points->height = 1;
  g.points->is_dense = true;

  if (f.hasNormals()) {
    bool usable = true;
    g.file_normals->resize(world.size());
    for (std::size_t k = 0; k < world.size() && usable; ++k) {
      const std::size_t i = static_cast<std::size_t>(g.raw_index[k]);
      Eigen::Vector3f nv(static_cast<float>(readValue(c, i, c.fields[f.nx])),
                         static_cast<float>(readValue(c, i, c.fields[f.ny])),
                         static_cast<float>(readValue(c, i, c.fields[f.nz])));
      const float len = nv.norm();
      if (!std::isfinite(len) || len < 1e-12f) {
        usable = false;  // a file with missing normals is treated as one without normals
        break;
      }
      (*g.file_normals)[k].getNormalVector3fMap() = nv / len;
    }
    if (!usable) g.file_normals->clear();
  }

  g.faces.reserve(shape.polygons.size());
  for (const auto& poly : shape.polygons) {
    pcl::Vertices v;
    bool ok = poly.vertices.size() >= 3;
    for (auto idx : poly.vertices) {
      const int fi =
          idx >= 0 && static_cast<std::size_t>(idx) < n ? g.finite_index[static_cast<std::size_t>(idx)] : -1;
      if (fi < 0) ok = false;
      v.vertices.push_back(static_cast<std::uint32_t>(fi));
    }
    if (ok) g.faces.push_back(std::move(v));
  }
  return g;
}

void storePositions(Shape& shape, const Geometry& geometry, const std::vector<Eigen::Vector3f>& positions,
                    const std::vector<Eigen::Vector3f>* normals) {
  pcl::PCLPointCloud2& c = shape.cloud;
  const XyzFields f = findXyzFields(c);
  const bool write_normals = normals != nullptr && f.hasNormals();
  for (std::size_t k = 0; k < positions.size(); ++k) {
    const std::size_t i = static_cast<std::size_t>(geometry.raw_index[k]);
    const Eigen::Vector3d p = positions[k].cast<double>() + geometry.origin;
    writeValue(c, i, c.fields[f.x], p.x());
    writeValue(c, i, c.fields[f.y], p.y());
    writeValue(c, i, c.fields[f.z], p.z());
    if (write_normals) {
      const Eigen::Vector3f& nv = (*normals)[k];
      writeValue(c, i, c.fields[f.nx], nv.x());
      writeValue(c, i, c.fields[f.ny], nv.y());
      writeValue(c, i, c.fields[f.nz], nv.z());
    }
  }
}

double boundingBoxDiagonal(const Geometry& geometry) {
  if (geometry.points->empty()) return 0;
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(INFINITY), hi = -lo;
  for (const auto& p : *geometry.points) {
    lo = lo.cwiseMin(p.getVector3fMap());
    hi = hi.cwiseMax(p.getVector3fMap());
  }
  return static_cast<double>((hi - lo).norm());
}

}  // namespace hgd
