"""Shapes keep what the command line keeps: every per-point field (read -> deform -> write ->
read back), points that do not move to the bit; the Shape's accessors."""

import numpy as np
import pytest

import hgdeform

from conftest import cli_deform, read_ply_vertices, same_bits, tube, tube_mesh, tube_scenario


def extra_fields(n, seed=21):
    rng = np.random.default_rng(seed)
    return {
        "intensity": rng.uniform(0, 1, n).astype(np.float32),
        "red": rng.integers(0, 256, n).astype(np.uint8),
        "green": rng.integers(0, 256, n).astype(np.uint8),
        "blue": rng.integers(0, 256, n).astype(np.uint8),
        "temperature": rng.normal(20, 5, n),  # float64
        "label": rng.integers(-5, 5, n).astype(np.int32),
    }


def test_read_deform_write_keeps_every_field(tmp_path):
    points, normals = tube()
    fields = extra_fields(len(points))
    scenario = tube_scenario()
    cli, _, src, s, cli_out = cli_deform(tmp_path, points, scenario, normals=normals,
                                         fields=fields)

    shape = hgdeform.read(src)
    assert shape.field_names == list(fields)
    for name, values in fields.items():
        assert same_bits(shape.field(name), values), name
        assert same_bits(shape.fields[name], values), name
    assert same_bits(shape.points, points)
    assert same_bits(shape.normals, normals)

    deformed, report = hgdeform.deform(shape, s)
    out = tmp_path / "py_out.ply"
    hgdeform.write(out, deformed)
    back = hgdeform.read(out)
    for name, values in fields.items():
        assert same_bits(back.field(name), values), name
    assert out.read_bytes() == cli_out.read_bytes()

    # the fixed end did not move: the same bits, not a recomputed value
    base = points[:, 0] < 1.0
    assert same_bits(back.points[base], points[base])
    assert same_bits(back.normals[base], normals[base])
    tip = points[:, 0] > 9.0
    assert np.abs(back.points[tip] - points[tip]).max() > 1.0
    assert report["points"] == len(points)


def test_a_shape_made_in_python_round_trips(tmp_path):
    points, faces = tube_mesh()
    fields = extra_fields(len(points))
    shape = hgdeform.Shape(points, faces=faces, fields=fields)
    assert len(shape) == len(points) and shape.is_mesh
    assert same_bits(shape.faces, faces)
    path = tmp_path / "made.ply"
    hgdeform.write(path, shape)
    back = hgdeform.read(path)
    assert same_bits(back.points, points)
    assert same_bits(back.faces, faces)
    for name, values in fields.items():
        assert same_bits(back.field(name), values), name
    # an independent reader sees the same records
    records = read_ply_vertices(path)
    assert same_bits(records["intensity"], fields["intensity"])

    deformed, _ = hgdeform.deform(back, tube_scenario())
    out = tmp_path / "deformed.ply"
    hgdeform.write(out, deformed)
    again = hgdeform.read(out)
    for name, values in fields.items():
        assert same_bits(again.field(name), values), name
    assert same_bits(again.faces, faces)


def test_ascii_and_pcd_keep_the_fields(tmp_path):
    points, _ = tube(n=500, seed=22)
    fields = {"intensity": np.linspace(0, 1, 500, dtype=np.float32),
              "label": np.arange(500, dtype=np.int32) % 7}
    shape = hgdeform.Shape(points, fields=fields)
    for name in ("a.pcd", "b.ply"):
        path = tmp_path / name
        hgdeform.write(path, shape, ascii=True)
        back = hgdeform.read(path)
        assert back.format == name[-3:]
        for field, values in fields.items():
            assert same_bits(back.field(field), values), (name, field)
        assert same_bits(back.points, points)


def test_setting_fields_and_positions(tmp_path):
    points, _ = tube(n=300, seed=23)
    shape = hgdeform.Shape(points.astype(np.float32))  # float64 storage: the values as given
    shape.set_field("weight", np.arange(300, dtype=np.uint16))
    assert shape.field("weight").dtype == np.uint16
    shape.set_field("weight", np.full(300, 7.9))  # converted to the field's own type
    assert same_bits(shape.field("weight"), np.full(300, 7, dtype=np.uint16))
    shape.set_field("uv", np.zeros((300, 2), dtype=np.float32))
    assert shape.field("uv").shape == (300, 2)
    shape.points = points + 1.0
    assert same_bits(shape.points, points + 1.0)
    assert shape.normals is None
    shape.normals = np.tile([0.0, 0.0, 1.0], (300, 1))
    assert same_bits(shape.normals, np.tile([0.0, 0.0, 1.0], (300, 1)))
    shape.faces = [[0, 1, 2, 3], [3, 4, 5]]
    faces = shape.faces
    assert isinstance(faces, list) and [list(f) for f in faces] == [[0, 1, 2, 3], [3, 4, 5]]
    with pytest.raises(KeyError, match="no field 'nope'"):
        shape.field("nope")
    with pytest.raises(ValueError, match=r"field w must have one row per point \(N = 300\), "
                                         r"got shape \(3,\)"):
        shape.set_field("w", [1, 2, 3])
    with pytest.raises(ValueError, match=r"^points must be an N×3 array with N = 300"):
        shape.points = points[:10]
    shape.faces = None  # (PCD has no place for them)
    path = tmp_path / "s.pcd"  # PCD holds a field of several values (PLY splits it: uv_0, uv_1)
    hgdeform.write(path, shape)
    back = hgdeform.read(path)
    assert same_bits(back.field("weight"), shape.field("weight"))
    assert same_bits(back.field("uv"), shape.field("uv"))


def test_writing_to_a_format_that_cannot_hold_the_fields_warns(tmp_path):
    points, faces = tube_mesh(nu=10, nv=6)
    shape = hgdeform.Shape(points, faces=faces, fields={"label": np.arange(60, dtype=np.int32)})
    with pytest.warns(UserWarning, match="label"):
        hgdeform.write(tmp_path / "m.stl", shape)
    hgdeform.write(tmp_path / "arrays.ply", points)  # arrays are written as a cloud
    assert same_bits(hgdeform.read(tmp_path / "arrays.ply").points, points)
