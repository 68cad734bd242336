// hgdeform's Python module, hgdeform._hgdeform (docs/python.md): numpy arrays in and out, the GIL
// released while the library builds, solves, interpolates, reads or writes. The package around it
// (python/hgdeform/__init__.py) adds Open3D geometries; everything else is here.
//
// One translation unit on the library's PCL-light API (Shape, Geometry, ScenarioRunner, Deformer):
// no PCL algorithm headers, so that the module builds in well under a minute.
#include <omp.h>
#include <pthread.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <numeric>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "hgdeform/app/regions.h"
#include "hgdeform/app/report.h"
#include "hgdeform/app/runner.h"
#include "hgdeform/app/scenario.h"
#include "hgdeform/deformer/deformer.h"
#include "hgdeform/io/fields.h"
#include "hgdeform/io/geometry.h"
#include "hgdeform/io/io.h"
#include "hgdeform/version.h"

namespace py = pybind11;

// Arguments taken as any Python object and checked by the function that takes them (arrays,
// sequences, regions, paths). They bind as py::object does, but signatures and help() name
// what is expected instead of pybind11's "handle" (`center: numpy.typing.ArrayLike | None`).
#define HGD_PY_ARG(Name, Shown)                                               \
  namespace hgd_py {                                                          \
  class Name : public py::object {                                            \
   public:                                                                    \
    PYBIND11_OBJECT_DEFAULT(Name, py::object, [](PyObject*) { return true; }) \
  };                                                                          \
  }                                                                           \
  template <>                                                                 \
  struct pybind11::detail::handle_type_name<hgd_py::Name> {                   \
    static constexpr auto name = const_name(Shown);                           \
  };
HGD_PY_ARG(ArrayLike, "numpy.typing.ArrayLike")
HGD_PY_ARG(OptionalArrayLike, "numpy.typing.ArrayLike | None")
HGD_PY_ARG(RegionLike, "Region | numpy.typing.ArrayLike")
HGD_PY_ARG(PathLike, "str | os.PathLike")
HGD_PY_ARG(ScenarioLike, "Scenario | dict | str | os.PathLike")
HGD_PY_ARG(FieldsLike, "dict[str, numpy.typing.ArrayLike] | None")
#undef HGD_PY_ARG

namespace {

using hgd_py::ArrayLike;
using hgd_py::FieldsLike;
using hgd_py::OptionalArrayLike;
using hgd_py::PathLike;
using hgd_py::RegionLike;
using hgd_py::ScenarioLike;

using Doubles = py::array_t<double, py::array::c_style | py::array::forcecast>;
using Field = pcl::PCLPointField;

// --- arguments ---------------------------------------------------------------------------------

std::string shapeText(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t d = 0; d < a.ndim(); ++d) s += (d ? ", " : "") + std::to_string(a.shape(d));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

std::string dtypeText(const py::dtype& dt) {
  return py::str(py::handle(dt)).cast<std::string>();
}

std::string typeName(const py::handle& obj) {
  return py::str(py::type::handle_of(obj).attr("__name__")).cast<std::string>();
}

/// `obj` as a numpy array (a list of lists is converted), or a TypeError naming `name`.
py::array asArray(const py::handle& obj, const std::string& name) {
  py::array a = py::array::ensure(obj);
  if (!a) {
    PyErr_Clear();
    throw py::type_error(name + " must be a numpy array, got " + typeName(obj));
  }
  return a;
}

/// A rows × `cols` array of real numbers (any float or integer dtype, any memory order) as C-order
/// doubles, converted once (no copy when it already is one). `rows` < 0: any count.
Doubles rowsArg(const py::handle& obj, const std::string& name, py::ssize_t cols, py::ssize_t rows = -1,
                const std::string& rows_are = "") {
  const py::array a = asArray(obj, name);
  const char kind = a.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u')
    throw py::type_error(name + " must hold real numbers, got dtype " + dtypeText(a.dtype()));
  if (a.ndim() != 2 || a.shape(1) != cols || (rows >= 0 && a.shape(0) != rows)) {
    std::string want = name + " must be an N×" + std::to_string(cols) + " array";
    if (rows >= 0) want += " with N = " + std::to_string(rows) + " (" + rows_are + ")";
    throw py::value_error(want + ", got shape " + shapeText(a));
  }
  return Doubles::ensure(a);
}

/// Under an address-space limit (ulimit -v), whether the OpenMP team's stacks still fit: libgomp
/// ends the whole interpreter when it cannot create a thread (status 1, no exception, no
/// `finally`). The command-line tools check the same at start (blas_guard.cpp); a module
/// cannot restart itself, so it raises MemoryError before the library works.
void checkThreadStacks() {
  rlimit rl{};
  if (getrlimit(RLIMIT_AS, &rl) != 0 || rl.rlim_cur == RLIM_INFINITY) return;
  std::size_t stack = 8u << 20;
  pthread_attr_t attr;
  if (pthread_getattr_default_np(&attr) == 0) {
    pthread_attr_getstacksize(&attr, &stack);
    pthread_attr_destroy(&attr);
  }
  // CHOLMOD asks for a team of 4 whatever the thread count.
  const int threads = std::max(omp_get_max_threads(), 4);
  const unsigned long long team = static_cast<unsigned long long>(threads - 1) * (stack + (1u << 20));
  unsigned long long pages = 0;
  if (std::FILE* f = std::fopen("/proc/self/statm", "r")) {
    if (std::fscanf(f, "%llu", &pages) != 1) pages = 0;
    std::fclose(f);
  }
  const unsigned long long mapped = pages * static_cast<unsigned long long>(sysconf(_SC_PAGESIZE));
  const unsigned long long limit = rl.rlim_cur;
  if (limit >= mapped + team + (64ull << 20)) return;
  char msg[400];
  std::snprintf(
      msg, sizeof msg,
      "the address-space limit (ulimit -v %llu kB) leaves %lld MB; %d OpenMP threads need %llu MB of "
      "stacks: set OMP_NUM_THREADS lower (or raise the limit)",
      limit / 1024, (static_cast<long long>(limit) - static_cast<long long>(mapped)) / (1 << 20), threads,
      (team + (64ull << 20)) >> 20);
  PyErr_SetString(PyExc_MemoryError, msg);
  throw py::error_already_set();
}

/// A path: a str or an os.PathLike (pathlib.Path).
std::string pathArg(const py::handle& obj, const std::string& name) {
  if (!py::isinstance<py::str>(obj) && !py::hasattr(obj, "__fspath__"))
    throw py::type_error(name + " must be a str or an os.PathLike, got " + typeName(obj));
  const py::object p = py::module_::import("os").attr("fspath")(obj);
  if (!py::isinstance<py::str>(p)) throw py::type_error(name + " must be a text path, got bytes");
  std::string path = p.cast<std::string>();
  // As Python's open(): the C library would read the path only up to the NUL (another file).
  if (path.find('\0') != std::string::npos) throw py::value_error(name + ": embedded null byte");
  return path;
}

/// A 3-vector (a sequence or array of 3 real numbers).
Eigen::Vector3d vec3Arg(const py::handle& obj, const std::string& name) {
  const py::array a = asArray(obj, name);
  const char kind = a.dtype().kind();
  if ((kind != 'f' && kind != 'i' && kind != 'u') || a.ndim() != 1 || a.shape(0) != 3)
    throw py::value_error(name + " must be 3 numbers, got " +
                          (kind == 'f' || kind == 'i' || kind == 'u' ? "shape " + shapeText(a)
                                                                     : "dtype " + dtypeText(a.dtype())));
  const Doubles d = Doubles::ensure(a);
  return {d.at(0), d.at(1), d.at(2)};
}

/// Point indices (a 1-D integer array or sequence).
std::vector<long long> indicesArg(const py::handle& obj, const std::string& name) {
  const py::array a = asArray(obj, name);
  const char kind = a.dtype().kind();
  if (kind != 'i' && kind != 'u' && !(a.size() == 0 && kind == 'f'))
    throw py::type_error(name + " must hold integer point indices, got dtype " + dtypeText(a.dtype()));
  if (a.ndim() != 1)
    throw py::value_error(name + " must be a 1-D array of point indices, got shape " + shapeText(a));
  const auto v = py::array_t<long long, py::array::c_style | py::array::forcecast>::ensure(a);
  return std::vector<long long>(v.data(), v.data() + v.size());
}

/// Faces: an M×k integer array (k ≥ 3), or a sequence of index sequences (polygons), each index
/// below `n`. None: no faces.
std::vector<pcl::Vertices> facesArg(const py::handle& obj, std::size_t n) {
  std::vector<pcl::Vertices> faces;
  if (obj.is_none()) return faces;
  auto add = [&](const py::array& a, std::size_t f) {
    const char kind = a.dtype().kind();
    if (kind != 'i' && kind != 'u')
      throw py::type_error("faces must hold integer vertex indices, got dtype " + dtypeText(a.dtype()));
    const auto v = py::array_t<long long, py::array::c_style | py::array::forcecast>::ensure(a);
    if (v.size() < 3)
      throw py::value_error("faces: face " + std::to_string(f) + " has " + std::to_string(v.size()) +
                            " vertices (at least 3)");
    pcl::Vertices poly;
    poly.vertices.reserve(static_cast<std::size_t>(v.size()));
    for (py::ssize_t k = 0; k < v.size(); ++k) {
      const long long idx = v.data()[k];
      if (idx < 0 || static_cast<std::size_t>(idx) >= n)
        throw py::value_error("faces: vertex index " + std::to_string(idx) + " of face " + std::to_string(f) +
                              " is out of range (the shape has " + std::to_string(n) + " points)");
      poly.vertices.push_back(static_cast<std::uint32_t>(idx));
    }
    faces.push_back(std::move(poly));
  };
  if (py::isinstance<py::array>(obj)) {
    const py::array a = py::reinterpret_borrow<py::array>(obj);
    if (a.ndim() != 2 || a.shape(1) < 3)
      throw py::value_error("faces must be an M×3 (or M×k) array of vertex indices, got shape " +
                            shapeText(a));
    const char kind = a.dtype().kind();
    if (kind != 'i' && kind != 'u')
      throw py::type_error("faces must hold integer vertex indices, got dtype " + dtypeText(a.dtype()));
    const auto v = py::array_t<long long, py::array::c_style | py::array::forcecast>::ensure(a);
    const auto m = static_cast<std::size_t>(v.shape(0)), k = static_cast<std::size_t>(v.shape(1));
    faces.resize(m);
    for (std::size_t f = 0; f < m; ++f) {
      faces[f].vertices.resize(k);
      for (std::size_t j = 0; j < k; ++j) {
        const long long idx = v.data()[f * k + j];
        if (idx < 0 || static_cast<std::size_t>(idx) >= n)
          throw py::value_error("faces: vertex index " + std::to_string(idx) + " of face " +
                                std::to_string(f) + " is out of range (the shape has " + std::to_string(n) +
                                " points)");
        faces[f].vertices[j] = static_cast<std::uint32_t>(idx);
      }
    }
    return faces;
  }
  if (!py::isinstance<py::sequence>(obj) || py::isinstance<py::str>(obj))
    throw py::type_error("faces must be an M×3 integer array or a list of index lists, got " + typeName(obj));
  std::size_t f = 0;
  for (const py::handle item : obj) {
    add(asArray(item, "faces[" + std::to_string(f) + "]"), f);
    ++f;
  }
  return faces;
}

// --- options and scenarios -------------------------------------------------------------------

const char* const kOptionNames =
    "clusters, blend, k, samples, joint_clusters, reweight, solver, mesh_ring, full_field";

int intOption(const py::handle& v, const std::string& key, int lo, int hi) {
  if (!PyIndex_Check(v.ptr()) || py::isinstance<py::bool_>(v))
    throw py::type_error("option " + key + " must be an integer, got " + typeName(v));
  const long long x = py::module_::import("operator").attr("index")(v).cast<long long>();
  if (x < lo || x > hi)
    throw py::value_error("option " + key + " must be " + std::to_string(lo) + " to " + std::to_string(hi) +
                          ", got " + std::to_string(x));
  return static_cast<int>(x);
}

/// A yes/no option: a bool (Python's or numpy's), nothing else (as intOption refuses a str).
bool boolOption(const py::handle& v, const std::string& key) {
  if (py::isinstance<py::bool_>(v)) return v.cast<bool>();
  if (py::hasattr(v, "dtype") && py::hasattr(v, "ndim") && v.attr("ndim").cast<int>() == 0 &&
      v.attr("dtype").attr("kind").cast<std::string>() == "b")
    return py::bool_(v.attr("item")()).cast<bool>();  // numpy.bool_
  throw py::type_error("option " + key + " must be True or False, got " + typeName(v));
}

/// The keyword options of deform(), field() and HandleDeformation(): the command line's
/// (`hgdeform deform --help`), with the same names and ranges, and the same precedence over the
/// scenario (clusters, blend).
hgd::RunOptions runOptions(const py::dict& options) {
  hgd::RunOptions ro;
  hgd::DeformOptions& opt = ro.deform;
  for (const auto& item : options) {
    const std::string key = item.first.cast<std::string>();
    const py::handle v = item.second;
    if (v.is_none()) continue;  // unset: the scenario's, else the default
    if (key == "clusters") {
      ro.clusters = intOption(v, key, 1, 1000);
    } else if (key == "k") {
      opt.field.k_neighbors = intOption(v, key, 2, 100);
    } else if (key == "samples") {
      opt.clusters.samples = intOption(v, key, 10, 10000000);
    } else if (key == "joint_clusters") {
      opt.clusters.joint_isovalues = intOption(v, key, 1, 100);
    } else if (key == "reweight") {
      opt.gauss_newton.reweight_rounds = intOption(v, key, 0, 100);
    } else if (key == "blend") {
      hgd::Blend blend;
      if (!py::isinstance<py::str>(v) || !hgd::parseBlend(v.cast<std::string>(), blend))
        throw py::value_error("option blend must be 'rotation' or 'linear', got " +
                              py::repr(v).cast<std::string>());
      ro.blend = blend;
    } else if (key == "solver") {
      const std::string s = py::isinstance<py::str>(v) ? v.cast<std::string>() : "";
      if (s == "auto")
        opt.field.solver = hgd::FieldSolver::Auto;
      else if (s == "exact")
        opt.field.solver = hgd::FieldSolver::Exact;
      else if (s == "multilevel")
        opt.field.solver = hgd::FieldSolver::Multilevel;
      else
        throw py::value_error("option solver must be 'auto', 'exact' or 'multilevel', got " +
                              py::repr(v).cast<std::string>());
    } else if (key == "mesh_ring") {
      opt.field.mesh_ring = boolOption(v, key);
    } else if (key == "full_field") {
      if (boolOption(v, key)) opt.multires_above = 0;
    } else {
      throw py::type_error("unexpected option '" + key + "' (the options: " + kOptionNames + ")");
    }
  }
  return ro;
}

/// A scenario given as a Scenario, a dict (the JSON format's objects), JSON text or a path.
hgd::Scenario scenarioArg(const py::handle& obj) {
  if (py::isinstance<hgd::Scenario>(obj)) return obj.cast<hgd::Scenario>();
  if (py::isinstance<py::dict>(obj)) {
    // numpy arrays and numbers inside (index arrays, coordinates) as the lists and numbers they hold
    const py::cpp_function numpy_values([](const py::handle& v) -> py::object {
      if (py::hasattr(v, "tolist")) return v.attr("tolist")();
      throw py::type_error("scenario: a value of type " + typeName(v) + " has no JSON form");
    });
    const std::string text =
        py::module_::import("json").attr("dumps")(obj, py::arg("default") = numpy_values).cast<std::string>();
    return hgd::parseScenario(text, "scenario");
  }
  if (py::isinstance<py::str>(obj)) {
    const std::string s = obj.cast<std::string>();
    const auto first = s.find_first_not_of(" \t\r\n");
    if (first != std::string::npos && s[first] == '{') return hgd::parseScenario(s, "scenario");
    const std::string path = pathArg(obj, "scenario");
    py::gil_scoped_release release;
    return hgd::readScenario(path);
  }
  if (py::hasattr(obj, "__fspath__")) {
    const std::string path = pathArg(obj, "scenario");
    py::gil_scoped_release release;
    return hgd::readScenario(path);
  }
  throw py::type_error("scenario must be a Scenario, a dict, JSON text or a path, got " + typeName(obj));
}

py::object reportDict(const hgd::DeformReport& report) {
  return py::module_::import("json").attr("loads")(hgd::reportJson(report));
}

// --- shapes ------------------------------------------------------------------------------------

Field makeField(const std::string& name, std::uint32_t offset, std::uint8_t type, std::uint32_t count = 1) {
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

// --- deform and field ------------------------------------------------------------------------

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

/// deform() on arrays: (points, normals or None, report).
py::tuple deformArrays(const py::handle& points, const hgd::Scenario& scenario, const py::handle& normals,
                       const py::handle& faces, const py::dict& options) {
  PyShape in = shapeFromPython(points, normals, faces);
  requireFinitePoint(in.s);
  const hgd::RunOptions ro = runOptions(options);
  hgd::DeformReport report;
  {
    py::gil_scoped_release release;
    hgd::ScenarioRunner run(std::move(in.s), ro);
    run.setScenario(scenario);
    run.applyMoves();
    in.s = run.release(true);
    report = run.report();
  }
  py::object out_normals = py::none();
  if (!normals.is_none()) {
    const hgd::XyzFields f = hgd::findXyzFields(in.s.cloud);
    out_normals = readTriples(in.s.cloud, f.nx, f.ny, f.nz);
  }
  py::array_t<double> out_points = takePoints(in.s);
  return py::make_tuple(out_points, out_normals, reportDict(report));
}

/// deform() on a Shape: (the deformed shape, report).
/// The shape is copied while the GIL is held: another thread may change (and reallocate) the
/// Python-owned shape once it is released.
py::tuple deformShape(const PyShape& shape, const hgd::Scenario& scenario, const py::dict& options) {
  const hgd::RunOptions ro = runOptions(options);
  hgd::Shape in = shape.s;
  requireFinitePoint(in);
  PyShape out;
  hgd::DeformReport report;
  {
    py::gil_scoped_release release;
    hgd::ScenarioRunner run(std::move(in), ro);
    run.setScenario(scenario);
    run.applyMoves();
    out.s = run.release(true);
    report = run.report();
  }
  return py::make_tuple(std::move(out), reportDict(report));
}

/// φ in file order: float32, NaN for the points the field does not cover (not finite, set apart).
/// `shape` is the caller's own copy (taken while the GIL was held), handed to the runner.
py::array_t<float> fieldOf(hgd::Shape shape, const hgd::Scenario& scenario, const py::dict& options) {
  requireFinitePoint(shape);
  const hgd::RunOptions ro = runOptions(options);
  const std::size_t n = shape.size();
  py::array_t<float> out(static_cast<py::ssize_t>(n));
  float* o = out.mutable_data();
  {
    py::gil_scoped_release release;
    const hgd::ScenarioRunner run(std::move(shape), ro);
    const hgd::FieldResult r = run.field(scenario);
    std::fill(o, o + n, std::numeric_limits<float>::quiet_NaN());
    const hgd::Geometry& g = run.geometry();
    for (std::size_t k = 0; k < r.values.size(); ++k) o[g.raw_index[k]] = r.values[k];
  }
  return out;
}

/// The C++ side of the speed check (python/bench/bench_python.py): the work deform() does on arrays,
/// timed in C++ on a shape built beforehand (milliseconds; the GIL released throughout).
double cppDeformMs(const py::handle& points, const hgd::Scenario& scenario, const py::dict& options) {
  PyShape in = shapeFromPython(points, py::none(), py::none());
  const hgd::RunOptions ro = runOptions(options);
  py::gil_scoped_release release;
  const auto t0 = std::chrono::steady_clock::now();
  hgd::ScenarioRunner run(std::move(in.s), ro);
  run.setScenario(scenario);
  run.applyMoves();
  in.s = run.release(true);
  const hgd::DeformReport report = run.report();  // as deform() makes it (the surface stretch)
  const auto t1 = std::chrono::steady_clock::now();
  static_cast<void>(report);
  return std::chrono::duration<double, std::milli>(t1 - t0).count();
}

// --- HandleDeformation -------------------------------------------------------------------------

/// Interactive deformation of one shape: handles by index (or a scenario), frames one at a time,
/// the deformed positions as a read-only view of the deformer's own buffer.
class PyHandleDeformation {
 public:
  // extractGeometry's own geometry (Morton order, its origin), as `hgdeform deform` builds it:
  // the library's sampling depends on the points' order, so any other order gives another
  // (equally valid, not bit-equal) result. The session behind it is the CLI's (hgd::Session,
  // through ScenarioRunner): the same handles, rebuild rule and moves.
  PyHandleDeformation(hgd::Shape shape, hgd::RunOptions options)
      : run_((checkThreadStacks(), std::move(shape)), options) {}

  void setFixed(const std::vector<std::vector<long long>>& handles) {
    std::lock_guard<std::mutex> lock(mutex_);
    run_.session().setFixedIndices(handles);
  }
  void setManipulated(std::vector<long long> handle) {
    std::lock_guard<std::mutex> lock(mutex_);
    run_.session().setManipulatedIndices(std::move(handle));
  }
  void setJoints(const std::vector<std::vector<long long>>& joints) {
    std::lock_guard<std::mutex> lock(mutex_);
    run_.session().setJointIndices(joints);
  }
  void setScenario(const hgd::Scenario& scenario) {
    std::lock_guard<std::mutex> lock(mutex_);
    run_.session().setScenario(scenario);
  }

  hgd::SolveStats drag(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    return run_.deformer().drag(from, to);
  }
  hgd::DragResult dragTo(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    return run_.deformer().dragTo(from, to);
  }
  hgd::SolveStats setHandleTransform(const Eigen::Affine3d& t) {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    return run_.deformer().setHandleTransform(t);
  }
  void reset() {
    std::lock_guard<std::mutex> lock(mutex_);
    run_.reset();  // also after a handle change not built yet
  }
  void build() {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
  }

  /// The deformer (built first if due), whose positions are the buffer `points` views: no frame
  /// or handle change moves it (Deformer sizes it once); a rebuild for other options (clusters,
  /// samples, full resolution) makes a new deformer, and the old one lives on as long as a view
  /// of it does.
  std::shared_ptr<const hgd::Deformer> deformer() {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    // The build's first shape is made when first read: here, under the lock, so that a view's
    // later read only reads (another thread's move or rebuild waits for this lock).
    (void)run_.deformer().deformedPoints();
    return run_.sharedDeformer();
  }
  std::vector<Eigen::Vector3f> normals() {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    return run_.deformer().deformedNormals();
  }
  std::vector<float> field() {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    return run_.deformer().field();
  }
  /// The deformed shape written as `hgdeform deform` writes it (in double from the input's values).
  hgd::Shape deformedShape() {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    return run_.deformedShape();
  }
  double lastInterpolationMs() {
    std::lock_guard<std::mutex> lock(mutex_);
    const std::shared_ptr<const hgd::Deformer> d = run_.sharedDeformer();
    return d ? d->lastInterpolationMs() : 0.0;
  }
  hgd::Energies energies() {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    return run_.deformer().energies();
  }

  const hgd::Geometry& geometry() const { return run_.geometry(); }
  const hgd::Shape& shape() const { return run_.shape(); }

 private:
  void ensureBuilt() {
    const std::string missing = run_.session().missingHandle();
    if (missing == "fixed")
      throw hgd::ScenarioError("HandleDeformation: no fixed handle (set_fixed or set_scenario)");
    if (!missing.empty())
      throw hgd::ScenarioError("HandleDeformation: no manipulated handle (set_manipulated or set_scenario)");
    if (run_.ensureBuilt()) run_.applyMoves();  // a scenario's moves, as `hgdeform deform` applies them
  }

  hgd::ScenarioRunner run_;
  std::mutex mutex_;  // one frame at a time (the GIL is released while it runs)
};

py::dict solveStats(const hgd::SolveStats& s, double interpolation_ms) {
  py::dict d;
  d["interpolation_ms"] = interpolation_ms;
  d["iterations"] = s.iterations;
  d["converged"] = s.converged;
  d["decreased"] = s.decreased;
  d["energy"] = s.energy.total();
  d["solve_ms"] = s.ms;
  return d;
}

std::vector<std::vector<long long>> indexLists(const py::handle& obj, const std::string& name) {
  std::vector<std::vector<long long>> out;
  if (py::isinstance<py::array>(obj) && py::reinterpret_borrow<py::array>(obj).ndim() == 1) {
    out.push_back(indicesArg(obj, name));  // one handle
    return out;
  }
  if (!py::isinstance<py::sequence>(obj) || py::isinstance<py::str>(obj))
    throw py::type_error(name + " must be a list of index arrays, got " + typeName(obj));
  // A flat, non-empty sequence of integers is one handle too, as a 1-D array is.
  const auto seq = py::reinterpret_borrow<py::sequence>(obj);
  const bool flat = py::len(seq) > 0 && std::all_of(seq.begin(), seq.end(), [](const py::handle& item) {
                      return PyIndex_Check(item.ptr()) && !py::isinstance<py::array>(item) &&
                             !py::isinstance<py::bool_>(item);
                    });
  if (flat) {
    out.push_back(indicesArg(obj, name));
    return out;
  }
  std::size_t k = 0;
  for (const py::handle item : obj) out.push_back(indicesArg(item, name + "[" + std::to_string(k++) + "]"));
  return out;
}

/// A read-only array over memory `owner` keeps alive.
py::array readOnlyView(const py::dtype& dt, std::vector<py::ssize_t> shape, const void* data,
                       const py::handle& owner) {
  py::array a(dt, std::move(shape), data, owner);
  a.attr("setflags")(py::arg("write") = false);
  return a;
}

/// A region where a Region is expected: a Region, or point indices (an integer array or list).
hgd::Region regionArg(const py::handle& obj, const std::string& name) {
  if (py::isinstance<hgd::Region>(obj)) return obj.cast<hgd::Region>();
  return hgd::Region::fromIndices(indicesArg(obj, name));
}

std::string vecText(const Eigen::Vector3d& v) {
  return "(" + py::repr(py::float_(v.x())).cast<std::string>() + ", " +
         py::repr(py::float_(v.y())).cast<std::string>() + ", " +
         py::repr(py::float_(v.z())).cast<std::string>() + ")";
}

std::string regionText(const hgd::Region& r) {
  using K = hgd::Region::Kind;
  const std::string radius = py::repr(py::float_(r.radius)).cast<std::string>();
  switch (r.kind) {
    case K::Sphere: return "Region.sphere(" + vecText(r.centre) + ", " + radius + ")";
    case K::Box: return "Region.box(" + vecText(r.min) + ", " + vecText(r.max) + ")";
    case K::Cylinder:
      return "Region.cylinder(" + vecText(r.start) + ", " + vecText(r.end) + ", " + radius + ")";
    case K::Indices: return "Region.indices(<" + std::to_string(r.indices.size()) + " indices>)";
    case K::Field:
      if (r.equals)
        return "Region.field('" + r.field_name + "', " + py::repr(py::float_(*r.equals)).cast<std::string>() +
               ")";
      return "Region.field_range('" + r.field_name + "', " +
             py::repr(py::float_(r.field_min)).cast<std::string>() + ", " +
             py::repr(py::float_(r.field_max)).cast<std::string>() + ")";
  }
  return "Region()";
}

}  // namespace

PYBIND11_MODULE(_hgdeform, m) {
  m.doc() =
      "hgdeform: handle-based deformation of point clouds and meshes (harmonic-guided clustering). "
      "The package hgdeform wraps this module; see docs/python.md.";
  m.attr("__version__") = HGDEFORM_VERSION;  // CMake's project(VERSION), through version.h

  // The library's two exception types, with their messages: a ValueError and an OSError.
  py::register_exception<hgd::ScenarioError>(m, "ScenarioError", PyExc_ValueError).attr("__doc__") =
      "A scenario that does not parse or does not fit its shape (a ValueError). The message names the "
      "place: '<file>: <json path>: <problem>'.";
  py::register_exception<hgd::IoError>(m, "IoError", PyExc_OSError).attr("__doc__") =
      "A shape file that cannot be read or written (an OSError). The message reads '<path>: <problem>'.";

  // --- regions and scenarios ---
  py::class_<hgd::Region>(m, "Region",
                          "A part of a shape: a sphere, a box, a cylinder, point indices, or the points "
                          "whose per-point field has a value or lies in a range (docs/scenario.md).")
      .def_static(
          "sphere", [](const ArrayLike& c, double r) { return hgd::Region::sphere(vec3Arg(c, "center"), r); },
          py::arg("center"), py::arg("radius"), "The points within `radius` of `center` (3 numbers).")
      .def_static(
          "box",
          [](const ArrayLike& lo, const ArrayLike& hi) {
            return hgd::Region::box(vec3Arg(lo, "min"), vec3Arg(hi, "max"));
          },
          py::arg("min"), py::arg("max"),
          "The points inside the axis-aligned box [min, max] (3 numbers each).")
      .def_static(
          "cylinder",
          [](const ArrayLike& a, const ArrayLike& b, double r) {
            return hgd::Region::cylinder(vec3Arg(a, "start"), vec3Arg(b, "end"), r);
          },
          py::arg("start"), py::arg("end"), py::arg("radius"),
          "The points within `radius` of the segment start-end, flat caps.")
      .def_static(
          "indices",
          [](const ArrayLike& idx) { return hgd::Region::fromIndices(indicesArg(idx, "indices")); },
          py::arg("indices"),
          "The points with these 0-based indices (an integer array of shape (K,)), file order.")
      .def_static("field", &hgd::Region::field, py::arg("name"), py::arg("value"),
                  "The points whose per-point field `name` equals `value`.")
      .def_static(
          "field_range",
          [](const std::string& name, std::optional<double> lo, std::optional<double> hi) {
            return hgd::Region::fieldRange(name, lo ? *lo : -INFINITY, hi ? *hi : INFINITY);
          },
          py::arg("name"), py::arg("min") = py::none(), py::arg("max") = py::none(),
          "The points whose field `name` lies in [min, max] (None: unbounded).")
      .def("__repr__", &regionText);

  py::class_<hgd::Scenario>(
      m, "Scenario",
      "Handles and moves, built in code as in C++:\n\n"
      "    Scenario().fix(Region.box(lo, hi)).manipulate(Region.sphere(c, r)).drag(a, b)\n\n"
      "Wherever a Region is taken, an integer index array is taken too.")
      .def(py::init<>())
      .def(
          "fix",
          [](hgd::Scenario& s, const RegionLike& r) -> hgd::Scenario& {
            return s.fix(regionArg(r, "region"));
          },
          py::arg("region"), py::return_value_policy::reference_internal,
          "Adds a fixed handle; returns self.")
      .def(
          "manipulate",
          [](hgd::Scenario& s, const RegionLike& r) -> hgd::Scenario& {
            return s.manipulate(regionArg(r, "region"));
          },
          py::arg("region"), py::return_value_policy::reference_internal,
          "Sets the manipulated handle; returns self.")
      .def(
          "joint",
          [](hgd::Scenario& s, const RegionLike& r) -> hgd::Scenario& {
            return s.joint(regionArg(r, "region"));
          },
          py::arg("region"), py::return_value_policy::reference_internal,
          "Adds a joint (skeletal deformation); returns self.")
      .def(
          "drag",
          [](hgd::Scenario& s, const ArrayLike& from, const ArrayLike& to, bool keep) -> hgd::Scenario& {
            return s.drag(vec3Arg(from, "from"), vec3Arg(to, "to"), keep);
          },
          py::arg("from_"), py::arg("to"), py::arg("keep_orientation") = false,
          py::return_value_policy::reference_internal,
          "Adds a drag: the manipulated handle's point nearest `from_` is dragged to `to`; returns self.")
      .def(
          "frame",
          [](hgd::Scenario& s, const ArrayLike& translate, const ArrayLike& axis, double degrees,
             const OptionalArrayLike& center) -> hgd::Scenario& {
            hgd::FrameMove f;
            f.translate = vec3Arg(translate, "translate");
            f.axis = vec3Arg(axis, "axis");
            f.degrees = degrees;
            if (!center.is_none()) f.centre = vec3Arg(center, "center");
            return s.frame(f);
          },
          py::arg("translate") = py::make_tuple(0, 0, 0), py::arg("axis") = py::make_tuple(0, 0, 1),
          py::arg("degrees") = 0.0, py::arg("center") = py::none(),
          py::return_value_policy::reference_internal,
          "Adds a frame move: x -> R(axis, degrees)(x - center) + center + translate (center: the "
          "handle's barycentre when None); returns self.")
      .def_property(
          "clusters", [](const hgd::Scenario& s) { return s.clusters; },
          [](hgd::Scenario& s, std::optional<int> c) { s.clusters = c; }, "Isovalue count, or None (16).")
      .def_property(
          "blend",
          [](const hgd::Scenario& s) -> py::object {
            return s.blend ? py::str(hgd::blendName(*s.blend)) : py::object(py::none());
          },
          [](hgd::Scenario& s, std::optional<std::string> b) {
            if (!b) {
              s.blend.reset();
              return;
            }
            hgd::Blend blend;
            if (!hgd::parseBlend(*b, blend))
              throw py::value_error("blend must be 'rotation' or 'linear', got '" + *b + "'");
            s.blend = blend;
          },
          "'rotation', 'linear', or None (rotation).")
      .def_static("from_json", &hgd::parseScenario, py::arg("text"), py::arg("name") = "scenario",
                  "Parses hgdeform-scenario/1 JSON text (`name` in messages).")
      .def_static(
          "read",
          [](const PathLike& p) {
            const std::string path = pathArg(p, "path");
            py::gil_scoped_release release;
            return hgd::readScenario(path);
          },
          py::arg("path"), "Reads a scenario file.")
      .def("to_json", &hgd::scenarioToJson, "The scenario as hgdeform-scenario/1 JSON text.")
      .def("__repr__",
           [](const hgd::Scenario& s) { return "Scenario.from_json('''" + hgd::scenarioToJson(s) + "''')"; });

  // --- shapes ---
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

  m.def(
      "_scenario", [](const ScenarioLike& scenario) { return scenarioArg(scenario); }, py::arg("scenario"));
  m.def(
      "_deform_arrays",
      [](const ArrayLike& points, const ScenarioLike& scenario, const OptionalArrayLike& normals,
         const OptionalArrayLike& faces, const py::dict& options) {
        checkThreadStacks();
        return deformArrays(points, scenarioArg(scenario), normals, faces, options);
      },
      py::arg("points"), py::arg("scenario"), py::arg("normals"), py::arg("faces"), py::arg("options"));
  m.def(
      "_deform_shape",
      [](const PyShape& shape, const ScenarioLike& scenario, const py::dict& options) {
        checkThreadStacks();
        return deformShape(shape, scenarioArg(scenario), options);
      },
      py::arg("shape"), py::arg("scenario"), py::arg("options"));
  m.def(
      "_field_arrays",
      [](const ArrayLike& points, const ScenarioLike& scenario, const OptionalArrayLike& normals,
         const OptionalArrayLike& faces, const py::dict& options) {
        checkThreadStacks();
        PyShape s = shapeFromPython(points, normals, faces);
        return fieldOf(std::move(s.s), scenarioArg(scenario), options);
      },
      py::arg("points"), py::arg("scenario"), py::arg("normals"), py::arg("faces"), py::arg("options"));
  m.def(
      "_field_shape",
      [](const PyShape& shape, const ScenarioLike& scenario, const py::dict& options) {
        checkThreadStacks();
        const hgd::Scenario sc = scenarioArg(scenario);  // (may release the GIL: a scenario file)
        return fieldOf(shape.s, sc, options);            // a copy, taken with the GIL held
      },
      py::arg("shape"), py::arg("scenario"), py::arg("options"));
  m.def(
      "_cpp_deform_ms",
      [](const ArrayLike& points, const ScenarioLike& scenario, const py::dict& options) {
        return cppDeformMs(points, scenarioArg(scenario), options);
      },
      py::arg("points"), py::arg("scenario"), py::arg("options"));

  // --- HandleDeformation ---
  py::class_<PyHandleDeformation>(
      m, "HandleDeformation",
      "Interactive deformation of one shape: set the handles (point indices, or a scenario), then "
      "drag or set the handle's transform frame by frame. `points` is a read-only view of the "
      "deformer's own buffer (no copy per frame).")
      .def(py::init([](const ArrayLike& points, const OptionalArrayLike& normals,
                       const OptionalArrayLike& faces, const py::kwargs& options) {
             hgd::Shape shape = py::isinstance<PyShape>(points) ? points.cast<const PyShape&>().s
                                                                : shapeFromPython(points, normals, faces).s;
             requireFinitePoint(shape);
             const hgd::RunOptions ro = runOptions(options);
             py::gil_scoped_release release;
             return std::make_unique<PyHandleDeformation>(std::move(shape), ro);
           }),
           py::arg("points"), py::arg("normals") = py::none(), py::arg("faces") = py::none(),
           "points: (N, 3) floats or a Shape; normals: (N, 3) or None; faces: (M, 3) integers or None; "
           "options as deform()'s.")
      .def(
          "set_fixed",
          [](PyHandleDeformation& h, const ArrayLike& handles) { h.setFixed(indexLists(handles, "fixed")); },
          py::arg("handles"), "The fixed handles: a list of index arrays (or one index array).")
      .def(
          "set_manipulated",
          [](PyHandleDeformation& h, const ArrayLike& handle) {
            h.setManipulated(indicesArg(handle, "manipulated"));
          },
          py::arg("handle"), "The manipulated handle: an index array (K,).")
      .def(
          "set_joints",
          [](PyHandleDeformation& h, const ArrayLike& joints) { h.setJoints(indexLists(joints, "joints")); },
          py::arg("joints"), "Joints (skeletal deformation): a list of index arrays.")
      .def(
          "set_scenario",
          [](PyHandleDeformation& h, const ScenarioLike& s) { h.setScenario(scenarioArg(s)); },
          py::arg("scenario"),
          "Handles (and clusters, blend) from a scenario; its moves are applied when the deformer is built.")
      .def(
          "build",
          [](PyHandleDeformation& h) {
            py::gil_scoped_release release;
            h.build();
          },
          "Builds the deformer now (else the first frame or `points` does).")
      .def(
          "drag",
          [](PyHandleDeformation& h, const ArrayLike& from, const ArrayLike& to) {
            const Eigen::Vector3d a = vec3Arg(from, "from_"), b = vec3Arg(to, "to");
            hgd::SolveStats s;
            {
              py::gil_scoped_release release;
              s = h.drag(a, b);
            }
            return solveStats(s, h.lastInterpolationMs());
          },
          py::arg("from_"), py::arg("to"),
          "One interactive frame: the manipulated handle's point nearest `from_` (3 numbers, deformed "
          "shape) is pulled towards `to`. Returns the solve's figures.")
      .def(
          "drag_to",
          [](PyHandleDeformation& h, const ArrayLike& from, const ArrayLike& to) {
            const Eigen::Vector3d a = vec3Arg(from, "from_"), b = vec3Arg(to, "to");
            hgd::DragResult r;
            {
              py::gil_scoped_release release;
              r = h.dragTo(a, b);
            }
            py::dict d;
            d["frames"] = r.frames;
            d["iterations"] = r.iterations;
            d["error"] = r.error;
            d["reached"] = r.reached;
            return d;
          },
          py::arg("from_"), py::arg("to"),
          "A whole drag replayed until the picked point reaches `to` (a scenario's drag).")
      .def(
          "set_handle_transform",
          [](PyHandleDeformation& h, const ArrayLike& transform) {
            const Doubles t = rowsArg(transform, "transform", 4, 4, "a 4×4 matrix");
            Eigen::Affine3d a;
            a.matrix() = Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(t.data());
            // A rigid motion, as documented: a bottom row other than 0 0 0 1 (a transposed
            // translation) was dropped, a scaling or singular matrix applied.
            if (!a.matrix().allFinite()) throw py::value_error("transform: not finite");
            if (a.matrix().row(3) != Eigen::RowVector4d(0, 0, 0, 1))
              throw py::value_error(
                  "transform: the bottom row must be 0 0 0 1 (a rigid motion; is the matrix "
                  "transposed?)");
            const Eigen::Matrix3d r = a.linear();
            const double off = (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
            if (off > 1e-6 || r.determinant() <= 0)
              throw py::value_error(
                  "transform: the upper-left 3×3 must be a rotation (orthonormal, determinant 1); "
                  "got one " +
                  std::string(r.determinant() <= 0 ? "that reflects or is singular"
                                                   : "that scales or shears") +
                  " (|RᵀR − I| = " + std::to_string(off) + ")");
            hgd::SolveStats s;
            {
              py::gil_scoped_release release;
              s = h.setHandleTransform(a);
            }
            return solveStats(s, h.lastInterpolationMs());
          },
          py::arg("transform"),
          "Frame metaphor: the manipulated handle gets this (4, 4) rigid transform (world, relative to rest) "
          "exactly. A matrix that is not a rotation and a translation (bottom row 0 0 0 1) is a ValueError.")
      .def(
          "reset",
          [](PyHandleDeformation& h) {
            py::gil_scoped_release release;
            h.reset();
          },
          "Back to the rest shape.")
      .def_property_readonly(
          "points",
          [](PyHandleDeformation& h) {
            std::shared_ptr<const hgd::Deformer> d;
            {
              py::gil_scoped_release release;
              d = h.deformer();
            }
            const std::vector<Eigen::Vector3f>& p = d->deformedPoints();
            // The view keeps this deformer (its buffer) alive, even past a rebuild.
            const py::capsule owner(new std::shared_ptr<const hgd::Deformer>(d), [](void* x) {
              delete static_cast<std::shared_ptr<const hgd::Deformer>*>(x);
            });
            return readOnlyView(py::dtype::of<float>(), {static_cast<py::ssize_t>(p.size()), 3}, p.data(),
                                owner);
          },
          "(N, 3) float32, read-only: a view of the deformer's own buffer, updated in place by every "
          "frame (no copy). Rows in the library's (Morton) order: row k is input point index[k]; "
          "world = points + origin. A set_scenario that changes clusters or full resolution builds a "
          "new deformer: fetch `points` again after it (an older view keeps the old buffer).")
      .def_property_readonly(
          "index",
          [](py::object self) {
            const auto& g = self.cast<PyHandleDeformation&>().geometry();
            return readOnlyView(py::dtype::of<int>(), {static_cast<py::ssize_t>(g.raw_index.size())},
                                g.raw_index.data(), self);
          },
          "(N,) int32, read-only: the input point of each row of `points` (points[k] is input point "
          "index[k]; inverse: rows = np.argsort(index) when every point is finite).")
      .def_property_readonly(
          "origin",
          [](const PyHandleDeformation& h) {
            const Eigen::Vector3d& o = h.geometry().origin;
            return py::make_tuple(o.x(), o.y(), o.z());
          },
          "world = points + origin: the centre of the shape's body, rounded (the library's local frame, "
          "which keeps float32 positions exact to the shape's detail).")
      .def_property_readonly(
          "normals",
          [](PyHandleDeformation& h) {
            std::vector<Eigen::Vector3f> n;
            {
              py::gil_scoped_release release;
              n = h.normals();
            }
            py::array_t<float> out({static_cast<py::ssize_t>(n.size()), py::ssize_t{3}});
            std::memcpy(out.mutable_data(), n.data(), n.size() * sizeof(Eigen::Vector3f));
            return out;
          },
          "(N, 3) float32: the deformed normals (a copy, derived when read), rows as `points`.")
      .def_property_readonly(
          "field",
          [](PyHandleDeformation& h) {
            std::vector<float> phi;
            {
              py::gil_scoped_release release;
              phi = h.field();
            }
            return py::array_t<float>(static_cast<py::ssize_t>(phi.size()), phi.data());
          },
          "(N,) float32: the harmonic field φ (1 on the manipulated handle, 0 on the fixed), rows as "
          "`points`.")
      .def(
          "deformed_shape",
          [](PyHandleDeformation& h) {
            PyShape out;
            {
              py::gil_scoped_release release;
              out.s = h.deformedShape();
            }
            return out;
          },
          "The deformed Shape in the input's order, in double from the input's values: what `hgdeform "
          "deform` writes for the same scenario, to the bit.")
      .def_property_readonly("energy", [](PyHandleDeformation& h) {
        hgd::Energies e;
        {
          py::gil_scoped_release release;
          e = h.energies();
        }
        py::dict d;
        d["detail"] = e.detail;
        d["prop"] = e.prop;
        d["manip"] = e.manip;
        d["length"] = e.length;
        d["total"] = e.total();
        return d;
      });
}
