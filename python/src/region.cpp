// hgdeform.Region: the parts of a shape handles are made of (docs/scenario.md).
#include <cmath>
#include <optional>
#include <string>

#include "common.h"

namespace hgd_py {
namespace {

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

void bindRegion(py::module_& m) {
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
}

}  // namespace hgd_py
