"""HandleDeformation: the zero-copy view of the deformer's positions, frames, reset, scenarios."""

import numpy as np
import pytest

import hgdeform
from hgdeform import Scenario

from conftest import tube, tube_scenario


def data_address(a):
    return a.__array_interface__["data"][0]


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
    # the owner object is the HandleDeformation itself: the view keeps it alive
    base = view
    while isinstance(base, np.ndarray) and base.base is not None:
        base = base.base
    assert base is h
    # row k is input point k, at rest, in world coordinates (origin zero for this shape)
    assert h.origin == (0.0, 0.0, 0.0)
    assert np.array_equal(h.index, np.arange(len(points)))
    assert np.abs(view - points).max() < 1e-5


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
    moved = np.abs(view - rest).max(axis=1)
    assert moved[tip].mean() > 1.0
    assert moved[base].max() < 1e-4
    # what was shown is the deformer's: the deformed shape agrees to float precision
    shape = h.deformed_shape()
    assert np.abs(shape.points - view).max() < 1e-4


def test_handle_transform_reset_and_new_handles_keep_the_buffer(hd):
    h, points = hd
    view = h.points
    address = data_address(view)
    tip = points[:, 0] > 9.0
    t = np.eye(4)
    t[:3, 3] = [0.0, 2.0, 0.0]
    h.set_handle_transform(t)
    assert np.allclose(view[tip] - points[tip], [0, 2, 0], atol=1e-4)
    h.reset()
    assert np.abs(view - points).max() < 1e-5
    h.set_manipulated(np.flatnonzero(points[:, 0] > 8.0))  # new handles: the field again
    h.set_handle_transform(np.asfortranarray(t.astype(np.float32)))
    assert data_address(h.points) == address
    assert np.allclose(view[points[:, 0] > 8.0] - points[points[:, 0] > 8.0], [0, 2, 0],
                       atol=1e-4)
    phi = h.field
    assert phi.shape == (len(points),)
    assert phi[points[:, 0] > 8.0].min() == 1.0 and phi[points[:, 0] < 1.0].max() == 0.0


def test_the_view_outlives_every_other_reference():
    points, _ = tube(n=1500, seed=3)
    h = hgdeform.HandleDeformation(points)
    h.set_fixed(np.flatnonzero(points[:, 0] < 1.0))  # one handle as one index array
    h.set_manipulated(np.flatnonzero(points[:, 0] > 9.0))
    view = h.points
    del h
    import gc
    gc.collect()
    assert np.abs(view - points).max() < 1e-5  # still readable: the view holds the owner


def test_a_scenario_replays_its_moves_like_deform():
    points, normals = tube()
    scenario = tube_scenario()
    h = hgdeform.HandleDeformation(points, normals)
    h.set_scenario(scenario)
    out, _, _ = hgdeform.deform(points, scenario, normals=normals)
    # The same method on the points in the input's order (deform() builds in Morton order):
    # not the same bits (the sample, kNN ties and sums go in another order), the same shape.
    diagonal = np.linalg.norm(points.max(axis=0) - points.min(axis=0))
    assert np.abs(h.points - out).max() < 5e-3 * diagonal
    assert np.abs(h.deformed_shape().points - h.points).max() < 1e-4
    assert h.normals.shape == points.shape


def test_rows_follow_the_input_when_points_are_missing():
    points, _ = tube(n=1500, seed=4)
    points[[3, 700]] = np.nan
    h = hgdeform.HandleDeformation(points)
    h.set_fixed([np.flatnonzero(points[:, 0] < 1.0)])
    h.set_manipulated(np.flatnonzero(points[:, 0] > 9.0))
    assert len(h.points) == len(points) - 2
    assert np.array_equal(h.index, np.delete(np.arange(len(points)), [3, 700]))
    assert np.abs(h.points - points[h.index]).max() < 1e-5


def test_a_shape_far_from_the_origin_keeps_its_detail_in_a_local_frame():
    points, _ = tube(n=1500, seed=5)
    offset = np.array([5e6, 2e6, 100.0])
    h = hgdeform.HandleDeformation(points + offset)
    h.set_fixed([np.flatnonzero(points[:, 0] < 1.0)])
    h.set_manipulated(np.flatnonzero(points[:, 0] > 9.0))
    origin = np.array(h.origin)
    assert np.abs(origin - offset).max() < 20
    assert np.abs(h.points + origin - (points + offset)).max() < 1e-5


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
    diagonal = np.linalg.norm(points.max(axis=0) - points.min(axis=0))
    assert np.abs(h.points - out).max() < 5e-3 * diagonal
    assert report["reached"]
