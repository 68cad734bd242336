# Type stub of the hgdeform package (the module hgdeform._hgdeform and python/hgdeform/__init__.py),
# for editors and type checkers. Array shapes are in the docstrings: N points, M faces.
import os
from typing import Any, Dict, List, Literal, Optional, Sequence, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

__version__: str

ArrayLike = npt.ArrayLike
PathLike = Union[str, os.PathLike]
ScenarioLike = Union["Scenario", Dict[str, Any], str, os.PathLike]
Vec3 = Union[Sequence[float], npt.NDArray[np.floating]]
Faces = Union[npt.NDArray[np.integer], Sequence[Sequence[int]]]

class ScenarioError(ValueError):
    """A scenario that does not parse or does not fit its shape; '<file>: <json path>: <problem>'."""

class IoError(OSError):
    """A shape file that cannot be read or written; '<path>: <problem>'."""

class MissingFileError(IoError, FileNotFoundError):
    """No shape file at the path (errno ENOENT)."""

class MissingScenarioError(ScenarioError, FileNotFoundError):
    """No scenario file at the path (errno ENOENT)."""

class Region:
    @staticmethod
    def sphere(center: Vec3, radius: float) -> Region: ...
    @staticmethod
    def box(min: Vec3, max: Vec3) -> Region: ...
    @staticmethod
    def cylinder(start: Vec3, end: Vec3, radius: float) -> Region: ...
    @staticmethod
    def indices(indices: ArrayLike) -> Region:
        """(K,) integer point indices, file order."""
    @staticmethod
    def field(name: str, value: float) -> Region: ...
    @staticmethod
    def field_range(name: str, min: Optional[float] = None, max: Optional[float] = None) -> Region: ...

RegionLike = Union[Region, ArrayLike]

class Scenario:
    clusters: Optional[int]
    blend: Optional[str]
    def __init__(self) -> None: ...
    def fix(self, region: RegionLike) -> Scenario: ...
    def manipulate(self, region: RegionLike) -> Scenario: ...
    def joint(self, region: RegionLike) -> Scenario: ...
    def drag(self, from_: Vec3, to: Vec3, keep_orientation: bool = False) -> Scenario: ...
    def frame(
        self,
        translate: Vec3 = (0, 0, 0),
        axis: Vec3 = (0, 0, 1),
        degrees: float = 0.0,
        center: Optional[Vec3] = None,
    ) -> Scenario: ...
    @staticmethod
    def from_json(text: str, name: str = "scenario") -> Scenario: ...
    @staticmethod
    def read(path: str) -> Scenario: ...
    def to_json(self) -> str: ...

class Shape:
    def __init__(
        self,
        points: ArrayLike,
        normals: Optional[ArrayLike] = None,
        faces: Optional[Faces] = None,
        fields: Optional[Dict[str, ArrayLike]] = None,
    ) -> None:
        """points (N, 3); normals (N, 3); faces (M, 3) or index lists; fields {name: (N,) or (N, k)}."""
    points: npt.NDArray[np.float64]
    """(N, 3) float64 (a copy; assigning stores at the file's type)."""
    normals: Optional[npt.NDArray[np.float64]]
    """(N, 3) float64, or None."""
    faces: Union[npt.NDArray[np.int64], List[npt.NDArray[np.int64]]]
    """(M, 3) int64 for triangles, else a list of index arrays."""
    @property
    def fields(self) -> Dict[str, np.ndarray]:
        """Every other per-point field, (N,) or (N, k), at its stored dtype (copies)."""
    @property
    def field_names(self) -> List[str]: ...
    def field(self, name: str) -> np.ndarray: ...
    def set_field(self, name: str, values: ArrayLike) -> None: ...
    @property
    def path(self) -> str: ...
    @property
    def format(self) -> str: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def warnings(self) -> List[str]: ...
    @property
    def is_mesh(self) -> bool: ...
    def __len__(self) -> int: ...

def read(path: PathLike) -> Shape:
    """Reads PLY, PCD, OBJ, XYZ/TXT, PTS, LAS, OFF or STL (by content). Raises IoError."""

def write(path: PathLike, shape: Union[Shape, ArrayLike, Any], ascii: bool = False) -> None:
    """Writes by extension, atomically. Raises IoError."""

@overload
def deform(points: Shape, scenario: ScenarioLike, **options: Any) -> Tuple[Shape, Dict[str, Any]]: ...
@overload
def deform(
    points: ArrayLike, scenario: ScenarioLike, normals: None = None, faces: Optional[Faces] = None, **options: Any
) -> Tuple[npt.NDArray[np.float64], Dict[str, Any]]:
    """points (N, 3) -> deformed (N, 3) float64 and the report dict."""
@overload
def deform(
    points: ArrayLike, scenario: ScenarioLike, normals: ArrayLike, faces: Optional[Faces] = None, **options: Any
) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], Dict[str, Any]]:
    """points, normals (N, 3) -> deformed points, normals (N, 3) float64 and the report dict."""
@overload
def deform(points: Any, scenario: ScenarioLike, **options: Any) -> Tuple[Any, Dict[str, Any]]:
    """An Open3D PointCloud or TriangleMesh -> a new one of the same kind and the report."""

def field(
    points: Union[Shape, ArrayLike, Any],
    scenario: ScenarioLike,
    normals: Optional[ArrayLike] = None,
    faces: Optional[Faces] = None,
    **options: Any,
) -> npt.NDArray[np.float32]:
    """φ, (N,) float32 in the input's order (NaN where a point is not finite)."""

@overload
def deform_by_constraints(
    geometry: ArrayLike,
    constraint_ids: ArrayLike,
    constraint_pos: ArrayLike,
    fixed_ids: Optional[ArrayLike] = None,
    normals: None = None,
    faces: Optional[Faces] = None,
    return_report: Literal[False] = False,
    **options: Any,
) -> npt.NDArray[np.float64]:
    """Arrays (N, 3) -> the deformed points (N, 3) float64."""
@overload
def deform_by_constraints(
    geometry: ArrayLike,
    constraint_ids: ArrayLike,
    constraint_pos: ArrayLike,
    fixed_ids: Optional[ArrayLike] = None,
    normals: None = None,
    faces: Optional[Faces] = None,
    *,
    return_report: Literal[True],
    **options: Any,
) -> Tuple[npt.NDArray[np.float64], Dict[str, Any]]: ...
@overload
def deform_by_constraints(
    geometry: Any,
    constraint_ids: ArrayLike,
    constraint_pos: ArrayLike,
    fixed_ids: Optional[ArrayLike] = None,
    normals: Optional[ArrayLike] = None,
    faces: Optional[Faces] = None,
    return_report: bool = False,
    **options: Any,
) -> Any:
    """Open3D's deform_as_rigid_as_possible(constraint_vertex_indices, constraint_vertex_positions)
    as an Open3D user calls it: constraint_ids (K,) and their targets constraint_pos (K, 3); the
    ids whose target is their rest position, and fixed_ids, stay; the others move rigidly (the
    least-squares rigid fit of their targets, no scale). A Shape or an Open3D geometry comes
    back in kind; (points, normals) with normals; with return_report, the report last."""

class HandleDeformation:
    def __init__(
        self,
        points: Union[Shape, ArrayLike, Any],
        normals: Optional[ArrayLike] = None,
        faces: Optional[Faces] = None,
        **options: Any,
    ) -> None: ...
    def set_fixed(self, handles: Union[Sequence[ArrayLike], ArrayLike]) -> None: ...
    def set_manipulated(self, handle: ArrayLike) -> None: ...
    def set_joints(self, joints: Sequence[ArrayLike]) -> None: ...
    def set_scenario(self, scenario: ScenarioLike) -> None: ...
    def build(self) -> None: ...
    def drag(self, from_: Vec3, to: Vec3) -> Dict[str, Any]:
        """One frame; {iterations, converged, decreased, energy, solve_ms, interpolation_ms}."""
    def drag_to(self, from_: Vec3, to: Vec3) -> Dict[str, Any]: ...
    def set_handle_transform(self, transform: ArrayLike) -> Dict[str, Any]:
        """transform: (4, 4)."""
    def reset(self) -> None: ...
    @property
    def points(self) -> npt.NDArray[np.float32]:
        """(N, 3) float32, read-only view of the deformer's buffer (no copy, updated by every frame).

        Rows in the library's (Morton) order: row k is input point index[k]; world = points + origin.
        Fetch again after a set_scenario that changes clusters or full resolution (a rebuild)."""
    @property
    def index(self) -> npt.NDArray[np.int32]:
        """(N,) the input point of each row of points (and of normals and field)."""
    @property
    def origin(self) -> Tuple[float, float, float]:
        """world = points + origin (the centre of the shape's body, rounded)."""
    @property
    def normals(self) -> npt.NDArray[np.float32]:
        """(N, 3) float32 (a copy), rows as points."""
    @property
    def field(self) -> npt.NDArray[np.float32]:
        """(N,) float32, rows as points."""
    def deformed_shape(self) -> Shape:
        """The deformed Shape in the input's order: what ``hgdeform deform`` writes, to the bit."""
    def deformed_geometry(self) -> Any:
        """The deformed input in kind: a Shape, an (N, 3) float64 array ((points, normals) when
        normals were given), or an Open3D geometry of
        the kind given (legacy or tensor PointCloud or TriangleMesh, Vector3dVector)."""
    def world_points(self, out: Optional[npt.NDArray[np.float64]] = None) -> npt.NDArray[np.float64]:
        """(N, 3) float64: the deformed positions in the input's order, world coordinates (the view
        put in order, + origin); non-finite input rows as they were. Into `out` when given
        ((N, 3) float64, C-contiguous, writable). The GIL is released while it fills."""
    @property
    def energy(self) -> Dict[str, float]: ...
