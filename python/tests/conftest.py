"""Shared test data and helpers: shapes made here with numpy, a PLY writer and reader of our own
(so that what the command-line tool reads and writes is checked independently of the module),
and the command-line tool itself (HGD_TOOL, set by ctest; else build/tools/hgdeform)."""

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
TOOL = os.environ.get("HGD_TOOL", str(ROOT / "build" / "tools" / "hgdeform"))


def tube(n=2000, seed=1, length=10.0, radius=1.0):
    """Points on a tube along x (0..length), with their outward normals: (n, 3), (n, 3)."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, length, n)
    a = rng.uniform(0.0, 2 * np.pi, n)
    normals = np.stack([np.zeros(n), np.cos(a), np.sin(a)], axis=1)
    points = np.stack([x, radius * np.cos(a), radius * np.sin(a)], axis=1)
    return points, normals


def tube_mesh(nu=60, nv=16, length=10.0, radius=1.0):
    """A triangulated tube: vertices (nu * nv, 3) and triangles (M, 3)."""
    u = np.linspace(0.0, length, nu)
    a = np.linspace(0.0, 2 * np.pi, nv, endpoint=False)
    uu, aa = np.meshgrid(u, a, indexing="ij")
    points = np.stack([uu.ravel(), radius * np.cos(aa).ravel(),
                       radius * np.sin(aa).ravel()], axis=1)
    faces = []
    for i in range(nu - 1):
        for j in range(nv):
            p, q = i * nv + j, i * nv + (j + 1) % nv
            faces.append([p, p + nv, q])
            faces.append([q, p + nv, q + nv])
    return points, np.array(faces, dtype=np.int64)


def tube_scenario(length=10.0, to=(10.0, 3.0, 0.0)):
    """The base of the tube fixed, its far end dragged sideways."""
    return {
        "format": "hgdeform-scenario/1",
        "fixed": [{"box": {"min": [-1, -2, -2], "max": [1.0, 2, 2]}}],
        "manipulated": {"box": {"min": [length - 1.0, -2, -2], "max": [length + 1, 2, 2]}},
        "clusters": 8,
        "move": {"drag": {"from": [length, 1.0, 0.0], "to": list(to)}},
    }


def write_ply(path, points, normals=None, faces=None, fields=None):
    """A binary little-endian PLY with double x y z (and nx ny nz), the given fields (name ->
    1-D array, its dtype kept) and triangles."""
    n = len(points)
    cols = [("x", points[:, 0]), ("y", points[:, 1]), ("z", points[:, 2])]
    if normals is not None:
        cols += [("nx", normals[:, 0]), ("ny", normals[:, 1]), ("nz", normals[:, 2])]
    for name, values in (fields or {}).items():
        cols.append((name, np.asarray(values)))
    names = {np.dtype(np.float64): "double", np.dtype(np.float32): "float",
             np.dtype(np.uint8): "uchar", np.dtype(np.int32): "int",
             np.dtype(np.uint16): "ushort", np.dtype(np.int16): "short",
             np.dtype(np.uint32): "uint", np.dtype(np.int8): "char"}
    dtype = np.dtype([(name, "<" + values.dtype.str[1:]) for name, values in cols])
    record = np.empty(n, dtype=dtype)
    for name, values in cols:
        record[name] = values
    header = ["ply", "format binary_little_endian 1.0", "element vertex %d" % n]
    header += ["property %s %s" % (names[values.dtype], name) for name, values in cols]
    if faces is not None:
        header += ["element face %d" % len(faces), "property list uchar int vertex_indices"]
    header.append("end_header")
    with open(path, "wb") as f:
        f.write(("\n".join(header) + "\n").encode())
        f.write(record.tobytes())
        if faces is not None:
            tri = np.empty(len(faces), dtype=[("k", "u1"), ("v", "<i4", (3,))])
            tri["k"] = 3
            tri["v"] = faces
            f.write(tri.tobytes())


def read_ply_vertices(path):
    """The vertex records of a binary little-endian PLY (as the tool writes it), as a numpy
    structured array."""
    types = {"double": "<f8", "float": "<f4", "uchar": "u1", "int": "<i4", "uint": "<u4",
             "short": "<i2", "ushort": "<u2", "char": "i1", "float64": "<f8",
             "float32": "<f4", "uint8": "u1", "int32": "<i4"}
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    lines = data[:end].decode().splitlines()
    assert lines[1] == "format binary_little_endian 1.0", lines[1]
    fields, count, in_vertex = [], 0, False
    for line in lines:
        words = line.split()
        if words[:1] == ["element"]:
            in_vertex = words[1] == "vertex"
            if in_vertex:
                count = int(words[2])
        elif words[:1] == ["property"] and in_vertex:
            fields.append((words[2], types[words[1]]))
    return np.frombuffer(data, dtype=np.dtype(fields), count=count, offset=end)


def xyz(records):
    return np.stack([records["x"], records["y"], records["z"]], axis=1).astype(np.float64)


def run_tool(*args):
    """Runs the command-line tool; its stdout. Fails the test with its stderr."""
    r = subprocess.run([TOOL, *map(str, args)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return r.stdout


def cli_deform(tmp_path, points, scenario, normals=None, faces=None, fields=None):
    """`hgdeform deform` on a PLY of these arrays: (its output records, its report, paths)."""
    src = tmp_path / "in.ply"
    write_ply(src, points, normals, faces, fields)
    s = tmp_path / "s.json"
    s.write_text(json.dumps(scenario))
    out = tmp_path / "cli_out.ply"
    rep = tmp_path / "cli_report.json"
    run_tool("deform", src, "-s", s, "-o", out, "--report", rep, "-q")
    return read_ply_vertices(out), json.loads(rep.read_text()), src, s, out


def same_bits(a, b):
    a, b = np.ascontiguousarray(a), np.ascontiguousarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


@pytest.fixture
def tube_points():
    return tube()
