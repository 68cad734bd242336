"""hgdeform: handle-based deformation of point clouds and meshes.

Numpy arrays in and out (Open3D geometries too), the C++ library underneath with the GIL
released while it works. See docs/python.md.

    import hgdeform
    from hgdeform import Region, Scenario

    shape = hgdeform.read("scan.ply")
    s = Scenario().fix(Region.box(lo, hi)).manipulate(Region.sphere(c, r)).drag(a, b)
    deformed, report = hgdeform.deform(shape, s)
    hgdeform.write("out.ply", deformed)
"""

import warnings as _warnings

from . import _hgdeform
from ._hgdeform import (  # noqa: F401  (the public names)
    HandleDeformation as _HandleDeformation,
    IoError,
    Region,
    Scenario,
    ScenarioError,
    Shape,
    __version__,
)

__all__ = [
    "HandleDeformation",
    "IoError",
    "MissingFileError",
    "MissingScenarioError",
    "Region",
    "Scenario",
    "ScenarioError",
    "Shape",
    "__version__",
    "deform",
    "field",
    "read",
    "write",
]

class MissingFileError(IoError, FileNotFoundError):
    """A shape file that is not there: an IoError and a FileNotFoundError (errno ENOENT,
    filename the path); its message is the library's, '<path>: cannot open: ...'."""

    def __str__(self):
        return str(self.args[0])


class MissingScenarioError(ScenarioError, FileNotFoundError):
    """A scenario file that is not there: a ScenarioError and a FileNotFoundError."""

    def __str__(self):
        return str(self.args[0])


def _refuse_missing(path, error):
    """Raises `error` (a FileNotFoundError) naming `path` when nothing is there."""
    import errno
    import os

    path = os.fspath(path)
    if isinstance(path, str) and "\0" not in path and not os.path.lexists(path):
        e = error(path + ": cannot open: No such file or directory")
        e.errno, e.strerror, e.filename = errno.ENOENT, "No such file or directory", path
        raise e


def _scenario_path(scenario):
    """The path a scenario argument names, or None (a Scenario, a dict, JSON text)."""
    import os

    if isinstance(scenario, str):
        return None if scenario.lstrip().startswith("{") else scenario
    return scenario if isinstance(scenario, os.PathLike) else None


for _cls in (IoError, ScenarioError, MissingFileError, MissingScenarioError, Region, Scenario,
             Shape):
    try:
        _cls.__module__ = "hgdeform"
    except (AttributeError, TypeError):
        pass


# --- Open3D, without importing it unless it is what was given ---------------------------------

def _is_open3d(obj):
    return type(obj).__module__.startswith("open3d")


def _open3d_tensor(geometry):
    """Whether `geometry` is one of Open3D's tensor geometries (open3d.t.geometry)."""
    return ".t." in type(geometry).__module__ + "."


def _open3d_arrays(geometry):
    """(points, normals or None, faces or None) of an Open3D PointCloud or TriangleMesh (legacy
    or tensor, open3d.t.geometry), or of a Vector3dVector of points."""
    import numpy as np

    name = type(geometry).__name__
    if name == "Vector3dVector":
        return np.asarray(geometry), None, None
    if _open3d_tensor(geometry):
        def column(attributes, key):
            return attributes[key].numpy() if key in attributes else None

        if name == "PointCloud":
            attrs = geometry.point
            return column(attrs, "positions"), column(attrs, "normals"), None
        if name == "TriangleMesh":
            attrs = geometry.vertex
            faces = column(geometry.triangle, "indices")
            return (column(attrs, "positions"), column(attrs, "normals"),
                    faces if faces is not None and len(faces) else None)
        raise TypeError("an Open3D PointCloud or TriangleMesh is taken, got open3d.t "
                        + name)
    if name == "PointCloud":
        points = np.asarray(geometry.points)
        normals = np.asarray(geometry.normals) if geometry.has_normals() else None
        return points, normals, None
    if name == "TriangleMesh":
        points = np.asarray(geometry.vertices)
        normals = (np.asarray(geometry.vertex_normals)
                   if geometry.has_vertex_normals() else None)
        faces = np.asarray(geometry.triangles)
        return points, normals, (faces if len(faces) else None)
    raise TypeError("an Open3D PointCloud or TriangleMesh is taken, got open3d "
                    + name)


def _open3d_like(geometry, points, normals):
    """A copy of `geometry` with these points (and normals), of the same kind: a legacy or a
    tensor geometry (its positions and normals keep their dtype), or a Vector3dVector."""
    import open3d

    vectors = open3d.utility.Vector3dVector
    name = type(geometry).__name__
    if name == "Vector3dVector":
        return vectors(points)
    if _open3d_tensor(geometry):
        out = geometry.clone()
        attrs = out.point if name == "PointCloud" else out.vertex

        def store(key, values):
            dtype = attrs[key].numpy().dtype
            attrs[key] = open3d.core.Tensor(values.astype(dtype, copy=False))

        store("positions", points)
        if normals is not None:
            store("normals", normals)
        if name == "TriangleMesh" and "normals" in out.triangle:
            out.compute_triangle_normals()  # the input's would be stale: the faces turned
        return out
    if name == "PointCloud":
        out = open3d.geometry.PointCloud(geometry)
        out.points = vectors(points)
        if normals is not None:
            out.normals = vectors(normals)
        return out
    out = open3d.geometry.TriangleMesh(geometry)
    out.vertices = vectors(points)
    if normals is not None:
        out.vertex_normals = vectors(normals)
    if out.has_triangle_normals():  # the input's would be stale: the faces turned
        out.compute_triangle_normals()
    return out


def _open3d_colors(geometry):
    """An Open3D geometry's colours as (N, 3) uint8 (what PLY files hold), or None."""
    import numpy as np

    name = type(geometry).__name__
    if name == "Vector3dVector":
        return None
    if _open3d_tensor(geometry):
        attrs = geometry.point if name == "PointCloud" else geometry.vertex
        if "colors" not in attrs:
            return None
        colors = attrs["colors"].numpy()
        if colors.dtype == np.uint8:
            return colors.copy()
        colors = colors.astype(np.float64)
    elif name == "PointCloud":
        if not geometry.has_colors():
            return None
        colors = np.asarray(geometry.colors)
    else:
        if not geometry.has_vertex_colors():
            return None
        colors = np.asarray(geometry.vertex_colors)
    return np.clip(np.rint(colors * 255.0), 0, 255).astype(np.uint8)


# --- the functions -----------------------------------------------------------------------------

def read(path):
    """Reads a PLY, PCD, OBJ, XYZ/TXT, PTS, LAS, OFF or STL file (by its content) into a Shape.

    path: a str or an os.PathLike. Raises IoError (an OSError) naming the file and the problem;
    MissingFileError (an IoError and a FileNotFoundError) when there is no file at `path`;
    ValueError for a path with a NUL byte, as open() does.
    """
    _refuse_missing(path, MissingFileError)
    return _hgdeform.read(path)


def deform(points, scenario, normals=None, faces=None, **options):
    """Deforms a shape as a scenario says (what ``hgdeform deform`` does).

    points: an (N, 3) array of any float dtype and memory order, a Shape, or an Open3D
        PointCloud or TriangleMesh.
    scenario: a Scenario, a dict or JSON text in the hgdeform-scenario/1 format, or a path.
    normals: (N, 3) or None (arrays only); turned with the shape when given.
    faces: (M, 3) integers, a list of index lists, or None (arrays only).
    options: clusters, blend ('rotation' or 'linear'), k, samples, joint_clusters, reweight,
        solver ('auto', 'exact', 'multilevel'), mesh_ring, full_field: the command line's.

    Returns (points, report) with points (N, 3) float64, or (points, normals, report) when
    normals were given; (Shape, report) for a Shape; (geometry, report) for Open3D, a new
    geometry of the same kind. The report is a dict with the keys of ``--report``.
    Raises ScenarioError (a ValueError) or IoError (an OSError) with the library's message.
    """
    if _scenario_path(scenario) is not None:
        _refuse_missing(_scenario_path(scenario), MissingScenarioError)
    if isinstance(points, Shape):
        _no_arrays(normals, faces, "a Shape")
        return _hgdeform._deform_shape(points, scenario, options)
    if _is_open3d(points):
        _no_arrays(normals, faces, "an Open3D geometry")
        p, n, f = _open3d_arrays(points)
        out, out_normals, report = _hgdeform._deform_arrays(p, scenario, n, f, options)
        return _open3d_like(points, out, out_normals), report
    out, out_normals, report = _hgdeform._deform_arrays(points, scenario, normals, faces,
                                                        options)
    if normals is None:
        return out, report
    return out, out_normals, report


def field(points, scenario, normals=None, faces=None, **options):
    """The harmonic field φ of a scenario's handles (what ``hgdeform field`` stores).

    points, scenario, normals, faces and options as deform()'s. Returns an (N,) float32 array
    in the input's order: 1 on the manipulated handle, 0 on the fixed ones (and on parts no
    handle reaches), NaN for points that are not finite.
    """
    if _scenario_path(scenario) is not None:
        _refuse_missing(_scenario_path(scenario), MissingScenarioError)
    if isinstance(points, Shape):
        _no_arrays(normals, faces, "a Shape")
        return _hgdeform._field_shape(points, scenario, options)
    if _is_open3d(points):
        _no_arrays(normals, faces, "an Open3D geometry")
        points, normals, faces = _open3d_arrays(points)
    return _hgdeform._field_arrays(points, scenario, normals, faces, options)


def write(path, shape, ascii=False):
    """Writes a Shape (or an (N, 3) array, or an Open3D geometry: its normals and colours, the
    colours as uint8 red/green/blue fields) to a PLY, PCD, OBJ, XYZ/TXT, PTS, LAS, OFF or STL file, chosen
    by the extension; binary unless ascii. Atomic: a failed write
    leaves no file. Warns (UserWarning) about what the format cannot hold. Raises IoError.
    """
    import os

    path = os.fspath(path)
    if not isinstance(shape, Shape):
        if _is_open3d(shape):
            p, n, f = _open3d_arrays(shape)
            colors = _open3d_colors(shape)
            shape = Shape(p, n, f)
            if colors is not None:  # as Open3D writes them: uint8 red, green, blue
                for k, name in enumerate(("red", "green", "blue")):
                    shape.set_field(name, colors[:, k])
        else:
            shape = Shape(shape)
    lost = _hgdeform._extras_lost(shape, path)
    if lost:
        _warnings.warn(path + ": " + lost, stacklevel=2)
    _hgdeform._write(path, shape, ascii)


class HandleDeformation(_HandleDeformation):
    """Interactive deformation of one shape (the C++ hgd::HandleDeformation's Python side).

        hd = hgdeform.HandleDeformation(points)       # (N, 3), a Shape or Open3D geometry
        hd.set_fixed([base_indices])
        hd.set_manipulated(hand_indices)
        view = hd.points                               # (N, 3) float32, read-only, no copy
        hd.drag(from_, to)                             # one frame: `view` now shows it
        hd.set_handle_transform(T)                     # or the frame metaphor, (4, 4)

    `points` is the deformer's own buffer: every frame writes into it and the view shows it
    without being fetched again. Its rows are in the library's (Morton) order, as
    ``hgdeform deform`` builds them: row k is input point index[k], and world = points + origin
    (the library's local frame). deformed_shape() is, in the input's order, what
    ``hgdeform deform`` writes for the same scenario, to the bit. A set_scenario that changes
    clusters or full resolution builds a new deformer: fetch `points` again after it.
    """

    def __init__(self, points, normals=None, faces=None, **options):
        if _is_open3d(points):
            if normals is not None or faces is not None:
                raise TypeError("normals and faces come from the Open3D geometry itself")
            points, normals, faces = _open3d_arrays(points)
        super().__init__(points, normals, faces, **options)


def _no_arrays(normals, faces, what):
    if normals is not None or faces is not None:
        raise TypeError("normals and faces are given with points arrays, not with "
                        + what + " (it has its own)")
