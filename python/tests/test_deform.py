"""deform() and field() against the command-line tool, on the same input, to the last bit; the
ways a scenario is given; dtypes and memory orders."""

import json
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest

import hgdeform
from hgdeform import Region, Scenario

from conftest import (cli_deform, read_ply_vertices, run_tool, same_bits, tube, tube_mesh,
                      tube_scenario, write_ply, xyz)


def test_version_is_the_project_version():
    assert hgdeform.__version__ == os.environ.get("HGD_VERSION", hgdeform.__version__)
    line = run_tool("--version").strip()
    assert line == "hgdeform " + hgdeform.__version__


def test_points_equal_the_command_line_to_the_bit(tmp_path, tube_points):
    points, _ = tube_points
    scenario = tube_scenario()
    cli, cli_report, *_ = cli_deform(tmp_path, points, scenario)
    out, report = hgdeform.deform(points, scenario)
    assert out.shape == points.shape and out.dtype == np.float64
    assert same_bits(out, xyz(cli))
    assert np.abs(out - points).max() > 1.0  # it did move
    assert report["clusters"] == cli_report["clusters"]
    assert report["iterations"] == cli_report["iterations"]


def test_normals_equal_the_command_line_to_the_bit(tmp_path, tube_points):
    points, normals = tube_points
    scenario = tube_scenario()
    cli, *_ = cli_deform(tmp_path, points, scenario, normals=normals)
    out, out_normals, report = hgdeform.deform(points, scenario, normals=normals)
    assert same_bits(out, xyz(cli))
    cli_normals = np.stack([cli["nx"], cli["ny"], cli["nz"]], axis=1)
    assert same_bits(out_normals, cli_normals)
    assert not np.allclose(out_normals, normals)  # turned with the shape
    assert isinstance(report, dict)


def test_mesh_equals_the_command_line_to_the_bit(tmp_path):
    points, faces = tube_mesh()
    scenario = tube_scenario()
    cli, *_ = cli_deform(tmp_path, points, scenario, faces=faces)
    out, _ = hgdeform.deform(points, scenario, faces=faces)
    assert same_bits(out, xyz(cli))
    # polygons as lists take the same path
    out_lists, _ = hgdeform.deform(points, scenario, faces=[list(f) for f in faces])
    assert same_bits(out_lists, out)


def test_shape_round_trip_writes_the_command_lines_file(tmp_path, tube_points):
    points, normals = tube_points
    scenario = tube_scenario()
    _, _, src, s, cli_out = cli_deform(tmp_path, points, scenario, normals=normals)
    shape = hgdeform.read(src)
    deformed, _ = hgdeform.deform(shape, s)
    assert isinstance(deformed, hgdeform.Shape)
    out = tmp_path / "py_out.ply"
    hgdeform.write(out, deformed)
    assert out.read_bytes() == cli_out.read_bytes()


def test_report_has_the_command_lines_keys(tmp_path, tube_points):
    points, _ = tube_points
    scenario = tube_scenario()
    _, cli_report, *_ = cli_deform(tmp_path, points, scenario)
    _, report = hgdeform.deform(points, scenario)

    def keys(d, prefix=""):
        out = set()
        for k, v in d.items():
            out.add(prefix + k)
            if isinstance(v, dict):
                out |= keys(v, prefix + k + ".")
        return out

    # All but the command's own peak memory and malloc: a call into the library shares its process.
    assert "peak_rss_mb" in cli_report and cli_report["peak_rss_mb"] > 0
    assert keys(report) == keys(cli_report) - {"peak_rss_mb", "huge_page_malloc"}
    for key in ("points", "clusters", "iterations", "frames", "handle_error", "energy",
                "warnings", "pieces", "surface", "version"):
        assert report[key] == cli_report[key], key


def test_field_equals_the_command_line_to_the_bit(tmp_path, tube_points):
    points, _ = tube_points
    scenario = tube_scenario()
    src = tmp_path / "in.ply"
    write_ply(src, points)
    s = tmp_path / "s.json"
    s.write_text(json.dumps(scenario))
    out = tmp_path / "field.ply"
    run_tool("field", src, "-s", s, "-o", out, "-q")
    phi = hgdeform.field(points, scenario)
    assert phi.shape == (len(points),) and phi.dtype == np.float32
    assert same_bits(phi, read_ply_vertices(out)["harmonic"])
    assert phi.min() == 0.0 and phi.max() == 1.0
    assert same_bits(hgdeform.field(hgdeform.read(src), s), phi)


def test_every_form_of_a_scenario_gives_the_same_result(tmp_path, tube_points):
    points, _ = tube_points
    d = tube_scenario()
    path = tmp_path / "s.json"
    path.write_text(json.dumps(d))
    built = (Scenario()
             .fix(Region.box([-1, -2, -2], [1, 2, 2]))
             .manipulate(Region.box((9, -2, -2), (11, 2, 2)))
             .drag([10, 1, 0], [10, 3, 0]))
    built.clusters = 8
    reference, _ = hgdeform.deform(points, d)
    for form in (json.dumps(d), str(path), path, built, Scenario.from_json(json.dumps(d)),
                 Scenario.read(str(path))):
        out, _ = hgdeform.deform(points, form)
        assert same_bits(out, reference), repr(form)


def test_the_builder_chains_and_takes_index_arrays(tube_points):
    points, _ = tube_points
    s = Scenario()
    assert s.fix(Region.sphere((0, 0, 0), 1.5)) is s
    base = np.flatnonzero(points[:, 0] < 1.0)
    tip = np.flatnonzero(points[:, 0] > 9.0)
    by_index = Scenario().fix(base).manipulate(tip).frame(translate=(0, 2, 0))
    by_region = (Scenario().fix(Region.indices(base)).manipulate(Region.indices(tip))
                 .frame(translate=(0, 2, 0)))
    a, _ = hgdeform.deform(points, by_index)
    b, _ = hgdeform.deform(points, by_region)
    assert same_bits(a, b)
    assert np.allclose(a[base], points[base])
    assert np.allclose(a[tip] - points[tip], [0, 2, 0], atol=1e-4)
    as_dict = {"fixed": [{"indices": base}], "manipulated": {"indices": tip},
               "move": {"frame": {"translate": np.array([0.0, 2.0, 0.0])}}}
    c, _ = hgdeform.deform(points, as_dict)  # numpy values inside a dict
    assert same_bits(c, a)
    assert "hgdeform-scenario/1" in by_index.to_json()
    assert repr(Region.sphere((0, 0, 0), 1.5)).startswith("Region.sphere(")


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("order", ["C", "F"])
def test_any_float_dtype_and_order_gives_the_c_order_float64_result(tube_points, dtype, order):
    points, normals = tube_points
    points = points.astype(dtype).astype(np.float64)  # the values float32 can hold
    scenario = tube_scenario()
    reference, ref_normals, _ = hgdeform.deform(np.ascontiguousarray(points), scenario,
                                                normals=normals)
    given = np.asarray(points, dtype=dtype, order=order)
    out, out_normals, _ = hgdeform.deform(given, scenario, normals=np.asfortranarray(normals))
    assert same_bits(out, reference)
    assert same_bits(out_normals, ref_normals)


def test_a_strided_view_and_a_list_are_taken(tube_points):
    points, _ = tube_points
    scenario = tube_scenario()
    reference, _ = hgdeform.deform(points, scenario)
    wide = np.zeros((len(points), 6))
    wide[:, ::2] = points
    out, _ = hgdeform.deform(wide[:, ::2], scenario)
    assert same_bits(out, reference)
    out, _ = hgdeform.deform(points.tolist(), scenario)
    assert same_bits(out, reference)


def test_options_override_the_scenario(tube_points):
    points, _ = tube_points
    _, report = hgdeform.deform(points, tube_scenario(), clusters=4, blend="linear",
                                solver="exact", k=12)
    _, default = hgdeform.deform(points, tube_scenario())
    assert report["isovalues"] == 4 and default["isovalues"] == 8


def test_reweight_is_the_solvers_option_and_off_by_default(tube_points):
    points, _ = tube_points
    default, _ = hgdeform.deform(points, tube_scenario())
    zero, _ = hgdeform.deform(points, tube_scenario(), reweight=0)
    assert same_bits(zero, default)
    rounds, _ = hgdeform.deform(points, tube_scenario(), reweight=8)
    assert not same_bits(rounds, default)
    with pytest.raises(ValueError, match=r"^option reweight must be 0 to 100, got 101$"):
        hgdeform.deform(points, tube_scenario(), reweight=101)


def test_the_package_has_its_stub_and_imports_from_elsewhere(tmp_path):
    package = pathlib.Path(hgdeform.__file__).parent
    assert (package / "__init__.pyi").is_file()
    assert (package / "py.typed").is_file()
    r = subprocess.run([sys.executable, "-c", "import hgdeform; print(hgdeform.__version__)"],
                       capture_output=True, text=True, cwd=tmp_path,
                       env=dict(os.environ, PYTHONPATH=str(package.parent)))
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == hgdeform.__version__
