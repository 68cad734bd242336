// deform() and field() (the package's hgdeform.deform and hgdeform.field call these), and the
// C++ side of the speed check.
#include <algorithm>
#include <chrono>
#include <limits>
#include <utility>

#include "common.h"
#include "shape.h"

namespace hgd_py {
namespace {

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

}  // namespace

void bindFunctions(py::module_& m) {
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
}

}  // namespace hgd_py
