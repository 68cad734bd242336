"""Inputs refused or taken with a clear message: in-memory shapes without a finite point, handles
as plain lists of ints, option types."""

import numpy as np
import pytest

import hgdeform

from conftest import tube, tube_scenario


def test_handles_as_a_plain_list_of_ints():
    points, _ = tube(n=1500, seed=11)
    base = np.flatnonzero(points[:, 0] < 1.0)
    tip = np.flatnonzero(points[:, 0] > 9.0)
    a = hgdeform.HandleDeformation(points)
    a.set_fixed(base.tolist())  # one handle, as a 1-D array is
    a.set_manipulated(tip.tolist())
    b = hgdeform.HandleDeformation(points)
    b.set_fixed([base])
    b.set_manipulated(tip)
    a.drag([10.0, 1.0, 0.0], [10.0, 2.0, 0.0])
    b.drag([10.0, 1.0, 0.0], [10.0, 2.0, 0.0])
    assert np.array_equal(a.points, b.points)
    a.set_fixed([base.tolist(), [0, 1]])  # a list of lists: several handles
    a.build()


@pytest.mark.parametrize("bad", [np.full((10, 3), np.nan), np.array([[np.inf, 0.0, 0.0]] * 4)])
def test_points_without_a_finite_row_are_a_value_error_naming_the_argument(bad):
    s = tube_scenario()
    for call in (lambda: hgdeform.deform(bad, s), lambda: hgdeform.field(bad, s),
                 lambda: hgdeform.deform(hgdeform.Shape(bad), s),
                 lambda: hgdeform.field(hgdeform.Shape(bad), s),
                 lambda: hgdeform.HandleDeformation(bad)):
        with pytest.raises(ValueError, match="^points has no finite row") as e:
            call()
        assert not isinstance(e.value, hgdeform.IoError)


@pytest.mark.parametrize("option", ["mesh_ring", "full_field"])
def test_a_yes_no_option_of_another_type_is_refused_by_name(option):
    points, _ = tube(n=500)
    with pytest.raises(TypeError, match="option %s must be True or False, got str" % option):
        hgdeform.deform(points, tube_scenario(), **{option: "no"})
    hgdeform.deform(points, tube_scenario(), **{option: np.bool_(False)})
