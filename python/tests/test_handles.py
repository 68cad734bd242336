"""HandleDeformation: the zero-copy view of the deformer's positions, frames, reset, scenarios."""

import pathlib

import numpy as np
import pytest

import hgdeform
from hgdeform import Scenario

from conftest import cli_deform, run_tool, same_bits, tube, tube_scenario, xyz


def data_address(a):
    return a.__array_interface__["data"][0]


def world(h, view=None, n=None):
    """The view's rows in input order, world coordinates (NaN for rows the input lacks)."""
    view = h.points if view is None else view
    n = len(view) if n is None else n
    out = np.full((n, 3), np.nan)
    out[h.index] = view.astype(np.float64) + h.origin
    return out


@pytest.fixture
def hd():
    points, _ = tube()
    h = hgdeform.HandleDeformation(points)
    h.set_fixed([np.flatnonzero(points[:, 0] < 1.0)])
    h.set_manipulated(np.flatnonzero(points[:, 0] > 9.0))
    return h, points


def test_points_is_a_read_only_view_of_the_deformers_buffer(hd):
    h, points = hd
    view = h.points
    assert view.shape == points.shape and view.dtype == np.float32
    assert view.flags.writeable is False
    with pytest.raises(ValueError):
        view[0, 0] = 1.0
    assert not view.flags.owndata
    again = h.points
    assert np.shares_memory(view, again)
    assert data_address(view) == data_address(again)
    # rows in the library's (Morton) order, a local frame: row k is input point index[k], and
    # world = points + origin (the centre of the shape's body, rounded)
    assert sorted(h.index) == list(range(len(points)))
    assert not np.array_equal(h.index, np.arange(len(points)))
    assert h.origin == (5.0, 0.0, 0.0)
    assert np.abs(view + h.origin - points[h.index]).max() < 1e-5


def test_a_drag_changes_the_view_without_fetching_it_again(hd):
    h, points = hd
    view = h.points
    address = data_address(view)
    rest = view.copy()
    tip = points[:, 0] > 9.0
    base = points[:, 0] < 1.0
    target = np.array([10.0, 1.5, 0.0])
    for k in range(1, 6):  # five frames of one drag, as a mouse would give them
        stats = h.drag([10.0, 1.0, 0.0] if k == 1 else prev, target * [1, 1, 1] + [0, 0.3 * k, 0])
        prev = target + [0, 0.3 * k, 0]
        assert stats["iterations"] >= 1
    assert data_address(view) == address  # the same memory, written in place
    moved = np.full(len(points), np.nan)
    moved[h.index] = np.abs(view - rest).max(axis=1)
    assert moved[tip].mean() > 1.0
    assert moved[base].max() < 1e-4
    # what was shown is the deformer's: the deformed shape agrees to float precision
    shape = h.deformed_shape()
    assert np.abs(shape.points - world(h, view)).max() < 1e-4


def test_handle_transform_reset_and_new_handles_keep_the_buffer(hd):
    h, points = hd
    view = h.points
    address = data_address(view)
    tip = points[:, 0] > 9.0
    t = np.eye(4)
    t[:3, 3] = [0.0, 2.0, 0.0]
    h.set_handle_transform(t)
    assert np.allclose(world(h, view)[tip] - points[tip], [0, 2, 0], atol=1e-4)
    h.reset()
    assert np.abs(world(h, view) - points).max() < 1e-5
    h.set_manipulated(np.flatnonzero(points[:, 0] > 8.0))  # new handles: the field again
    h.set_handle_transform(np.asfortranarray(t.astype(np.float32)))
    assert data_address(h.points) == address
    assert np.allclose(world(h, view)[points[:, 0] > 8.0] - points[points[:, 0] > 8.0], [0, 2, 0],
                       atol=1e-4)
    phi = np.empty(len(points), np.float32)
    phi[h.index] = h.field
    assert h.field.shape == (len(points),)
    assert phi[points[:, 0] > 8.0].min() == 1.0 and phi[points[:, 0] < 1.0].max() == 0.0


def test_reset_after_a_handle_change_returns_the_view_to_rest(hd):
    h, points = hd
    view = h.points
    rest = view.copy()
    h.drag([10.0, 1.0, 0.0], [10.0, 3.0, 0.0])
    assert np.abs(view - rest).max() > 0.1
    h.set_manipulated(np.flatnonzero(points[:, 0] > 8.5))  # not built yet
    h.reset()
    assert np.array_equal(view, rest)


def test_the_view_outlives_every_other_reference():
    points, _ = tube(n=1500, seed=3)
    h = hgdeform.HandleDeformation(points)
    h.set_fixed(np.flatnonzero(points[:, 0] < 1.0))  # one handle as one index array
    h.set_manipulated(np.flatnonzero(points[:, 0] > 9.0))
    view = h.points
    index, origin = h.index.copy(), h.origin
    del h
    import gc
    gc.collect()
    # still readable: the view holds the deformer
    assert np.abs(view + origin - points[index]).max() < 1e-5


def test_a_scenario_replays_its_moves_like_deform():
    points, normals = tube()
    scenario = tube_scenario()
    h = hgdeform.HandleDeformation(points, normals)
    h.set_scenario(scenario)
    out, out_normals, _ = hgdeform.deform(points, scenario, normals=normals)
    # The same path as deform() (extractGeometry's geometry, the same deformer): the same bits.
    shape = h.deformed_shape()
    assert np.array_equal(shape.points, out)
    assert np.array_equal(shape.normals, out_normals)
    # and the view is those positions in float32, in its rows and frame
    diagonal = np.linalg.norm(points.max(axis=0) - points.min(axis=0))
    assert np.abs(world(h) - out).max() < 1e-6 * diagonal
    assert h.normals.shape == points.shape


def test_handle_deformation_follows_deform_whatever_the_input_order():
    # The library sorts the points (Morton order) before it samples them: a shuffled input
    # gives the same shape up to the order of equal sort keys (as deform() itself), and
    # HandleDeformation takes deform()'s path on it, to the bit.
    points, _ = tube(n=3000, seed=9)
    scenario = tube_scenario()
    perm = np.random.default_rng(0).permutation(len(points))
    a = hgdeform.HandleDeformation(points)
    a.set_scenario(scenario)
    b = hgdeform.HandleDeformation(points[perm])
    b.set_scenario(scenario)
    assert np.array_equal(b.deformed_shape().points, hgdeform.deform(points[perm], scenario)[0])
    diagonal = np.linalg.norm(points.max(axis=0) - points.min(axis=0))
    assert np.abs(a.deformed_shape().points[perm] - b.deformed_shape().points).max() < 1e-9 * diagonal
    assert np.abs(world(a)[perm] - world(b)).max() < 1e-6 * diagonal


def test_a_second_scenario_with_other_clusters_rebuilds_the_deformer():
    points, _ = tube(n=3000, seed=10)
    s8 = dict(tube_scenario(), clusters=8)
    s4 = dict(tube_scenario(), clusters=4)
    h = hgdeform.HandleDeformation(points)
    h.set_scenario(s8)
    old = h.points.copy()
    h.set_scenario(s4)
    fresh = hgdeform.HandleDeformation(points)
    fresh.set_scenario(s4)
    assert np.array_equal(h.points, fresh.points)  # fetched again after the rebuild
    assert not np.array_equal(h.points, old)
    assert np.array_equal(h.deformed_shape().points, fresh.deformed_shape().points)
    assert np.array_equal(h.deformed_shape().points, hgdeform.deform(points, s4)[0])
    # the blend alone keeps the deformer (and the buffer)
    view = h.points
    h.set_scenario(dict(s4, blend="linear"))
    assert data_address(h.points) == data_address(view)
    linear = hgdeform.HandleDeformation(points)
    linear.set_scenario(dict(s4, blend="linear"))
    assert np.array_equal(view, linear.points)


def test_rows_follow_the_input_when_points_are_missing():
    points, _ = tube(n=1500, seed=4)
    points[[3, 700]] = np.nan
    h = hgdeform.HandleDeformation(points)
    h.set_fixed([np.flatnonzero(points[:, 0] < 1.0)])
    h.set_manipulated(np.flatnonzero(points[:, 0] > 9.0))
    assert len(h.points) == len(points) - 2
    assert np.array_equal(np.sort(h.index), np.delete(np.arange(len(points)), [3, 700]))
    assert np.abs(h.points + h.origin - points[h.index]).max() < 1e-5


def test_a_shape_far_from_the_origin_keeps_its_detail_in_a_local_frame():
    points, _ = tube(n=1500, seed=5)
    offset = np.array([5e6, 2e6, 100.0])
    h = hgdeform.HandleDeformation(points + offset)
    h.set_fixed([np.flatnonzero(points[:, 0] < 1.0)])
    h.set_manipulated(np.flatnonzero(points[:, 0] > 9.0))
    origin = np.array(h.origin)
    assert np.abs(origin - offset).max() < 20
    assert np.abs(h.points + origin - (points + offset)[h.index]).max() < 1e-5


def test_open3d_free_constructor_takes_a_shape():
    points, _ = tube(n=1200, seed=6)
    h = hgdeform.HandleDeformation(hgdeform.Shape(points))
    h.set_scenario(Scenario().fix(np.flatnonzero(points[:, 0] < 1.0))
                   .manipulate(np.flatnonzero(points[:, 0] > 9.0)))
    assert h.points.shape == points.shape


def test_joints_and_a_whole_drag():
    points, _ = tube(n=3000, seed=8)
    h = hgdeform.HandleDeformation(points, blend="rotation")
    base = np.flatnonzero(points[:, 0] < 1.0)
    tip = np.flatnonzero(points[:, 0] > 9.0)
    joint = np.flatnonzero(np.abs(points[:, 0] - 5.0) < 0.4)
    h.set_fixed([base])
    h.set_manipulated(tip)
    h.set_joints([joint])
    result = h.drag_to([10.0, 1.0, 0.0], [8.0, 4.0, 0.0])
    assert result["reached"] and result["frames"] >= 1
    scenario = (Scenario().fix(base).manipulate(tip).joint(joint)
                .drag([10.0, 1.0, 0.0], [8.0, 4.0, 0.0]))
    out, report = hgdeform.deform(points, scenario)
    assert np.array_equal(h.deformed_shape().points, out)  # the same path, the same bits
    assert report["reached"]


DATASETS = pathlib.Path(__file__).resolve().parents[2] / "datasets"


def test_deformed_shape_is_what_the_command_line_writes_for_the_bunny(tmp_path):
    mesh, scenario = DATASETS / "bunny_1839.ply", DATASETS / "bunny_ears.json"
    out = tmp_path / "cli.ply"
    run_tool("deform", mesh, "-s", scenario, "-o", out, "-q")
    h = hgdeform.HandleDeformation(hgdeform.read(mesh))
    h.set_scenario(scenario)
    mine = tmp_path / "hd.ply"
    hgdeform.write(mine, h.deformed_shape())
    assert same_bits(h.deformed_shape().points, hgdeform.read(out).points)
    assert mine.read_bytes() == out.read_bytes()


def test_deformed_shape_is_what_the_command_line_writes_for_a_generated_cloud(tmp_path):
    points, normals = tube(n=4000, seed=21)
    points[17] = np.nan
    scenario = tube_scenario()
    records, _, src, s, _ = cli_deform(tmp_path, points, scenario, normals=normals)
    h = hgdeform.HandleDeformation(hgdeform.read(src))
    h.set_scenario(s)
    shape = h.deformed_shape()
    assert np.array_equal(shape.points, xyz(records), equal_nan=True)
    arrays = hgdeform.HandleDeformation(points, normals)
    arrays.set_scenario(scenario)
    assert np.array_equal(arrays.deformed_shape().points, xyz(records), equal_nan=True)
