// Shared by the files of hgdeform's Python module (python/src/): the argument types that
// signatures show, and the conversions of Python arguments (arrays, indices, faces, paths,
// options, scenarios) to the library's types. Internal to the module.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstddef>
#include <string>
#include <vector>

#include "hgdeform/app/regions.h"
#include "hgdeform/app/report.h"
#include "hgdeform/app/runner.h"
#include "hgdeform/app/scenario.h"
#include "hgdeform/io/io.h"

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
HGD_PY_ARG(OptionalOut, "numpy.ndarray | None")
#undef HGD_PY_ARG

namespace hgd_py {

using Doubles = py::array_t<double, py::array::c_style | py::array::forcecast>;
using Field = pcl::PCLPointField;

// --- arguments ---------------------------------------------------------------------------------

std::string shapeText(const py::array& a);
std::string dtypeText(const py::dtype& dt);
std::string typeName(const py::handle& obj);
/// `obj` as a numpy array (a list of lists is converted), or a TypeError naming `name`.
py::array asArray(const py::handle& obj, const std::string& name);
/// A rows × `cols` array of real numbers (any float or integer dtype, any memory order) as C-order
/// doubles, converted once (no copy when it already is one). `rows` < 0: any count.
Doubles rowsArg(const py::handle& obj, const std::string& name, py::ssize_t cols, py::ssize_t rows = -1,
                const std::string& rows_are = "");
/// MemoryError when an address-space limit leaves no room for the OpenMP team's stacks.
void checkThreadStacks();
/// A path: a str or an os.PathLike (pathlib.Path).
std::string pathArg(const py::handle& obj, const std::string& name);
/// A 3-vector (a sequence or array of 3 real numbers).
Eigen::Vector3d vec3Arg(const py::handle& obj, const std::string& name);
/// Point indices (a 1-D integer array or sequence).
std::vector<long long> indicesArg(const py::handle& obj, const std::string& name);
/// Index lists (a list of index arrays, or one index array).
std::vector<std::vector<long long>> indexLists(const py::handle& obj, const std::string& name);
/// Faces: an M×k integer array (k ≥ 3), or a sequence of index sequences, each index below `n`.
std::vector<pcl::Vertices> facesArg(const py::handle& obj, std::size_t n);
/// A read-only array over memory `owner` keeps alive.
py::array readOnlyView(const py::dtype& dt, std::vector<py::ssize_t> shape, const void* data,
                       const py::handle& owner);

// --- options and scenarios -------------------------------------------------------------------

/// The keyword options of deform(), field() and HandleDeformation() (the command line's).
hgd::RunOptions runOptions(const py::dict& options);
/// A scenario given as a Scenario, a dict (the JSON format's objects), JSON text or a path.
hgd::Scenario scenarioArg(const py::handle& obj);
/// A region where a Region is expected: a Region, or point indices (an integer array or list).
hgd::Region regionArg(const py::handle& obj, const std::string& name);
/// The report as a dict (the library's JSON serialiser, parsed).
py::object reportDict(const hgd::DeformReport& report);

// --- the bindings, one function per bound type (module.cpp calls them) ------------------------

void bindRegion(py::module_& m);
void bindScenario(py::module_& m);
void bindShape(py::module_& m);
void bindFunctions(py::module_& m);
void bindHandleDeformation(py::module_& m);

}  // namespace hgd_py
