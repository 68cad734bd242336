"""CloudCompare (command line, headless under xvfb-run) as the writer: PLY (binary, ascii) with
normals, colours and scalar fields (Intensity, GpsTime), ASCII with a header row (space and comma
separated, 12 decimals), and the mesh formats PLY, OBJ, OFF, STL; read back by CloudCompare
loading the file and exporting it (clouds as ASCII with a header, -PREC 12; meshes as binary PLY)."""

import cases
import checks

test_python_reads, test_roundtrip, test_identity_move, test_move = checks.writer_tests(
    cases.cloudcompare_cases(), ("cloud_ply_binary", "cloud_asc_header_txt", "mesh_ply_binary"))
