"""Open3D geometries where arrays are taken, returned in kind; and no import of Open3D when it
is not what was given (or not installed)."""

import subprocess
import sys

import numpy as np
import pytest

import hgdeform

from conftest import same_bits, tube, tube_mesh, tube_scenario


def test_the_package_does_not_import_open3d():
    code = (
        "import sys, numpy as np\n"
        "sys.modules['open3d'] = None  # as if it were not installed: importing it fails\n"
        "import hgdeform\n"
        "sys.path.insert(0, %r)\n"
        "from conftest import tube, tube_scenario\n"
        "p, n = tube(n=600)\n"
        "out, report = hgdeform.deform(p, tube_scenario())\n"
        "hgdeform.field(p, tube_scenario())\n"
        "h = hgdeform.HandleDeformation(p)\n"
        "print(sys.modules['open3d'] is None)\n" % str(__import__("pathlib").Path(__file__).parent))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "True"


o3d = pytest.importorskip(
    "open3d", reason="Open3D is not installed (Debian: python3-open3d); its interop is not tested")


def test_a_point_cloud_comes_back_as_a_point_cloud():
    points, normals = tube()
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    pc.normals = o3d.utility.Vector3dVector(normals)
    pc.colors = o3d.utility.Vector3dVector(np.full((len(points), 3), 0.5))
    out, report = hgdeform.deform(pc, tube_scenario())
    assert isinstance(out, o3d.geometry.PointCloud) and out is not pc
    expected, expected_normals, _ = hgdeform.deform(points, tube_scenario(), normals=normals)
    assert same_bits(np.asarray(out.points), expected)
    assert same_bits(np.asarray(out.normals), expected_normals)
    assert same_bits(np.asarray(out.colors), np.asarray(pc.colors))  # kept
    assert same_bits(np.asarray(pc.points), points)  # the input is left as it was
    assert report["points"] == len(points)
    phi = hgdeform.field(pc, tube_scenario())
    assert same_bits(phi, hgdeform.field(points, tube_scenario(), normals=normals))


def test_a_triangle_mesh_comes_back_as_a_triangle_mesh():
    points, faces = tube_mesh()
    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(points),
                                     o3d.utility.Vector3iVector(faces.astype(np.int32)))
    out, _ = hgdeform.deform(mesh, tube_scenario())
    assert isinstance(out, o3d.geometry.TriangleMesh)
    expected, _ = hgdeform.deform(points, tube_scenario(), faces=faces)
    assert same_bits(np.asarray(out.vertices), expected)
    assert same_bits(np.asarray(out.triangles), faces.astype(np.int32))


def test_handle_deformation_and_write_take_open3d(tmp_path):
    points, _ = tube(n=1000, seed=31)
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    h = hgdeform.HandleDeformation(pc)
    h.set_fixed([np.flatnonzero(points[:, 0] < 1.0)])
    h.set_manipulated(np.flatnonzero(points[:, 0] > 9.0))
    assert h.points.shape == points.shape
    hgdeform.write(tmp_path / "pc.ply", pc)
    assert same_bits(hgdeform.read(tmp_path / "pc.ply").points, points)
    with pytest.raises(TypeError, match="Open3D PointCloud or TriangleMesh"):
        hgdeform.deform(o3d.geometry.LineSet(), tube_scenario())


def test_write_keeps_an_open3d_clouds_colours_and_normals(tmp_path):
    points, normals = tube(n=800, seed=32)
    colors = np.random.default_rng(3).uniform(0, 1, (len(points), 3))
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    pc.normals = o3d.utility.Vector3dVector(normals)
    pc.colors = o3d.utility.Vector3dVector(colors)
    hgdeform.write(tmp_path / "pc.ply", pc)
    back = hgdeform.read(tmp_path / "pc.ply")
    expected = np.rint(colors * 255).astype(np.uint8)
    for k, name in enumerate(("red", "green", "blue")):
        assert back.field(name).dtype == np.uint8
        assert np.array_equal(back.field(name), expected[:, k])
    assert np.allclose(back.normals, normals, atol=1e-6)
    # and Open3D reads them back as it wrote its own
    again = o3d.io.read_point_cloud(str(tmp_path / "pc.ply"))
    assert np.abs(np.asarray(again.colors) - colors).max() <= 0.5 / 255 + 1e-9


def test_a_deformed_meshs_triangle_normals_are_recomputed():
    points, faces = tube_mesh()
    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(points),
                                     o3d.utility.Vector3iVector(faces.astype(np.int32)))
    mesh.compute_triangle_normals()
    out, _ = hgdeform.deform(mesh, tube_scenario())
    expected = o3d.geometry.TriangleMesh(out)
    expected.compute_triangle_normals()
    assert not np.allclose(np.asarray(out.triangle_normals), np.asarray(mesh.triangle_normals))
    assert np.array_equal(np.asarray(out.triangle_normals), np.asarray(expected.triangle_normals))
