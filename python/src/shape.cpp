// hgdeform.Shape and read/write (shape.h).
#include "shape.h"

#include <cmath>
#include <optional>
#include <utility>

namespace hgd_py {

// --- shapes ------------------------------------------------------------------------------------

Field makeField(const std::string& name, std::uint32_t offset, std::uint8_t type, std::uint32_t count) {
  Field f;
  f.name = name;
  f.offset = offset;
  f.datatype = type;
  f.count = count;
  return f;
}

/// A shape of `n` points from C-order doubles (x, y, z and optionally nx, ny, nz, all FLOAT64):
/// what reading a PLY with double coordinates gives, so the library takes the same path. Without
/// normals the cloud's bytes are the points array's bytes.
hgd::Shape shapeFromArrays(const double* points, std::size_t n, const double* normals,
                           std::vector<pcl::Vertices> faces) {
  hgd::Shape s;
  pcl::PCLPointCloud2& c = s.cloud;
  for (const char* name : {"x", "y", "z"})
    c.fields.push_back(makeField(name, static_cast<std::uint32_t>(8 * c.fields.size()), Field::FLOAT64));
  if (normals)
    for (const char* name : {"nx", "ny", "nz"})
      c.fields.push_back(makeField(name, static_cast<std::uint32_t>(8 * c.fields.size()), Field::FLOAT64));
  c.point_step = static_cast<std::uint32_t>(8 * c.fields.size());
  c.width = static_cast<std::uint32_t>(n);
  c.height = 1;
  c.row_step = c.point_step * c.width;
  c.is_bigendian = false;
  c.data.resize(static_cast<std::size_t>(c.point_step) * n);
  if (!normals) {
    if (n) std::memcpy(c.data.data(), points, 24 * n);
  } else {
    auto* out = reinterpret_cast<double*>(c.data.data());
    for (std::size_t i = 0; i < n; ++i) {
      std::memcpy(out + 6 * i, points + 3 * i, 24);
      std::memcpy(out + 6 * i + 3, normals + 3 * i, 24);
    }
  }
  bool dense = true;
  for (std::size_t i = 0; i < 3 * n && dense; ++i) dense = std::isfinite(points[i]);
  c.is_dense = dense;
  s.polygons = std::move(faces);
  s.format = hgd::FileFormat::Ply;
  return s;
}

/// numpy's dtype for a PCL field type.
py::dtype dtypeOf(std::uint8_t type) {
  switch (type) {
    case Field::INT8: return py::dtype::of<std::int8_t>();
    case Field::UINT8: return py::dtype::of<std::uint8_t>();
    case Field::INT16: return py::dtype::of<std::int16_t>();
    case Field::UINT16: return py::dtype::of<std::uint16_t>();
    case Field::INT32: return py::dtype::of<std::int32_t>();
    case Field::UINT32: return py::dtype::of<std::uint32_t>();
    case Field::INT64: return py::dtype::of<std::int64_t>();
    case Field::UINT64: return py::dtype::of<std::uint64_t>();
    case Field::FLOAT32: return py::dtype::of<float>();
    case Field::FLOAT64: return py::dtype::of<double>();
    case Field::BOOL: return py::dtype::of<bool>();
    default: throw py::type_error("a field of unknown type " + std::to_string(type));
  }
}

/// The PCL field type for a numpy dtype (bool and the sized integer and float types).
std::uint8_t typeOf(const py::dtype& dt, const std::string& name) {
  const char kind = dt.kind();
  const auto size = dt.itemsize();
  if (kind == 'b') return Field::BOOL;
  if (kind == 'f' && size == 4) return Field::FLOAT32;
  if (kind == 'f' && size == 8) return Field::FLOAT64;
  if (kind == 'i' || kind == 'u') {
    const bool u = kind == 'u';
    switch (size) {
      case 1: return u ? Field::UINT8 : Field::INT8;
      case 2: return u ? Field::UINT16 : Field::INT16;
      case 4: return u ? Field::UINT32 : Field::INT32;
      case 8: return u ? Field::UINT64 : Field::INT64;
      default: break;
    }
  }
  throw py::type_error("field " + name + ": a field holds bool, integers or float32/float64, got dtype " +
                       dtypeText(dt));
}

bool isPositionOrNormal(const std::string& name) {
  static const char* const names[] = {"x", "y", "z", "nx", "ny", "nz", "normal_x", "normal_y", "normal_z"};
  return std::find_if(std::begin(names), std::end(names), [&](const char* n) { return name == n; }) !=
         std::end(names);
}

/// Three fields of `c` (x/y/z or the normals) for every point, as an N×3 float64 array.
py::array_t<double> readTriples(const pcl::PCLPointCloud2& c, int a, int b, int d) {
  const std::size_t n = static_cast<std::size_t>(c.width) * c.height;
  py::array_t<double> out({static_cast<py::ssize_t>(n), py::ssize_t{3}});
  double* o = out.mutable_data();
  const Field &fa = c.fields[static_cast<std::size_t>(a)], &fb = c.fields[static_cast<std::size_t>(b)],
              &fd = c.fields[static_cast<std::size_t>(d)];
  if (fa.datatype == Field::FLOAT64 && fb.datatype == Field::FLOAT64 && fd.datatype == Field::FLOAT64) {
    for (std::size_t i = 0; i < n; ++i) {  // the exact bits, without the per-value conversion
      const std::uint8_t* p = c.data.data() + i * c.point_step;
      std::memcpy(o + 3 * i, p + fa.offset, 8);
      std::memcpy(o + 3 * i + 1, p + fb.offset, 8);
      std::memcpy(o + 3 * i + 2, p + fd.offset, 8);
    }
    return out;
  }
  for (std::size_t i = 0; i < n; ++i) {
    o[3 * i] = hgd::readValue(c, i, fa);
    o[3 * i + 1] = hgd::readValue(c, i, fb);
    o[3 * i + 2] = hgd::readValue(c, i, fd);
  }
  return out;
}

void writeTriples(pcl::PCLPointCloud2& c, int a, int b, int d, const Doubles& v) {
  const std::size_t n = static_cast<std::size_t>(c.width) * c.height;
  const double* p = v.data();
  const Field fa = c.fields[static_cast<std::size_t>(a)], fb = c.fields[static_cast<std::size_t>(b)],
              fd = c.fields[static_cast<std::size_t>(d)];
  for (std::size_t i = 0; i < n; ++i) {
    hgd::writeValue(c, i, fa, p[3 * i]);
    hgd::writeValue(c, i, fb, p[3 * i + 1]);
    hgd::writeValue(c, i, fd, p[3 * i + 2]);
  }
}

/// Appends a field of `type` × `count` to every point (zero), repacking the records.
int appendField(pcl::PCLPointCloud2& c, const std::string& name, std::uint8_t type, std::uint32_t count) {
  const std::size_t n = static_cast<std::size_t>(c.width) * c.height;
  const std::uint32_t old_step = c.point_step;
  const auto add = static_cast<std::uint32_t>(hgd::datatypeSize(type) * count);
  std::vector<std::uint8_t> data(static_cast<std::size_t>(old_step + add) * n, 0);
  for (std::size_t i = 0; i < n; ++i)
    std::memcpy(data.data() + i * (old_step + add), c.data.data() + i * old_step, old_step);
  c.data.swap(data);
  c.fields.push_back(makeField(name, old_step, type, count));
  c.point_step = old_step + add;
  c.row_step = c.point_step * c.width;
  return static_cast<int>(c.fields.size()) - 1;
}

const char* formatName(hgd::FileFormat f) {
  switch (f) {
    case hgd::FileFormat::Ply: return "ply";
    case hgd::FileFormat::Pcd: return "pcd";
    case hgd::FileFormat::Obj: return "obj";
    case hgd::FileFormat::Xyz: return "xyz";
    case hgd::FileFormat::Off: return "off";
    case hgd::FileFormat::Stl: return "stl";
    case hgd::FileFormat::Pts: return "pts";
    case hgd::FileFormat::Las: return "las";
  }
  return "?";
}

PyShape shapeFromPython(const py::handle& points, const py::handle& normals, const py::handle& faces) {
  const Doubles p = rowsArg(points, "points", 3);
  const auto n = static_cast<std::size_t>(p.shape(0));
  if (n == 0) throw py::value_error("points must be an N×3 array with N ≥ 1, got shape (0, 3)");
  std::optional<Doubles> nv;
  if (!normals.is_none()) nv = rowsArg(normals, "normals", 3, p.shape(0), "one per point");
  return PyShape{shapeFromArrays(p.data(), n, nv ? nv->data() : nullptr, facesArg(faces, n))};
}

/// Refuses a shape held in memory (no path) without a finite point before the library sees it,
/// which would name the file ("<path>: no finite points") that there is not: a ValueError naming
/// the argument. A shape read from a file keeps the library's IoError with its path.
void requireFinitePoint(const hgd::Shape& s) {
  if (!s.path.empty()) return;
  const pcl::PCLPointCloud2& c = s.cloud;
  const hgd::XyzFields f = hgd::findXyzFields(c);
  if (!f.hasXyz()) return;  // the library's message
  const Field &fx = c.fields[static_cast<std::size_t>(f.x)], &fy = c.fields[static_cast<std::size_t>(f.y)],
              &fz = c.fields[static_cast<std::size_t>(f.z)];
  for (std::size_t i = 0, n = s.size(); i < n; ++i)
    if (std::isfinite(hgd::readValue(c, i, fx)) && std::isfinite(hgd::readValue(c, i, fy)) &&
        std::isfinite(hgd::readValue(c, i, fz)))
      return;
  throw py::value_error("points has no finite row (every point is NaN or infinite)");
}

/// x, y, z of a shape built by shapeFromArrays, as an N×3 array without a copy when the records
/// are the coordinates alone (the cloud's bytes handed to numpy).
py::array_t<double> takePoints(hgd::Shape& s) {
  pcl::PCLPointCloud2& c = s.cloud;
  const std::size_t n = s.size();
  if (c.point_step == 24) {
    auto* bytes = new std::vector<std::uint8_t>(std::move(c.data));
    py::capsule owner(bytes, [](void* p) { delete static_cast<std::vector<std::uint8_t>*>(p); });
    return py::array_t<double>({static_cast<py::ssize_t>(n), py::ssize_t{3}},
                               reinterpret_cast<const double*>(bytes->data()), owner);
  }
  const hgd::XyzFields f = hgd::findXyzFields(c);
  return readTriples(c, f.x, f.y, f.z);
}

void bindShape(py::module_& m) {
  py::class_<PyShape>(m, "Shape",
                      "A point cloud or mesh with every per-point field, in file order; what read() "
                      "gives and write() takes. Accessors return copies.")
      .def(py::init([](const ArrayLike& points, const OptionalArrayLike& normals,
                       const OptionalArrayLike& faces, const FieldsLike& fields) {
             PyShape s = shapeFromPython(points, normals, faces);
             if (!fields.is_none())
               for (const auto& item : fields.cast<py::dict>())
                 s.setField(item.first.cast<std::string>(), item.second);
             return s;
           }),
           py::arg("points"), py::arg("normals") = py::none(), py::arg("faces") = py::none(),
           py::arg("fields") = py::none(),
           "points: (N, 3) floats; normals: (N, 3) or None; faces: (M, 3) integers, a list of index "
           "lists, or None; fields: {name: (N,) or (N, k) array}.")
      .def_property("points", &PyShape::points, &PyShape::setPoints,
                    "(N, 3) float64: the positions (a copy; assigning stores them at the file's type).")
      .def_property("normals", &PyShape::normals, &PyShape::setNormals, "(N, 3) float64, or None.")
      .def_property("faces", &PyShape::faces, &PyShape::setFaces,
                    "(M, 3) int64 for triangles, else a list of int64 index arrays; (0, 3) for a cloud.")
      .def_property_readonly("fields", &PyShape::fields,
                             "{name: array}: every per-point field but positions and normals, each at its "
                             "stored dtype, (N,) or (N, k) (copies).")
      .def_property_readonly("field_names", &PyShape::fieldNames)
      .def("field", &PyShape::field, py::arg("name"), "One field's values, (N,) or (N, k), its stored dtype.")
      .def(
          "set_field",
          [](PyShape& s, const std::string& name, const ArrayLike& values) { s.setField(name, values); },
          py::arg("name"), py::arg("values"),
          "Stores (N,) or (N, k) values: converted to the field's type if it exists, else added with the "
          "array's dtype.")
      .def_property_readonly("path", [](const PyShape& s) { return s.s.path; })
      .def_property_readonly("format", [](const PyShape& s) { return formatName(s.s.format); })
      .def_property_readonly("width", [](const PyShape& s) { return s.s.cloud.width; })
      .def_property_readonly("height", [](const PyShape& s) { return s.s.cloud.height; })
      .def_property_readonly("warnings", [](const PyShape& s) { return s.s.warnings; })
      .def_property_readonly("is_mesh", [](const PyShape& s) { return s.s.isMesh(); })
      .def("__len__", &PyShape::size)
      .def("__repr__", [](const PyShape& s) {
        std::string fields;
        for (const Field& f : s.s.cloud.fields) fields += (fields.empty() ? "" : " ") + f.name;
        return "<hgdeform.Shape " + std::to_string(s.size()) + " points, " +
               std::to_string(s.s.polygons.size()) + " faces, fields: " + fields +
               (s.s.path.empty() ? std::string() : ", from " + s.s.path) + ">";
      });

  m.def(
      "read",
      [](const PathLike& p) {
        const std::string path = pathArg(p, "path");
        py::gil_scoped_release release;
        return PyShape{hgd::readShape(path)};
      },
      py::arg("path"),
      "Reads a PLY, PCD, OBJ, XYZ/TXT, PTS, LAS, OFF or STL file (by its content) into a Shape. Raises "
      "IoError.");
  m.def(
      "_write",
      [](const PathLike& p, const PyShape& shape, bool ascii) {
        const std::string path = pathArg(p, "path");
        hgd::WriteOptions wo;
        if (ascii) wo.encoding = hgd::Encoding::Ascii;
        // A copy taken with the GIL held: once it is released another thread may change the
        // Python-owned shape (set_field reallocates its records).
        const hgd::Shape copy = shape.s;
        py::gil_scoped_release release;
        hgd::writeShape(path, copy, wo);
      },
      py::arg("path"), py::arg("shape"), py::arg("ascii") = false);
  m.def(
      "_extras_lost",
      [](const PyShape& shape, const std::string& path) {
        return hgd::extrasLost(shape.s, hgd::formatFromPath(path));
      },
      py::arg("shape"), py::arg("path"));
}

}  // namespace hgd_py
