"""MeshLab (meshlabserver 2020.09, headless under xvfb-run) as the writer: a tube mesh given
normals, a per-vertex quality and colours by a filter script, saved as PLY (binary, ascii; -m vc
vn vq), OBJ, OFF and STL (binary, ascii); read back by meshlabserver loading the file and saving
it as binary PLY with colours, normals and quality (binary: its ascii PLY keeps 7 digits)."""

import cases
import checks

test_python_reads, test_roundtrip, test_identity_move, test_move = checks.writer_tests(
    cases.meshlab_cases(), ("ply_binary", "off"))
