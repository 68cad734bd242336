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


def test_tensor_geometries_come_back_in_kind():
    points, normals = tube(n=900, seed=41)
    pc = o3d.t.geometry.PointCloud(o3d.core.Tensor(points))  # float64 positions
    pc.point.normals = o3d.core.Tensor(normals.astype(np.float32))
    pc.point.intensity = o3d.core.Tensor(np.arange(len(points), dtype=np.float32)[:, None])
    out, report = hgdeform.deform(pc, tube_scenario())
    assert type(out) is o3d.t.geometry.PointCloud and out is not pc
    expected, expected_normals, _ = hgdeform.deform(points, tube_scenario(),
                                                    normals=normals.astype(np.float32))
    assert out.point.positions.dtype == o3d.core.float64
    assert same_bits(out.point.positions.numpy(), expected)
    assert out.point.normals.dtype == o3d.core.float32  # each attribute keeps its dtype
    assert np.array_equal(out.point.normals.numpy(), expected_normals.astype(np.float32))
    assert np.array_equal(out.point.intensity.numpy(), pc.point.intensity.numpy())  # kept
    assert same_bits(pc.point.positions.numpy(), points)  # the input is left as it was
    assert report["points"] == len(points)

    vertices, faces = tube_mesh()
    mesh = o3d.t.geometry.TriangleMesh(o3d.core.Tensor(vertices.astype(np.float32)),
                                       o3d.core.Tensor(faces))
    out, _ = hgdeform.deform(mesh, tube_scenario())
    assert type(out) is o3d.t.geometry.TriangleMesh
    expected, _ = hgdeform.deform(vertices.astype(np.float32), tube_scenario(), faces=faces)
    assert out.vertex.positions.dtype == o3d.core.float32
    assert np.array_equal(out.vertex.positions.numpy(), expected.astype(np.float32))
    assert np.array_equal(out.triangle.indices.numpy(), faces)


def test_a_vector3dvector_is_taken_and_returned():
    points, _ = tube(n=700, seed=42)
    out, _ = hgdeform.deform(o3d.utility.Vector3dVector(points), tube_scenario())
    assert isinstance(out, o3d.utility.Vector3dVector)
    expected, _ = hgdeform.deform(points, tube_scenario())
    assert same_bits(np.asarray(out), expected)
    phi = hgdeform.field(o3d.utility.Vector3dVector(points), tube_scenario())
    assert same_bits(phi, hgdeform.field(points, tube_scenario()))


def test_written_pcd_is_read_by_open3d_with_normals_and_colours(tmp_path):
    # Open3D and PCL look for normal_x and a packed rgb in a PCD: a shape made from arrays or an
    # Open3D cloud is written with those names.
    points, normals = tube(n=600, seed=43)
    colors = np.random.default_rng(5).integers(0, 256, (len(points), 3)) / 255.0
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    pc.normals = o3d.utility.Vector3dVector(normals)
    pc.colors = o3d.utility.Vector3dVector(colors)
    for binary in (True, False):
        path = tmp_path / ("pc%d.pcd" % binary)
        hgdeform.write(path, pc, ascii=not binary)
        header = path.read_bytes()[:400].decode("latin-1")
        assert "normal_x normal_y normal_z rgb" in header, header
        back = o3d.io.read_point_cloud(str(path))
        assert back.has_normals() and back.has_colors()
        assert np.abs(np.asarray(back.normals) - normals).max() < 1e-6
        assert np.abs(np.asarray(back.colors) - colors).max() < 1e-9
    shape = hgdeform.Shape(points, normals)
    hgdeform.write(tmp_path / "shape.pcd", shape)
    back = o3d.io.read_point_cloud(str(tmp_path / "shape.pcd"))
    assert back.has_normals()
    assert np.abs(np.asarray(back.normals) - normals).max() < 1e-6


def test_tensor_geometries_in_field_and_float32_positions():
    points, normals = tube(n=900, seed=44)
    pc = o3d.t.geometry.PointCloud(o3d.core.Tensor(points.astype(np.float32)))
    pc.point.normals = o3d.core.Tensor(normals.astype(np.float32))
    pc.point.colors = o3d.core.Tensor(np.full((len(points), 3), 0.25, np.float32))
    phi = hgdeform.field(pc, tube_scenario())
    assert same_bits(phi, hgdeform.field(points.astype(np.float32), tube_scenario(),
                                         normals=normals.astype(np.float32)))
    out, _ = hgdeform.deform(pc, tube_scenario())
    expected, _, _ = hgdeform.deform(points.astype(np.float32), tube_scenario(),
                                     normals=normals.astype(np.float32))
    assert out.point.positions.dtype == o3d.core.float32
    assert np.array_equal(out.point.positions.numpy(), expected.astype(np.float32))
    assert np.array_equal(out.point.colors.numpy(), pc.point.colors.numpy())

    vertices, faces = tube_mesh()
    mesh = o3d.t.geometry.TriangleMesh(o3d.core.Tensor(vertices), o3d.core.Tensor(faces))
    assert same_bits(hgdeform.field(mesh, tube_scenario()),
                     hgdeform.field(vertices, tube_scenario(), faces=faces))


def handle_deformation_of(geometry, points):
    hd = hgdeform.HandleDeformation(geometry)
    hd.set_fixed([np.flatnonzero(points[:, 0] < 1.0)])
    hd.set_manipulated(np.flatnonzero(points[:, 0] > 9.0))
    hd.drag((10.0, 1.0, 0.0), (10.0, 2.5, 0.5))
    return hd


def test_handle_deformation_gives_the_deformed_geometry_in_kind():
    points, normals = tube(n=1200, seed=45)
    expected = handle_deformation_of(points, points).deformed_shape().points

    legacy = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    legacy.colors = o3d.utility.Vector3dVector(np.full((len(points), 3), 0.5))
    out = handle_deformation_of(legacy, points).deformed_geometry()
    assert isinstance(out, o3d.geometry.PointCloud) and out is not legacy
    assert same_bits(np.asarray(out.points), expected)
    assert same_bits(np.asarray(out.colors), np.asarray(legacy.colors))

    tensor = o3d.t.geometry.PointCloud(o3d.core.Tensor(points))
    tensor.point.intensity = o3d.core.Tensor(np.arange(len(points), dtype=np.float32)[:, None])
    hd = handle_deformation_of(tensor, points)
    out = hd.deformed_geometry()
    assert type(out) is o3d.t.geometry.PointCloud
    assert same_bits(out.point.positions.numpy(), expected)
    assert np.array_equal(out.point.intensity.numpy(), tensor.point.intensity.numpy())
    assert same_bits(tensor.point.positions.numpy(), points)  # the input left as it was
    # world_points: the same positions to float32's precision, in the same order
    assert np.abs(hd.world_points() - expected).max() < 1e-5

    out = handle_deformation_of(o3d.utility.Vector3dVector(points), points).deformed_geometry()
    assert isinstance(out, o3d.utility.Vector3dVector)
    assert same_bits(np.asarray(out), expected)
