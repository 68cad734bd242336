"""PCL as the writer: savePCDFileASCII / Binary / BinaryCompressed and PLYWriter (ascii, binary)
of PointXYZ, PointXYZI, PointXYZRGB, PointXYZRGBNormal, PointNormal and an organized cloud with
NaN points (pcl_probe.cpp), and the pcl_ply2pcd, pcl_pcd2ply and pcl_convert_pcd_ascii_binary
converters; read back with pcl::io::loadPCDFile / loadPLYFile (pcl_probe read)."""

import pytest

import cases
import checks

CASES = cases.pcl_cases()
MOVES = [c for c in CASES if c.name in ("pcd_binary_xyzrgbnormal", "pcd_binary_compressed_organized",
                                        "ply_ascii_pointnormal", "pcd_ascii_xyzi")]


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
