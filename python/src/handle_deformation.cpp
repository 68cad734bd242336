// hgdeform.HandleDeformation's binding (the class: handle_deformation.h).
#include "handle_deformation.h"

#include <cstring>
#include <string>
#include <vector>

#include "shape.h"

namespace hgd_py {
namespace {

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

/// The array world_points() fills: `out` when given (checked: an (n, 3) C-contiguous, writable
/// float64 array), else a new one.
py::array_t<double> worldOut(const py::handle& out, std::size_t n) {
  const auto rows = static_cast<py::ssize_t>(n);
  if (out.is_none()) return py::array_t<double>({rows, py::ssize_t{3}});
  if (!py::isinstance<py::array>(out))
    throw py::type_error("out must be a numpy array (float64, (N, 3), C-contiguous), got " + typeName(out));
  const auto a = py::reinterpret_borrow<py::array>(out);
  if (!a.dtype().is(py::dtype::of<double>()))
    throw py::type_error("out must be a float64 array, got dtype " + dtypeText(a.dtype()));
  if (a.ndim() != 2 || a.shape(0) != rows || a.shape(1) != 3)
    throw py::value_error("out must have shape (" + std::to_string(n) + ", 3), got " + shapeText(a));
  if (!(a.flags() & py::array::c_style))
    throw py::value_error("out must be C-contiguous (np.ascontiguousarray, or np.empty((N, 3)))");
  if (!a.writeable()) throw py::value_error("out is read-only");
  return py::reinterpret_borrow<py::array_t<double>>(out);
}

/// The deformed positions in the input's order, in world coordinates (float32 positions + the
/// origin, in double, as Deformer::deformedWorld gives them), into `o` (n × 3); the rows of the
/// points that are not finite (which the deformer does not hold) as the input has them.
void fillWorld(const hgd::Deformer& d, const hgd::Geometry& g, const hgd::Shape& shape, double* o) {
  const std::vector<Eigen::Vector3f>& p = d.deformedPoints();
  const std::vector<int>& index = g.raw_index;
  const std::size_t n = shape.size(), rows = index.size();
  if (p.size() != rows) throw std::logic_error("world_points: the deformer's points are not the geometry's");
  const double ox = g.origin.x(), oy = g.origin.y(), oz = g.origin.z();
  for (std::size_t k = 0; k < rows; ++k) {
    double* w = o + 3 * static_cast<std::size_t>(index[k]);
    w[0] = static_cast<double>(p[k].x()) + ox;
    w[1] = static_cast<double>(p[k].y()) + oy;
    w[2] = static_cast<double>(p[k].z()) + oz;
  }
  if (rows == n) return;
  std::vector<char> held(n, 0);
  for (const int i : index) held[static_cast<std::size_t>(i)] = 1;
  const hgd::XyzFields f = hgd::findXyzFields(shape.cloud);
  const pcl::PCLPointCloud2& c = shape.cloud;
  const Field &fx = c.fields[static_cast<std::size_t>(f.x)], &fy = c.fields[static_cast<std::size_t>(f.y)],
              &fz = c.fields[static_cast<std::size_t>(f.z)];
  for (std::size_t i = 0; i < n; ++i)
    if (!held[i]) {
      o[3 * i] = hgd::readValue(c, i, fx);
      o[3 * i + 1] = hgd::readValue(c, i, fy);
      o[3 * i + 2] = hgd::readValue(c, i, fz);
    }
}

}  // namespace

void bindHandleDeformation(py::module_& m) {
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
          "world_points",
          [](PyHandleDeformation& h, const OptionalOut& out) {
            py::array_t<double> result = worldOut(out, h.shape().size());
            double* o = result.mutable_data();
            {
              py::gil_scoped_release release;
              // Under the session's lock: a frame of another thread waits until the fill is done.
              h.withDeformer([&](const hgd::Deformer& d) { fillWorld(d, h.geometry(), h.shape(), o); });
            }
            return result;
          },
          py::arg("out") = py::none(),
          "The deformed positions in the input's order (as deform() returns them), world coordinates: "
          "(N, 3) float64, `points` + `origin` put back in input order (float32 precision, as the view); "
          "the points that are not finite as the input has them. Into `out` when given ((N, 3) float64, "
          "C-contiguous, writable), which is returned. The GIL is released while it fills.")
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

}  // namespace hgd_py
