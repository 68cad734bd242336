// hgdeform.Scenario: handles and moves, built in code as in C++ (docs/scenario.md).
#include <optional>
#include <string>

#include "common.h"

namespace hgd_py {

void bindScenario(py::module_& m) {
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
}

}  // namespace hgd_py
