"""Errors: the library's exceptions as ScenarioError (a ValueError) and IoError (an OSError)
with its messages; bad shapes, dtypes and options refused with a message naming the argument."""

import json
import re

import numpy as np
import pytest

import hgdeform
from hgdeform import Region, Scenario

from conftest import tube, tube_scenario, write_ply


@pytest.fixture(scope="module")
def points():
    return tube(n=800, seed=7)[0]


def test_exception_types():
    assert issubclass(hgdeform.ScenarioError, ValueError)
    assert issubclass(hgdeform.IoError, OSError)
    assert hgdeform.ScenarioError.__module__ == "hgdeform"
    assert hgdeform.IoError.__module__ == "hgdeform"


def test_a_region_that_selects_nothing(points):
    s = tube_scenario()
    s["fixed"] = [{"sphere": {"center": [100, 100, 100], "radius": 1}}]
    with pytest.raises(hgdeform.ScenarioError,
                       match=r"^scenario: /fixed/0: selects no point of the shape"):
        hgdeform.deform(points, s)
    with pytest.raises(ValueError):  # caught as what it is
        hgdeform.field(points, s)


def test_a_scenario_that_does_not_parse(points, tmp_path):
    s = tube_scenario()
    s["fixd"] = []
    with pytest.raises(hgdeform.ScenarioError, match=r"^scenario: /fixd: "):
        hgdeform.deform(points, s)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(s))
    with pytest.raises(hgdeform.ScenarioError, match="^" + re.escape(str(path)) + ": /fixd: "):
        hgdeform.deform(points, path)
    with pytest.raises(hgdeform.ScenarioError, match=r"/fixed/0/sphere/radius"):
        Scenario.from_json('{"fixed": [{"sphere": {"center": [0,0,0], "radius": -1}}],'
                           ' "manipulated": {"indices": [1]}}')
    with pytest.raises(hgdeform.ScenarioError, match="missing.json"):
        hgdeform.deform(points, str(tmp_path / "missing.json"))


def test_an_index_out_of_range(points):
    s = Scenario().fix(np.arange(10)).manipulate([5000])
    with pytest.raises(hgdeform.ScenarioError,
                       match=r"/manipulated: index 5000 is out of range \(the shape has 800 points\)"):
        hgdeform.deform(points, s)


def test_io_errors(tmp_path, points):
    missing = tmp_path / "missing.ply"
    with pytest.raises(hgdeform.IoError, match="^" + re.escape(str(missing)) + ": ") as e:
        hgdeform.read(missing)
    assert isinstance(e.value, OSError)
    garbage = tmp_path / "garbage.ply"
    garbage.write_bytes(b"\x00\x01 not a shape")
    with pytest.raises(OSError, match=re.escape(str(garbage))):
        hgdeform.read(garbage)
    src = tmp_path / "in.ply"
    write_ply(src, points)
    shape = hgdeform.read(src)
    with pytest.raises(hgdeform.IoError, match="refusing|input|overwrite"):
        hgdeform.write(src, shape)  # never over its input
    with pytest.raises(hgdeform.IoError, match=r"\.foo"):
        hgdeform.write(tmp_path / "out.foo", shape)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["garbage.ply", "in.ply"]


def test_handle_deformation_without_handles(points):
    h = hgdeform.HandleDeformation(points)
    with pytest.raises(hgdeform.ScenarioError,
                       match=r"^HandleDeformation: no fixed handle \(set_fixed or set_scenario\)$"):
        h.points
    h.set_fixed([np.arange(10)])
    with pytest.raises(hgdeform.ScenarioError, match="no manipulated handle"):
        h.drag([0, 0, 0], [1, 1, 1])


@pytest.mark.parametrize("bad, message", [
    (np.zeros((5, 2)), r"^points must be an N×3 array, got shape \(5, 2\)$"),
    (np.zeros(9), r"^points must be an N×3 array, got shape \(9,\)$"),
    (np.zeros((2, 3, 3)), r"^points must be an N×3 array, got shape \(2, 3, 3\)$"),
    (np.zeros((0, 3)), r"^points must be an N×3 array with N ≥ 1, got shape \(0, 3\)$"),
])
def test_bad_point_shapes(bad, message):
    with pytest.raises(ValueError, match=message):
        hgdeform.deform(bad, tube_scenario())
    with pytest.raises(ValueError, match=message):
        hgdeform.field(bad, tube_scenario())
    with pytest.raises(ValueError, match=message):
        hgdeform.HandleDeformation(bad)


def test_bad_dtypes_and_types(points):
    with pytest.raises(TypeError, match=r"^points must hold real numbers, got dtype <U1$"):
        hgdeform.deform(np.full((4, 3), "a"), tube_scenario())
    with pytest.raises(TypeError, match=r"^points must hold real numbers, got dtype complex128$"):
        hgdeform.deform(np.zeros((4, 3), dtype=complex), tube_scenario())
    with pytest.raises(TypeError, match="scenario must be a Scenario, a dict, JSON text or a path"):
        hgdeform.deform(points, 42)
    with pytest.raises(TypeError, match="faces must hold integer vertex indices, got dtype float64"):
        hgdeform.deform(points, tube_scenario(), faces=np.zeros((3, 3)))
    with pytest.raises(TypeError, match="integer point indices"):
        Region.indices(np.array([0.5, 1.5]))


def test_bad_companions(points):
    n = len(points)
    with pytest.raises(ValueError, match=r"^normals must be an N×3 array with N = %d \(one per point\), "
                                         r"got shape \(%d, 3\)$" % (n, n - 1)):
        hgdeform.deform(points, tube_scenario(), normals=np.zeros((n - 1, 3)))
    with pytest.raises(ValueError, match=r"^faces: vertex index %d of face 1 is out of range "
                                         r"\(the shape has %d points\)$" % (n, n)):
        hgdeform.deform(points, tube_scenario(), faces=[[0, 1, 2], [1, 2, n]])
    with pytest.raises(ValueError, match=r"^faces must be an M×3 \(or M×k\) array"):
        hgdeform.deform(points, tube_scenario(), faces=np.zeros((3, 2), dtype=int))
    h = hgdeform.HandleDeformation(points)
    with pytest.raises(ValueError, match=r"^transform must be an N×4 array with N = 4 "
                                         r"\(a 4×4 matrix\), got shape \(3, 3\)$"):
        h.set_handle_transform(np.eye(3))
    with pytest.raises(ValueError, match=r"^from_ must be 3 numbers, got shape \(2,\)$"):
        h.drag([0, 0], [1, 1, 1])
    with pytest.raises(ValueError, match=r"^center must be 3 numbers"):
        Region.sphere([0, 0], 1.0)


def test_bad_options(points):
    with pytest.raises(TypeError, match=r"^unexpected option 'clustres' \(the options: clusters, "):
        hgdeform.deform(points, tube_scenario(), clustres=4)
    with pytest.raises(ValueError, match=r"^option blend must be 'rotation' or 'linear', got 'fast'$"):
        hgdeform.deform(points, tube_scenario(), blend="fast")
    with pytest.raises(ValueError, match=r"^option clusters must be 1 to 1000, got 0$"):
        hgdeform.deform(points, tube_scenario(), clusters=0)
    with pytest.raises(TypeError, match=r"^option k must be an integer, got float$"):
        hgdeform.deform(points, tube_scenario(), k=10.0)
    with pytest.raises(TypeError, match="normals and faces are given with points arrays"):
        hgdeform.deform(hgdeform.Shape(points), tube_scenario(), normals=points)


def test_a_path_with_a_nul_byte_is_refused_as_open_refuses_it(tmp_path, points):
    # The C library would stop at the NUL: 'victim\0.ply' is the file 'victim'.
    victim = tmp_path / "victim"
    victim.write_bytes(b"precious")
    for call in (lambda: hgdeform.write(str(victim) + "\0.ply", points),
                 lambda: hgdeform.read(str(victim) + "\0.ply"),
                 lambda: hgdeform.deform(points, str(victim) + "\0.json")):
        with pytest.raises(ValueError, match="embedded null byte"):
            call()
    with pytest.raises(ValueError):
        open(str(victim) + "\0.ply", "rb")  # what Python's own open() does
    assert victim.read_bytes() == b"precious"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["victim"]


def test_handle_transform_must_be_rigid(points):
    h = hgdeform.HandleDeformation(points)
    h.set_fixed([np.flatnonzero(points[:, 0] < 1.0)])
    h.set_manipulated(np.flatnonzero(points[:, 0] > 9.0))
    before = h.points.copy()
    t = np.eye(4)
    t[3, :3] = [0.0, 2.0, 0.0]  # a translation in the bottom row: the matrix transposed
    with pytest.raises(ValueError, match="bottom row must be 0 0 0 1"):
        h.set_handle_transform(t)
    for bad, why in ((np.diag([2.0, 2.0, 2.0, 1.0]), "scales or shears"),
                     (np.diag([1.0, 1.0, 0.0, 1.0]), "reflects or is singular"),
                     (np.diag([1.0, 1.0, -1.0, 1.0]), "reflects or is singular"),
                     (np.full((4, 4), np.nan), "not finite")):
        with pytest.raises(ValueError, match=why):
            h.set_handle_transform(bad)
    assert np.array_equal(h.points, before)  # nothing was applied
    c, s = np.cos(0.3), np.sin(0.3)
    rigid = np.array([[c, -s, 0, 0.5], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    h.set_handle_transform(rigid)  # a rotation and a translation is taken
    assert not np.array_equal(h.points, before)


def test_a_missing_file_is_a_file_not_found_error(tmp_path, points):
    import inspect

    missing = tmp_path / "nothere.ply"
    with pytest.raises(FileNotFoundError) as e:
        hgdeform.read(missing)
    assert isinstance(e.value, hgdeform.IoError) and e.value.filename == str(missing)
    assert "nothere.ply" in str(e.value)
    for call in (hgdeform.deform, hgdeform.field):
        with pytest.raises(FileNotFoundError) as e:
            call(points, tmp_path / "none.json")
        assert isinstance(e.value, hgdeform.ScenarioError)
        with pytest.raises(FileNotFoundError):
            call(points, str(tmp_path / "none.json"))
    assert list(inspect.signature(hgdeform.read).parameters) == ["path"]
