"""MeshLab (meshlabserver 2020.09, headless under xvfb-run) as the writer: a tube mesh given
normals, a per-vertex quality and colours by a filter script, saved as PLY (binary, ascii; -m vc
vn vq), OBJ, OFF and STL (binary, ascii); read back by meshlabserver loading the file and saving
it as binary PLY with colours, normals and quality (binary: its ascii PLY keeps 7 digits)."""

import pytest

import cases
import checks

CASES = cases.meshlab_cases()
MOVES = [c for c in CASES if c.name in ("ply_binary", "off")]


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
