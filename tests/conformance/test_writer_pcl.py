"""PCL as the writer: savePCDFileASCII / Binary / BinaryCompressed and PLYWriter (ascii, binary)
of PointXYZ, PointXYZI, PointXYZRGB, PointXYZRGBNormal, PointNormal and an organized cloud with
NaN points (pcl_probe.cpp), and the pcl_ply2pcd, pcl_pcd2ply and pcl_convert_pcd_ascii_binary
converters; read back with pcl::io::loadPCDFile / loadPLYFile (pcl_probe read)."""

import cases
import checks

test_python_reads, test_roundtrip, test_identity_move, test_move = checks.writer_tests(
    cases.pcl_cases(), ("pcd_binary_xyzrgbnormal", "pcd_binary_compressed_organized", "ply_ascii_pointnormal", "pcd_ascii_xyzi"))
