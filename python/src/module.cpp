// hgdeform's Python module, hgdeform._hgdeform (docs/python.md): numpy arrays in and out, the GIL
// released while the library builds, solves, interpolates, reads or writes. The package around it
// (python/hgdeform/__init__.py) adds Open3D geometries; everything else is here.
//
// One file a bound type, as Open3D's cpp/pybind/geometry/ has them, each with its bindX(m):
// region.cpp, scenario.cpp, shape.cpp, functions.cpp (deform, field), handle_deformation.cpp;
// the argument conversions they share in common.h/.cpp. On the library's PCL-light API (Shape,
// Geometry, ScenarioRunner, Deformer): no PCL algorithm headers, so that the module builds fast.
#include "common.h"
#include "hgdeform/version.h"

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

  hgd_py::bindRegion(m);
  hgd_py::bindScenario(m);
  hgd_py::bindShape(m);
  hgd_py::bindFunctions(m);
  hgd_py::bindHandleDeformation(m);
}
