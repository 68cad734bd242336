"""Open3D as the writer: write_point_cloud to ply, pcd (ascii, binary, compressed), xyz, xyzn,
xyzrgb and pts, with normals and colours where the format holds them; write_triangle_mesh to ply,
obj, off and stl; read back with open3d.io.read_point_cloud / read_triangle_mesh."""

import pytest

import cases
import checks

CASES = cases.open3d_cases()
MOVES = [c for c in CASES if c.name in ("cloud_ply_binary", "cloud_pcd_ascii", "cloud_xyzn", "mesh_obj",
                                        "mesh_ply_ascii")]


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.id)
def test_python_reads(session, case):
    checks.check_python_reads(session, case)


@pytest.mark.parametrize("case,label,ext,ascii,tool", checks.roundtrip_params(CASES))
def test_roundtrip(session, case, label, ext, ascii, tool):
    checks.check_roundtrip(session, case, label, ext, ascii, tool)


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.id)
def test_identity_move(session, case):
    checks.check_identity(session, case)


@pytest.mark.parametrize("case", MOVES, ids=lambda c: c.id)
def test_move(session, case):
    checks.check_move(session, case)
