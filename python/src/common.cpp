// The conversions of Python arguments shared by the module's files (common.h).
#include "common.h"

#include <omp.h>
#include <pthread.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>

#include "hgdeform/io/fields.h"

namespace hgd_py {

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
Doubles rowsArg(const py::handle& obj, const std::string& name, py::ssize_t cols, py::ssize_t rows,
                const std::string& rows_are) {
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

}  // namespace hgd_py
