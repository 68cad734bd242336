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
    "deform_by_constraints",
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
    world_points() gives the deformed positions in the input's order and world coordinates
    (float64, no permutation in Python), deformed_geometry() the deformed input in kind.
    """

    def __init__(self, points, normals=None, faces=None, **options):
        # What deformed_geometry() returns in kind: the Open3D geometry itself (its other
        # attributes are copied from it), else only the kind (no second reference to the input).
        self._input = points if _is_open3d(points) else None
        self._kind = "shape" if isinstance(points, Shape) else "arrays"
        self._with_normals = normals is not None
        if _is_open3d(points):
            if normals is not None or faces is not None:
                raise TypeError("normals and faces come from the Open3D geometry itself")
            points, normals, faces = _open3d_arrays(points)
        super().__init__(points, normals, faces, **options)

    def deformed_geometry(self):
        """The deformed input, of the kind given to the constructor: a Shape for a Shape (as
        deformed_shape()), an (N, 3) float64 array for arrays (with normals given: (points,
        normals), as deform() returns them), and for an Open3D geometry (legacy
        or tensor PointCloud or TriangleMesh, or a Vector3dVector) a new one of that kind, its
        other attributes copied from the geometry as it is now. Positions (and normals) are
        deformed_shape()'s: in double from the input's values, what ``hgdeform deform`` writes.
        """
        shape = self.deformed_shape()
        if self._input is not None:
            return _open3d_like(self._input, shape.points, shape.normals)
        if self._kind == "shape":
            return shape
        if self._with_normals:
            return shape.points, shape.normals
        return shape.points


def _rigid_fit(rest, target):
    """The rotation R and the centroids (c, d) of the rigid motion x -> R (x - c) + d that takes
    `rest` (K, 3) nearest to `target` in the least-squares sense (Kabsch, without scale). With
    one point, or points on one line, the rotation is the smallest that does it."""
    import numpy as np

    c, d = rest.mean(axis=0), target.mean(axis=0)
    h = (rest - c).T @ (target - d)
    u, s, vt = np.linalg.svd(h)
    if s[0] == 0.0:  # one point (or all at one place): a translation
        return np.eye(3), c, d
    a, b = u[:, 0], vt[0]
    if s[1] <= 1e-12 * s[0] and a @ b > -1.0 + 1e-9:  # on a line: the smallest rotation that
        v, cos = np.cross(a, b), float(a @ b)            # turns its direction as the targets'
        k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
        return np.eye(3) + k + k @ k / (1.0 + cos), c, d
    sign = 1.0 if np.linalg.det(vt.T @ u.T) >= 0 else -1.0  # a rotation, not a reflection
    return vt.T @ np.diag([1.0, 1.0, sign]) @ u.T, c, d


def _axis_degrees(r):
    """A rotation matrix as (unit axis, degrees), accurate near 0 and 180 degrees."""
    import numpy as np

    w = 0.5 * np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])  # sin θ · axis
    cos = 0.5 * (np.trace(r) - 1.0)
    sin = float(np.linalg.norm(w))
    angle = np.arctan2(sin, cos)
    if sin == 0.0 and cos > 0:
        return np.array([0.0, 0.0, 1.0]), 0.0
    if cos >= 0:
        axis = w / sin
    else:  # near 180°: from the symmetric part, (R + Rᵀ)/2 − cos θ I = (1 − cos θ) a aᵀ
        b = 0.5 * (r + r.T) - cos * np.eye(3)
        j = int(np.argmax(np.diag(b)))
        axis = b[:, j] / np.sqrt(b[j, j] * (1.0 - cos))
        if axis @ w < 0:
            axis = -axis
        axis /= np.linalg.norm(axis)
    return axis, float(np.degrees(angle))


def deform_by_constraints(geometry, constraint_ids, constraint_pos, fixed_ids=None,
                          normals=None, faces=None, return_report=False, **options):
    """Deforms a geometry so that constrained points go to their targets, as Open3D's
    ``TriangleMesh.deform_as_rigid_as_possible(constraint_vertex_indices,
    constraint_vertex_positions, ...)`` is called.

    geometry: an (N, 3) array, a Shape, or an Open3D PointCloud or TriangleMesh (legacy or
        tensor) or Vector3dVector.
    constraint_ids: (K,) point indices (an array, a list or an open3d.utility.IntVector).
    constraint_pos: (K, 3) their target positions (an array or a Vector3dVector).
    fixed_ids: more point indices that stay where they are, or None.
    normals, faces: with arrays, as deform()'s. options: deform()'s (clusters, blend, ...).

    The constrained points whose target is their rest position (equal, in float64) and the
    fixed_ids are the fixed handle; the others are the manipulated handle, which moves
    rigidly: by the rotation and translation that take their rest positions nearest to their
    targets (Kabsch, least squares, no scale), applied as a frame move. Targets that are a
    rigid motion of their points are met exactly (to rounding); others in the least-squares
    sense. The rest of the shape follows as deform() makes it.

    Returns the deformed geometry of the kind given (an (N, 3) float64 array for arrays, or
    (points, normals) when normals were given), and with return_report=True a tuple with the
    report last: (geometry, report). Raises ValueError when no point is fixed or none moves.
    """
    import numpy as np

    if isinstance(geometry, Shape):
        rest = geometry.points
    elif _is_open3d(geometry):
        rest = _open3d_arrays(geometry)[0]
    else:
        rest = geometry
    rest = np.asarray(rest, dtype=np.float64)
    if rest.ndim != 2 or rest.shape[1] != 3:
        raise ValueError("geometry must be N×3 points, got shape %s" % (rest.shape,))
    n = len(rest)

    def ids_arg(values, name):
        ids = np.asarray(values)
        if ids.size == 0:
            return np.zeros(0, dtype=np.int64)
        if ids.ndim != 1 or ids.dtype.kind not in "iu":
            raise TypeError("%s must be a 1-D array of integer point indices, got %s %s"
                            % (name, ids.dtype, ids.shape))
        ids = ids.astype(np.int64)
        bad = ids[(ids < 0) | (ids >= n)]
        if len(bad):
            raise ValueError("%s: point index %d is out of range (the geometry has %d points)"
                             % (name, bad[0], n))
        return ids

    ids = ids_arg(constraint_ids, "constraint_ids")
    pos = np.asarray(constraint_pos, dtype=np.float64)
    if pos.shape != (len(ids), 3):
        raise ValueError("constraint_pos must be a K×3 array with K = %d (one per constraint "
                         "id), got shape %s" % (len(ids), pos.shape))
    if not np.isfinite(pos).all():
        raise ValueError("constraint_pos: a target is not finite")
    order = np.argsort(ids, kind="stable")
    same = ids[order][1:] == ids[order][:-1]
    if same.any():
        k = np.flatnonzero(same)
        if (pos[order][k] != pos[order][k + 1]).any():
            raise ValueError("constraint_ids: a point is given two different targets")
        ids, first = np.unique(ids, return_index=True)
        pos = pos[first]
    still = (pos == rest[ids]).all(axis=1)
    fixed = np.union1d(ids[still], ids_arg([] if fixed_ids is None else fixed_ids, "fixed_ids"))
    moving, targets = ids[~still], pos[~still]
    if np.isin(moving, fixed).any():
        raise ValueError("fixed_ids: point %d is fixed and given a target elsewhere"
                         % moving[np.isin(moving, fixed)][0])
    if len(fixed) == 0:
        raise ValueError("no fixed point: give fixed_ids, or constraints whose target is their "
                         "rest position")
    if len(moving) == 0:
        raise ValueError("no constraint moves its point (every target is its rest position)")
    if not np.isfinite(rest[moving]).all():
        raise ValueError("constraint_ids: a constrained point is not finite")
    r, centre, moved_centre = _rigid_fit(rest[moving], targets)
    axis, degrees = _axis_degrees(r)
    scenario = (Scenario().fix(Region.indices(fixed)).manipulate(Region.indices(moving))
                .frame(translate=moved_centre - centre, axis=axis, degrees=degrees,
                       center=centre))
    result = deform(geometry, scenario, normals=normals, faces=faces, **options)
    if return_report:
        return result
    return result[0] if len(result) == 2 else result[:-1]


def _no_arrays(normals, faces, what):
    if normals is not None or faces is not None:
        raise TypeError("normals and faces are given with points arrays, not with "
                        + what + " (it has its own)")
