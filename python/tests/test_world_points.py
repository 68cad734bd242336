"""HandleDeformation.world_points(): the deformed positions in the input's order and world
coordinates, computed in C++; checked against the view put back in order here with numpy."""

import threading
import time

import numpy as np
import pytest

import hgdeform

from conftest import same_bits, tube


def by_hand(hd, points):
    """The expected result, from the view alone: row k of `points` is input point index[k],
    world = float32 view + origin in float64; the rows the view lacks as the input has them."""
    out = np.array(points, dtype=np.float64)
    out[np.asarray(hd.index)] = np.asarray(hd.points, dtype=np.float64) + np.array(hd.origin)
    return out


def handles(points):
    hd = hgdeform.HandleDeformation(points)
    x = points[:, 0] - np.nanmin(points[:, 0])
    hd.set_fixed([np.flatnonzero(x < 1.0)])
    hd.set_manipulated(np.flatnonzero(x > 9.0))
    return hd


def test_world_points_is_the_view_in_input_order():
    points, _ = tube(n=2500, seed=61)
    points += (5e4, -3e3, 7.0)  # a frame far from the origin: origin matters
    hd = handles(points)
    rest = hd.world_points()
    assert rest.dtype == np.float64 and rest.shape == points.shape and rest.flags.c_contiguous
    assert same_bits(rest, by_hand(hd, points))
    assert np.abs(rest - points).max() < 1e-2  # float32 positions near a rounded origin
    hd.drag(points[np.argmax(points[:, 0])], points[np.argmax(points[:, 0])] + (0, 2.0, 0))
    moved = hd.world_points()
    assert same_bits(moved, by_hand(hd, points))
    assert np.abs(moved - rest).max() > 0.3
    # the same positions as the double-precision deformed shape, to float32's precision
    assert np.abs(moved - hd.deformed_shape().points).max() < 1e-7 * 5e4 * 10


def test_points_that_are_not_finite_come_back_as_the_input_has_them():
    points, _ = tube(n=1500, seed=62)
    points[[4, 900]] = np.nan
    points[77] = (1.5, np.nan, -2.0)  # a row with finite values besides the NaN
    points[78] = (np.inf, 0.0, 0.0)
    hd = handles(points)
    hd.drag((10, 1, 0), (10, 3, 0))
    world = hd.world_points()
    assert len(hd.index) == len(points) - 4
    assert np.array_equal(world[[4, 77, 78, 900]], points[[4, 77, 78, 900]], equal_nan=True)
    assert same_bits(world, by_hand(hd, points))


def test_world_points_fills_out():
    points, _ = tube(n=1200, seed=63)
    hd = handles(points)
    hd.drag((10, 1, 0), (10, 2, 1))
    out = np.full(points.shape, -1.0)
    got = hd.world_points(out=out)
    assert got is out
    assert same_bits(out, by_hand(hd, points))
    assert same_bits(hd.world_points(out), out)  # positional too


@pytest.mark.parametrize("bad, error, message", [
    (np.zeros((1200, 3), np.float32), TypeError, "float64"),
    ([[0.0, 0.0, 0.0]] * 1200, TypeError, "numpy array"),
    (np.zeros((1199, 3)), ValueError, r"shape \(1200, 3\)"),
    (np.zeros((1200, 4)), ValueError, r"shape \(1200, 3\)"),
    (np.zeros((3, 1200)).T, ValueError, "C-contiguous"),
    (np.zeros((1200, 6))[:, ::2], ValueError, "C-contiguous"),
])
def test_a_bad_out_is_refused(bad, error, message):
    points, _ = tube(n=1200, seed=63)
    hd = handles(points)
    with pytest.raises(error, match=message):
        hd.world_points(out=bad)


def test_a_read_only_out_is_refused():
    points, _ = tube(n=1200, seed=63)
    hd = handles(points)
    out = np.zeros(points.shape)
    out.setflags(write=False)
    with pytest.raises(ValueError, match="read-only"):
        hd.world_points(out=out)


def test_world_points_from_threads():
    points, _ = tube(n=3000, seed=64)
    hd = handles(points)
    hd.build()
    results, errors = [], []

    def fetch():
        try:
            results.append(hd.world_points())
        except Exception as e:  # noqa: BLE001 (reported below)
            errors.append(e)

    threads = [threading.Thread(target=fetch) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    for r in results:
        assert same_bits(r, by_hand(hd, points))


def test_world_points_never_shows_half_a_frame():
    # Readers fetch while another thread drags: every fill must be one whole state the dragging
    # thread also saw (a fill racing a frame would mix two states' rows).
    points, _ = tube(n=20000, seed=66)
    hd = handles(points)
    states = {hd.world_points().tobytes()}
    seen, errors, done = [], [], threading.Event()

    def drag():
        try:
            for k in range(25):
                before = len(seen)
                hd.drag((10, 1 + 0.04 * k, 0), (10, 1 + 0.04 * (k + 1), 0.02 * k))
                states.add(hd.world_points().tobytes())
                # On a loaded machine the readers can be starved for the whole drag: the next frame
                # waits (10 s at most) until a fill of this one or of the drag before it came in,
                # so the readers always race frames, not only the last one.
                deadline = time.monotonic() + 10
                while len(seen) <= before and time.monotonic() < deadline:
                    time.sleep(0.001)
        except Exception as e:  # noqa: BLE001 (reported below)
            errors.append(e)
        finally:
            done.set()

    def read():
        try:
            while not done.is_set():
                seen.append(hd.world_points().tobytes())
        except Exception as e:  # noqa: BLE001 (reported below)
            errors.append(e)

    threads = [threading.Thread(target=drag)] + [threading.Thread(target=read) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    assert len(states) > 10 and len(seen) > 10
    torn = sum(1 for r in seen if r not in states)
    assert torn == 0, f"{torn} of {len(seen)} fills mixed two frames"


def test_deformed_geometry_of_arrays_and_shapes():
    points, _ = tube(n=1000, seed=65)
    hd = handles(points)
    hd.drag((10, 1, 0), (10, 2, 0))
    out = hd.deformed_geometry()
    assert isinstance(out, np.ndarray) and same_bits(out, hd.deformed_shape().points)
    shape = hgdeform.Shape(points, fields={"label": np.arange(len(points), dtype=np.uint16)})
    hs = hgdeform.HandleDeformation(shape)
    hs.set_fixed([np.flatnonzero(points[:, 0] < 1.0)])
    hs.set_manipulated(np.flatnonzero(points[:, 0] > 9.0))
    hs.drag((10, 1, 0), (10, 2, 0))
    got = hs.deformed_geometry()
    assert isinstance(got, hgdeform.Shape)
    assert same_bits(got.points, out)
    assert np.array_equal(got.field("label"), np.arange(len(points)))
    # Arrays with normals: (points, normals), as deform() gives them; the normals turned.
    normals = np.tile([0.0, 1.0, 0.0], (len(points), 1))
    hn = hgdeform.HandleDeformation(points, normals)
    hn.set_fixed([np.flatnonzero(points[:, 0] < 1.0)])
    hn.set_manipulated(np.flatnonzero(points[:, 0] > 9.0))
    hn.drag((10, 1, 0), (10, 2, 0))
    got_points, got_normals = hn.deformed_geometry()
    assert same_bits(got_points, hn.deformed_shape().points)
    tip = points[:, 0] > 9.0
    assert np.abs(got_normals[tip] - normals[tip]).max() > 0.05  # the dragged end turned
    assert np.allclose(np.linalg.norm(got_normals, axis=1), 1.0)
