// hgdeform.Shape: every field of every point in file order, faces, and what the file held
// besides; and the shapes the module makes from arrays. Internal to the module.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "common.h"
#include "hgdeform/io/fields.h"
#include "hgdeform/io/geometry.h"

namespace hgd_py {

Field makeField(const std::string& name, std::uint32_t offset, std::uint8_t type, std::uint32_t count = 1);
/// A shape of `n` points from C-order doubles (x, y, z and optionally nx, ny, nz, all FLOAT64).
hgd::Shape shapeFromArrays(const double* points, std::size_t n, const double* normals,
                           std::vector<pcl::Vertices> faces);
/// numpy's dtype for a PCL field type.
py::dtype dtypeOf(std::uint8_t type);
/// The PCL field type for a numpy dtype (bool and the sized integer and float types).
std::uint8_t typeOf(const py::dtype& dt, const std::string& name);
bool isPositionOrNormal(const std::string& name);
/// Three fields of `c` (x/y/z or the normals) for every point, as an N×3 float64 array.
py::array_t<double> readTriples(const pcl::PCLPointCloud2& c, int a, int b, int d);
void writeTriples(pcl::PCLPointCloud2& c, int a, int b, int d, const Doubles& v);
/// Appends a field of `type` × `count` to every point (zero), repacking the records.
int appendField(pcl::PCLPointCloud2& c, const std::string& name, std::uint8_t type, std::uint32_t count);

/// A shape: every field of every point in file order, faces, and what its file held besides.
struct PyShape {
  hgd::Shape s;

  std::size_t size() const { return s.size(); }

  hgd::XyzFields xyz() const {
    const hgd::XyzFields f = hgd::findXyzFields(s.cloud);
    if (!f.hasXyz()) throw py::value_error("the shape has no x/y/z fields");
    return f;
  }

  py::array_t<double> points() const {
    const hgd::XyzFields f = xyz();
    return readTriples(s.cloud, f.x, f.y, f.z);
  }
  void setPoints(const py::handle& v) {
    const hgd::XyzFields f = xyz();
    writeTriples(s.cloud, f.x, f.y, f.z,
                 rowsArg(v, "points", 3, static_cast<py::ssize_t>(size()), "the shape's point count"));
  }
  py::object normals() const {
    const hgd::XyzFields f = hgd::findXyzFields(s.cloud);
    if (!f.hasNormals()) return py::none();
    return readTriples(s.cloud, f.nx, f.ny, f.nz);
  }
  void setNormals(const py::handle& v) {
    const Doubles d = rowsArg(v, "normals", 3, static_cast<py::ssize_t>(size()), "the shape's point count");
    hgd::XyzFields f = hgd::findXyzFields(s.cloud);
    if (!f.hasNormals()) {  // as the writers name them for the shape's format
      const bool pcd = s.format == hgd::FileFormat::Pcd;
      f.nx = appendField(s.cloud, pcd ? "normal_x" : "nx", Field::FLOAT32, 1);
      f.ny = appendField(s.cloud, pcd ? "normal_y" : "ny", Field::FLOAT32, 1);
      f.nz = appendField(s.cloud, pcd ? "normal_z" : "nz", Field::FLOAT32, 1);
    }
    writeTriples(s.cloud, f.nx, f.ny, f.nz, d);
  }

  py::object faces() const {
    const std::size_t m = s.polygons.size();
    const bool triangles = std::all_of(s.polygons.begin(), s.polygons.end(),
                                       [](const pcl::Vertices& v) { return v.vertices.size() == 3; });
    if (triangles) {
      py::array_t<std::int64_t> out({static_cast<py::ssize_t>(m), py::ssize_t{3}});
      std::int64_t* o = out.mutable_data();
      for (std::size_t f = 0; f < m; ++f)
        for (std::size_t j = 0; j < 3; ++j) o[3 * f + j] = s.polygons[f].vertices[j];
      return py::object(std::move(out));
    }
    py::list out;
    for (const auto& poly : s.polygons) {
      py::array_t<std::int64_t> a(static_cast<py::ssize_t>(poly.vertices.size()));
      std::copy(poly.vertices.begin(), poly.vertices.end(), a.mutable_data());
      out.append(a);
    }
    return py::object(std::move(out));
  }
  void setFaces(const py::handle& v) { s.polygons = facesArg(v, size()); }

  std::vector<std::string> fieldNames() const {
    std::vector<std::string> names;
    for (const Field& f : s.cloud.fields)
      if (!isPositionOrNormal(f.name) && f.name != "_") names.push_back(f.name);
    return names;
  }

  /// One field's values as stored (its own dtype, the exact bits): N, or N×count.
  py::array field(const std::string& name) const {
    const int k = hgd::findField(s.cloud, name);
    if (k < 0) throw py::key_error("the shape has no field '" + name + "'");
    const Field& f = s.cloud.fields[static_cast<std::size_t>(k)];
    const std::size_t n = size(), bytes = hgd::datatypeSize(f.datatype) * f.count;
    std::vector<py::ssize_t> shape{static_cast<py::ssize_t>(n)};
    if (f.count != 1) shape.push_back(static_cast<py::ssize_t>(f.count));
    py::array out(dtypeOf(f.datatype), shape);
    auto* o = static_cast<std::uint8_t*>(out.mutable_data());
    for (std::size_t i = 0; i < n; ++i)
      std::memcpy(o + i * bytes, s.cloud.data.data() + i * s.cloud.point_step + f.offset, bytes);
    return out;
  }

  /// Stores `values` (N, or N×count) into field `name`: converted to its declared type when the
  /// shape has it, else added with the array's dtype.
  void setField(const std::string& name, const py::handle& values) {
    if (isPositionOrNormal(name))
      throw py::value_error("field " + name + ": set positions and normals with points and normals");
    py::array a = asArray(values, "field " + name);
    const std::size_t n = size();
    if (a.ndim() < 1 || a.ndim() > 2 || static_cast<std::size_t>(a.shape(0)) != n)
      throw py::value_error("field " + name + " must have one row per point (N = " + std::to_string(n) +
                            "), got shape " + shapeText(a));
    const auto count = static_cast<std::uint32_t>(a.ndim() == 2 ? a.shape(1) : 1);
    int k = hgd::findField(s.cloud, name);
    if (k < 0) {
      k = appendField(s.cloud, name, typeOf(a.dtype(), name), count);
    } else if (s.cloud.fields[static_cast<std::size_t>(k)].count != count) {
      throw py::value_error("field " + name + " holds " +
                            std::to_string(s.cloud.fields[static_cast<std::size_t>(k)].count) +
                            " values per point, got " + std::to_string(count));
    }
    const Field f = s.cloud.fields[static_cast<std::size_t>(k)];
    // Converted once to the field's own dtype (numpy's casting: floats to integers truncate).
    const py::array conv = py::array::ensure(a.attr("astype")(dtypeOf(f.datatype)), py::array::c_style);
    const std::size_t bytes = hgd::datatypeSize(f.datatype) * f.count;
    const auto* in = static_cast<const std::uint8_t*>(conv.data());
    for (std::size_t i = 0; i < n; ++i)
      std::memcpy(s.cloud.data.data() + i * s.cloud.point_step + f.offset, in + i * bytes, bytes);
  }

  py::dict fields() const {
    py::dict d;
    for (const std::string& name : fieldNames()) d[py::str(name)] = field(name);
    return d;
  }
};

const char* formatName(hgd::FileFormat f);
/// A shape from (N, 3) points, (N, 3) normals or None, faces or None.
PyShape shapeFromPython(const py::handle& points, const py::handle& normals, const py::handle& faces);
/// A ValueError for a shape held in memory without a finite point.
void requireFinitePoint(const hgd::Shape& s);
/// x, y, z of a shape built by shapeFromArrays as an N×3 array (no copy when it can).
py::array_t<double> takePoints(hgd::Shape& s);

}  // namespace hgd_py
