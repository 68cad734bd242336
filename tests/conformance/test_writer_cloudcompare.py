"""CloudCompare (command line, headless under xvfb-run) as the writer: PLY (binary, ascii) with
normals, colours and scalar fields (Intensity, GpsTime), ASCII with a header row (space and comma
separated, 12 decimals), and the mesh formats PLY, OBJ, OFF, STL; read back by CloudCompare
loading the file and exporting it (clouds as ASCII with a header, -PREC 12; meshes as binary PLY)."""

import pytest

import cases
import checks

CASES = cases.cloudcompare_cases()
MOVES = [c for c in CASES if c.name in ("cloud_ply_binary", "cloud_asc_header_txt", "mesh_ply_binary")]


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
