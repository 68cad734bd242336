"""Open3D as the writer: write_point_cloud to ply, pcd (ascii, binary, compressed), xyz, xyzn,
xyzrgb and pts, with normals and colours where the format holds them; write_triangle_mesh to ply,
obj, off and stl; read back with open3d.io.read_point_cloud / read_triangle_mesh."""

import cases
import checks

test_python_reads, test_roundtrip, test_identity_move, test_move = checks.writer_tests(
    cases.open3d_cases(), ("cloud_ply_binary", "cloud_pcd_ascii", "cloud_xyzn", "mesh_obj", "mesh_ply_ascii"))
