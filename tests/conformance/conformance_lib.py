"""Shared machinery of the conformance suite: where the tools are, how a third-party tool reads a
file (as a `Reading`: every per-point value it sees, in its own types), and how two readings are
compared (bit for bit).

The rule of the suite: a file written by a third-party tool W is deformed by hgdeform (a move that
moves nothing, or a real one) and written back in its own format and in the others; then a tool
that reads both the source's format and the output's (W itself when it can) reads the source and
the output, and what it sees must be the same, value for value, bit for bit.
"""

import hashlib
import json
import os
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile
import threading

import numpy as np
import pytest

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[1]
TOOL = os.environ.get("HGD_TOOL", str(ROOT / "build" / "tools" / "hgdeform"))
XVFB = shutil.which("xvfb-run")
# CloudCompare and MeshLab are given this long per call (they start in about half a second).
GUI_TIMEOUT = 120


def in_ci():
    value = os.environ.get("CI", "").strip().lower()
    return value not in ("", "0", "false", "no")


def unavailable(reason):
    """A tool the case needs cannot run: a failure in CI (CI=true), else a skip that says why."""
    if in_ci():
        pytest.fail("CI is set and a tool this case needs cannot run: " + reason, pytrace=False)
    pytest.skip(reason)


class ToolUnavailable(Exception):
    pass


# ----------------------------------------------------------------------------------------------
# hgdeform (the command-line tool and the Python module)

def hgdeform_tool():
    if not (os.path.isfile(TOOL) and os.access(TOOL, os.X_OK)):
        raise ToolUnavailable("the hgdeform command-line tool is not at %s (set HGD_TOOL, or build it)" % TOOL)
    return TOOL


# hgdeform.read runs in a child process, so that a crash of the module (a segmentation fault)
# fails the case that met it instead of ending the whole session.
_READ_SCRIPT = r"""
import sys
import numpy as np
try:
    import hgdeform
except Exception as e:
    print("IMPORT: %s: %s" % (type(e).__name__, e))
    sys.exit(3)
try:
    s = hgdeform.read(sys.argv[1])
except Exception as e:
    print("READ: %s: %s" % (type(e).__name__, e))
    sys.exit(4)
out = {"points": np.asarray(s.points), "width": np.array(s.width), "height": np.array(s.height)}
if s.normals is not None:
    out["normals"] = np.asarray(s.normals)
faces = s.faces
if faces is not None and len(faces):
    flat = [np.asarray(f, dtype=np.int64) for f in faces]
    out["face_sizes"] = np.array([len(f) for f in flat], dtype=np.int64)
    out["face_indices"] = np.concatenate(flat)
names = list(s.fields)
for i, name in enumerate(names):
    out["field_%d" % i] = np.asarray(s.fields[name])
out["field_names"] = np.array(names, dtype=object)
np.savez(sys.argv[2], **out)
"""


class ModuleShape:
    """What hgdeform.read returned (in a child process): points, normals, faces, fields, width, height."""

    def __init__(self, npz):
        self.points = npz["points"]
        self.normals = npz["normals"] if "normals" in npz else None
        self.width, self.height = int(npz["width"]), int(npz["height"])
        self.faces = None
        if "face_sizes" in npz:
            sizes, idx = npz["face_sizes"], npz["face_indices"]
            ends = np.cumsum(sizes)
            self.faces = [tuple(int(i) for i in idx[e - k:e]) for k, e in zip(sizes, ends)]
        names = list(npz["field_names"])
        self.fields = {str(n): npz["field_%d" % i] for i, n in enumerate(names)}

    def __len__(self):
        return len(self.points)


def hgdeform_read(path):
    """hgdeform.read(path) in a child process: a ModuleShape. ToolUnavailable when the module does
    not import; ReadFailure (with the error, or the signal that ended it) when the read fails."""
    with tempfile.TemporaryDirectory(prefix="hgd-read-") as d:
        out = os.path.join(d, "shape.npz")
        r = subprocess.run([sys.executable, "-c", _READ_SCRIPT, str(path), out], capture_output=True, text=True,
                           timeout=300)
        if r.returncode == 3:
            raise ToolUnavailable("the hgdeform Python module does not import (%s; PYTHONPATH=%s)" % (
                r.stdout.strip()[8:], os.environ.get("PYTHONPATH", "")))
        if r.returncode != 0:
            why = r.stdout.strip() or ("killed by signal %d" % -r.returncode if r.returncode < 0 else
                                       "exit %d" % r.returncode)
            raise ReadFailure("hgdeform.read(%r) failed: %s%s" % (str(path), why, (
                "\n" + r.stderr.strip()[-1500:]) if r.stderr.strip() else ""))
        with np.load(out, allow_pickle=True) as npz:
            return ModuleShape(npz)


FIXED_BOX = {"box": {"min": [-1.0, -3.0, -3.0], "max": [1.0, 3.0, 3.0]}}
HANDLE_BOX = {"box": {"min": [9.0, -3.0, -3.0], "max": [11.0, 3.0, 3.0]}}

# The suite's shapes are tubes along x from 0 to 10 (radius about 1): the end x < 1 is fixed, the
# end x > 9 is the handle. REST has no move (hgdeform writes the rest pose: the round trips);
# IDENTITY moves the handle by nothing (a frame motion of zero): nothing may change either.
REST = {
    "format": "hgdeform-scenario/1",
    "fixed": [FIXED_BOX],
    "manipulated": HANDLE_BOX,
    "clusters": 8,
}
IDENTITY = dict(REST, move={"frame": {"translate": [0.0, 0.0, 0.0]}})
# A real move: the handle's end dragged sideways by 2 (a fifth of the length).
DRAG = {
    "format": "hgdeform-scenario/1",
    "fixed": [FIXED_BOX],
    "manipulated": HANDLE_BOX,
    "clusters": 8,
    "move": {"drag": {"from": [10.0, 1.0, 0.0], "to": [10.0, 3.0, 0.0]}},
}


def scenario_file(directory, name, scenario):
    path = pathlib.Path(directory) / (name + ".json")
    if not path.exists():
        path.write_text(json.dumps(scenario, indent=1))
    return path


def tool_cmd(*args):
    return " ".join(shlex_quote(str(a)) for a in args)


def shlex_quote(s):
    import shlex
    return shlex.quote(s)


def run_hgdeform(src, out, scenario_path, ascii=False):
    """`hgdeform deform SRC -s S -o OUT [--ascii]`: (command line, stderr). Fails the test with the
    command and its stderr when the tool fails."""
    try:
        tool = hgdeform_tool()
    except ToolUnavailable as e:
        unavailable(str(e))
    args = [tool, "deform", str(src), "-s", str(scenario_path), "-o", str(out), "-q"]
    if ascii:
        args.append("--ascii")
    r = subprocess.run(args, capture_output=True, text=True, timeout=300)
    cmd = tool_cmd(*args)
    if r.returncode != 0:
        pytest.fail("hgdeform failed (exit %d): %s\n%s" % (r.returncode, cmd, r.stderr.strip()), pytrace=False)
    if not pathlib.Path(out).exists():
        pytest.fail("hgdeform wrote no %s: %s" % (out, cmd), pytrace=False)
    return cmd, r.stderr


# ----------------------------------------------------------------------------------------------
# Readings

class Reading:
    """What one tool sees in one file. `fields` maps a canonical key to an array with a row per
    point (the tool's own dtype): 'xyz' (N, 3), 'normal' (N, 3), 'rgb' (N, 3), 'alpha' (N,), and
    every other per-point value under its name in lower case without CloudCompare's 'scalar_'
    prefix. Keys starting with '_' hold what is compared only when the output is in the source's
    own format (the alpha byte of a PCL packed 'rgb'). `names` gives the tool's own name of each
    key (for messages); `faces` the polygons (a list of index tuples) or None; `triangles` (STL:
    (M, 3, 3) corner positions) or None."""

    def __init__(self, tool, path):
        self.tool, self.path = tool, pathlib.Path(path)
        self.fields, self.names = {}, {}
        self.faces = None
        self.width = self.height = None
        self.command = None  # how the tool was made to read the file (for messages)
        self.capacity = {}  # key -> "f4" where the reader holds the values in float32 only
        self.unordered = False  # the reader renumbers vertices

    def float32_reader(self):
        for k in self.fields:
            self.capacity[k] = "f4"

    @property
    def n(self):
        return len(self.fields["xyz"]) if "xyz" in self.fields else 0

    def add(self, key, values, name):
        self.fields[key] = np.asarray(values)
        self.names[key] = name

    def describe(self):
        return ", ".join("%s(%s %s)" % (self.names.get(k, k), v.dtype, "x".join(map(str, v.shape[1:])) or "1")
                         for k, v in self.fields.items())


def add_columns(rd, col, names, xyz, normal, rgb, alpha):
    """Adds a table's columns (`col[name]`, names in order) to a Reading: the positions, normals,
    colours and alpha under the names this writer gives them, every other column by its name."""
    rd.add("xyz", np.stack([col[n] for n in xyz], axis=1), " ".join(xyz))
    used = set(xyz)
    for key, triple in (("normal", normal), ("rgb", rgb)):
        if set(triple) <= set(names):
            rd.add(key, np.stack([col[n] for n in triple], axis=1), " ".join(triple))
            used |= set(triple)
    if alpha in names:
        rd.add("alpha", col[alpha], alpha)
        used.add(alpha)
    for n in names:
        if n not in used:
            rd.add(canonical(n), col[n], n)


def canonical(name):
    n = name.strip().lower()
    if n.startswith("scalar_") and len(n) > 7:
        n = n[7:]
    return n


# ---- PLY (MeshLab's and CloudCompare's read-back files, any PLY) ------------------------------

_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}


def parse_ply(path):
    """A PLY file: {element name: structured array (no lists) or list of per-row dicts}, as
    (elements, order of properties). Vertex records are numpy structured arrays; a face element
    gives a list of index tuples under 'faces'."""
    data = pathlib.Path(path).read_bytes()
    end = data.index(b"end_header")
    end = data.index(b"\n", end) + 1
    header = data[:end].decode("latin-1").splitlines()
    fmt, elements = None, []
    for line in header:
        w = line.split()
        if not w:
            continue
        if w[0] == "format":
            fmt = w[1]
        elif w[0] == "element":
            elements.append([w[1], int(w[2]), []])
        elif w[0] == "property":
            if w[1] == "list":
                elements[-1][2].append((w[4], "list", _PLY_TYPES[w[2]], _PLY_TYPES[w[3]]))
            else:
                elements[-1][2].append((w[2], _PLY_TYPES[w[1]]))
    out = {}
    if fmt == "ascii":
        tokens = data[end:].split()
        pos = 0
        for name, count, props in elements:
            if all(len(p) == 2 for p in props):
                k = len(props)
                block = np.array(tokens[pos:pos + k * count], dtype=object).reshape(count, k) if count else \
                    np.empty((0, k), dtype=object)
                rec = np.empty(count, dtype=[(p[0], p[1]) for p in props])
                for j, p in enumerate(props):
                    col = block[:, j]
                    if p[1].startswith("f"):
                        rec[p[0]] = np.array([float(t) for t in col], dtype=np.float64)
                    else:
                        rec[p[0]] = np.array([int(t) for t in col], dtype=np.int64)
                pos += k * count
                out[name] = rec
            else:
                rows = []
                for _ in range(count):
                    row = {}
                    for p in props:
                        if p[1] == "list":
                            m = int(tokens[pos]); pos += 1
                            row[p[0]] = tuple(int(float(t)) for t in tokens[pos:pos + m]); pos += m
                        else:
                            row[p[0]] = float(tokens[pos]); pos += 1
                    rows.append(row)
                out[name] = rows
    else:
        bo = "<" if fmt == "binary_little_endian" else ">"
        pos = end
        for name, count, props in elements:
            if all(len(p) == 2 for p in props):
                dt = np.dtype([(p[0], bo + p[1] if p[1] not in ("i1", "u1") else p[1]) for p in props])
                out[name] = np.frombuffer(data, dtype=dt, count=count, offset=pos).copy()
                pos += dt.itemsize * count
            else:
                rows = []
                for _ in range(count):
                    row = {}
                    for p in props:
                        if p[1] == "list":
                            ct = np.dtype(bo + p[2] if p[2] not in ("i1", "u1") else p[2])
                            it = np.dtype(bo + p[3] if p[3] not in ("i1", "u1") else p[3])
                            m = int(np.frombuffer(data, ct, 1, pos)[0]); pos += ct.itemsize
                            row[p[0]] = tuple(int(v) for v in np.frombuffer(data, it, m, pos)); pos += it.itemsize * m
                        else:
                            t = np.dtype(bo + p[1] if p[1] not in ("i1", "u1") else p[1])
                            row[p[0]] = np.frombuffer(data, t, 1, pos)[0]; pos += t.itemsize
                    rows.append(row)
                out[name] = rows
    return out


def reading_from_ply(tool, path, ply_path):
    """A Reading of the vertex (and face) elements of a PLY that a tool wrote to show what it read."""
    r = Reading(tool, path)
    el = parse_ply(ply_path)
    v = el.get("vertex")
    if v is None:
        v = np.empty(0, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    add_columns(r, v, list(v.dtype.names), ("x", "y", "z"), ("nx", "ny", "nz"), ("red", "green", "blue"), "alpha")
    faces = el.get("face")
    if faces is not None:
        key = None
        if faces:
            key = "vertex_indices" if "vertex_indices" in faces[0] else next(iter(faces[0]))
        r.faces = [tuple(f[key]) for f in faces] if key else []
    return r


# ---- PCL (tests/conformance/pcl_probe) ---------------------------------------------------------

_PCL_TYPES = {1: "i1", 2: "u1", 3: "<i2", 4: "<u2", 5: "<i4", 6: "<u4", 7: "<f4", 8: "<f8"}
PCL_READS = ("pcd", "ply")

_probe_lock = threading.Lock()
_probe_path = None
_probe_error = None


def pcl_probe():
    """The probe program: HGD_PCL_PROBE (ctest sets it), build/tests/conformance/pcl_probe, or
    compiled here with g++ and pkg-config (once per session, into a temporary folder)."""
    global _probe_path, _probe_error
    with _probe_lock:
        if _probe_path or _probe_error:
            if _probe_error:
                raise ToolUnavailable(_probe_error)
            return _probe_path
        for candidate in (os.environ.get("HGD_PCL_PROBE"), str(ROOT / "build" / "tests" / "conformance" / "pcl_probe")):
            if candidate and os.path.isfile(candidate) and os.access(candidate, os.X_OK):
                _probe_path = candidate
                return candidate
        gxx, pkg = shutil.which("g++"), shutil.which("pkg-config")
        if not gxx or not pkg:
            _probe_error = "pcl_probe is not built (HGD_PCL_PROBE unset) and g++/pkg-config are missing to build it"
            raise ToolUnavailable(_probe_error)
        flags = subprocess.run([pkg, "--cflags", "--libs", "pcl_io"], capture_output=True, text=True)
        if flags.returncode != 0:
            _probe_error = "pcl_probe is not built and pkg-config finds no pcl_io (libpcl-dev): " + flags.stderr.strip()
            raise ToolUnavailable(_probe_error)
        out = pathlib.Path(tempfile.mkdtemp(prefix="hgd-pcl-probe-")) / "pcl_probe"
        r = subprocess.run([gxx, "-std=c++17", "-O1", "-DEIGEN_HAS_CXX17_OVERALIGN=0", str(HERE / "pcl_probe.cpp"),
                            "-o", str(out)] + flags.stdout.split(), capture_output=True, text=True)
        if r.returncode != 0:
            # The probe is part of this suite: a compile error is a failure, not a missing tool.
            pytest.fail("pcl_probe.cpp does not compile:\n" + r.stderr[-3000:], pytrace=False)
        _probe_path = str(out)
        return _probe_path


def pcl_read(path):
    probe = pcl_probe()
    args = [probe, "read", str(path)]
    r = subprocess.run(args, capture_output=True, text=True, timeout=120)
    if r.returncode != 0:
        raise ReadFailure("PCL could not read %s: %s\n%s" % (path, tool_cmd(*args), r.stderr.strip()[-2000:]))
    j = json.loads(r.stdout)
    n = j["width"] * j["height"]
    raw = bytes.fromhex(j["data"])
    rd = Reading("pcl", path)
    rd.command = tool_cmd(*args)
    rd.width, rd.height = j["width"], j["height"]
    cols = {}
    for f in j["fields"]:
        if f["name"] in ("_", ""):
            continue
        dt = np.dtype(_PCL_TYPES[f["datatype"]])
        shape = (f["count"],) if f["count"] != 1 else ()
        rec = np.dtype({"names": ["v"], "formats": [(dt, shape) if shape else dt], "offsets": [f["offset"]],
                        "itemsize": j["point_step"]})
        cols[f["name"]] = (np.frombuffer(raw, dtype=rec, count=n)["v"].copy(), f)
    if not {"x", "y", "z"} <= set(cols):
        raise ReadFailure("PCL read %s without x y z (fields %s)" % (path, list(cols)))
    rd.add("xyz", np.stack([cols["x"][0], cols["y"][0], cols["z"][0]], axis=1), "x y z")
    used = {"x", "y", "z"}
    if {"normal_x", "normal_y", "normal_z"} <= set(cols):
        rd.add("normal", np.stack([cols["normal_x"][0], cols["normal_y"][0], cols["normal_z"][0]], axis=1),
               "normal_x normal_y normal_z")
        used |= {"normal_x", "normal_y", "normal_z"}
    for packed in ("rgb", "rgba"):
        if packed in cols:
            values, f = cols[packed]
            bits = np.frombuffer(values.astype(values.dtype.newbyteorder("<")).tobytes(), "<u4") \
                if values.dtype.itemsize == 4 else values.astype("<u4")
            rgb = np.stack([(bits >> 16) & 255, (bits >> 8) & 255, bits & 255], axis=1).astype(np.uint8)
            rd.add("rgb", rgb, packed + " (packed, bytes R G B)")
            if packed == "rgba":
                rd.add("alpha", ((bits >> 24) & 255).astype(np.uint8), "rgba (packed, byte A)")
            else:
                rd.add("_alpha_byte", ((bits >> 24) & 255).astype(np.uint8), "rgb (packed, its 4th byte)")
            used.add(packed)
            break
    for name, (values, f) in cols.items():
        if name not in used:
            rd.add(canonical(name), values, name)
    return rd


class ReadFailure(Exception):
    pass


# ---- Open3D -------------------------------------------------------------------------------------

OPEN3D_CLOUD_READS = ("ply", "pcd", "xyz", "xyzn", "xyzrgb", "pts")
OPEN3D_MESH_READS = ("ply", "obj", "off", "stl")


def open3d():
    try:
        import open3d as o3d  # noqa: F401
        return o3d
    except Exception as e:
        raise ToolUnavailable("Open3D does not import (python3-open3d): %s: %s" % (type(e).__name__, e))


def _pcd_header_types(path):
    """{field: numpy dtype} of a PCD's header (FIELDS, SIZE, TYPE), and whether it is ascii."""
    fields = sizes = types = None
    ascii = False
    with open(path, "rb") as f:
        for raw in f:
            w = raw.decode("latin-1").split()
            if not w:
                continue
            if w[0] == "FIELDS":
                fields = w[1:]
            elif w[0] == "SIZE":
                sizes = [int(x) for x in w[1:]]
            elif w[0] == "TYPE":
                types = w[1:]
            elif w[0] == "DATA":
                ascii = w[1] == "ascii"
                break
    out = {}
    for n, z, t in zip(fields or [], sizes or [], types or []):
        out[n] = np.dtype({"F": "f", "I": "i", "U": "u"}[t] + str(z))
    return out, ascii


_O3D_F8 = {}


def open3d_binary_f8_limit(path):
    """Why Open3D cannot judge this PCD, or None: Open3D 0.16's binary PCD reader reads 8-byte
    floats (SIZE 8 TYPE F) as 0, silently. Confirmed on a two-point file each run, so that an
    Open3D that reads them makes the case a real check again."""
    types, ascii = _pcd_header_types(path)
    if ascii or types.get("x") != np.float64:
        return None
    if "limit" not in _O3D_F8:
        o3d = open3d()
        with tempfile.TemporaryDirectory() as d:
            probe = os.path.join(d, "f8.pcd")
            with open(probe, "wb") as f:
                f.write(b"VERSION 0.7\nFIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\n"
                        b"VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA binary\n" + np.array(
                            [1.5, 2.5, 3.5, 4, 5, 6], dtype="<f8").tobytes())
            got = np.asarray(o3d.io.read_point_cloud(probe).points)
        ok = got.shape == (2, 3) and np.array_equal(got.ravel(), [1.5, 2.5, 3.5, 4, 5, 6])
        _O3D_F8["limit"] = None if ok else (
            "Open3D %s reads a binary PCD's 8-byte floats as %s (a 2-point probe file): it cannot judge %s, "
            "whose x y z are doubles (PCL reads them)" % (o3d.__version__, got.ravel().tolist(), path))
    return _O3D_F8["limit"]


def open3d_read(path, mesh, fmt="auto"):
    """Open3D's reading. Its OBJ (tinyobjloader), OFF and STL readers hold float32 values; its
    OBJ reader renumbers vertices. Its ascii PCD reader parses text into double whatever the
    header's SIZE says: the values are taken at the header's type (what the file holds)."""
    o3d = open3d()
    rd = Reading("open3d", path)
    ext = pathlib.Path(path).suffix.lower().lstrip(".")
    if mesh:
        m = o3d.io.read_triangle_mesh(str(path))
        rd.command = "open3d.io.read_triangle_mesh(%r)" % str(path)
        v = np.asarray(m.vertices)
        if len(v) == 0:
            raise ReadFailure("Open3D read no vertex from %s (%s)" % (path, rd.command))
        rd.add("xyz", v, "vertices")
        if m.has_vertex_normals():
            rd.add("normal", np.asarray(m.vertex_normals), "vertex_normals")
        if m.has_vertex_colors():
            rd.add("rgb", np.asarray(m.vertex_colors), "vertex_colors")
        rd.faces = [tuple(int(i) for i in t) for t in np.asarray(m.triangles)]
        if ext in ("obj", "off", "stl"):
            rd.float32_reader()
        if ext == "obj":
            rd.unordered = True
            for k in rd.fields:
                rd.capacity[k] = "f4~"
    else:
        pc = o3d.io.read_point_cloud(str(path), format=fmt)
        rd.command = "open3d.io.read_point_cloud(%r, format=%r)" % (str(path), fmt)
        if len(pc.points) == 0:
            raise ReadFailure("Open3D read no point from %s (%s)" % (path, rd.command))
        pts = np.asarray(pc.points)
        nrm = np.asarray(pc.normals) if pc.has_normals() else None
        if ext == "pcd":
            types, ascii = _pcd_header_types(path)
            if ascii:
                if types.get("x") == np.float32:
                    pts = pts.astype(np.float32).astype(np.float64)
                if nrm is not None and types.get("normal_x") == np.float32:
                    nrm = nrm.astype(np.float32).astype(np.float64)
        rd.add("xyz", pts, "points")
        if nrm is not None:
            rd.add("normal", nrm, "normals")
        if pc.has_colors():
            rd.add("rgb", np.asarray(pc.colors), "colors")
    return rd


# ---- CloudCompare and MeshLab (headless, under xvfb-run) ---------------------------------------

CLOUDCOMPARE = shutil.which("CloudCompare") or shutil.which("cloudcompare")
MESHLABSERVER = shutil.which("meshlabserver")
CC_READS = ("ply", "xyz", "txt", "asc", "obj", "off", "stl")
MESHLAB_READS = ("ply", "obj", "off", "stl")


def gui_available(name, exe):
    if not exe:
        raise ToolUnavailable("%s is not installed (no executable on PATH)" % name)
    if not XVFB:
        raise ToolUnavailable("xvfb-run is missing (package xvfb): %s needs a display" % name)


def run_gui(args, name, expect):
    """Runs a Qt tool under xvfb-run; (command line, log). ReadFailure when it fails or does not
    write every file in `expect`."""
    full = [XVFB, "-a"] + [str(a) for a in args]
    for e in expect:
        pathlib.Path(e).unlink(missing_ok=True)
    try:
        r = subprocess.run(full, capture_output=True, text=True, timeout=GUI_TIMEOUT,
                           env=dict(os.environ, QT_LOGGING_RULES="*=false"))
    except subprocess.TimeoutExpired:
        raise ReadFailure("%s did not finish in %d s: %s" % (name, GUI_TIMEOUT, tool_cmd(*full)))
    log = r.stdout + r.stderr
    missing = [str(e) for e in expect if not pathlib.Path(e).exists()]
    if r.returncode != 0 or missing:
        lines = [l for l in log.splitlines() if "Plugin" not in l and l.strip()]
        raise ReadFailure("%s failed (exit %d%s): %s\n%s" % (
            name, r.returncode, ", did not write " + " ".join(missing) if missing else "",
            tool_cmd(*full), "\n".join(lines[-15:])))
    return tool_cmd(*full), log


def cloudcompare(*args, expect=()):
    gui_available("CloudCompare", CLOUDCOMPARE)
    return run_gui([CLOUDCOMPARE, "-SILENT", "-NO_TIMESTAMP"] + list(args), "CloudCompare", expect)


def meshlab(*args, expect=()):
    gui_available("meshlabserver", MESHLABSERVER)
    return run_gui([MESHLABSERVER] + list(args), "meshlabserver", expect)


def parse_cc_ascii(tool_path, asc_path):
    """CloudCompare's ASCII export with a header row (`//X Y Z R G B Intensity Nx Ny Nz`)."""
    text = pathlib.Path(asc_path).read_text()
    lines = text.splitlines()
    header = lines[0]
    if not header.startswith("//"):
        raise ReadFailure("CloudCompare's export %s has no header row" % asc_path)
    names = re.split(r"[ ,;\t]+", header[2:].strip())
    rows = [re.split(r"[ ,;\t]+", l.strip()) for l in lines[1:] if l.strip()]
    table = np.array([[float(v) for v in row] for row in rows], dtype=np.float64).reshape(len(rows), len(names))
    rd = Reading("cloudcompare", tool_path)
    col = {n: table[:, i] for i, n in enumerate(names)}
    add_columns(rd, col, names, ("X", "Y", "Z"), ("Nx", "Ny", "Nz"), ("R", "G", "B"), "A")
    return rd


_CC_PLY_KNOWN = {"x", "y", "z", "nx", "ny", "nz", "red", "green", "blue", "alpha", "diffuse_red", "diffuse_green",
                 "diffuse_blue"}


def cc_scalar_named_ply(path, workdir):
    """CloudCompare 2.11's PLY loader, without its dialog (-SILENT), loads every vertex property
    named scalar_NAME (as its own PLY export names scalar fields) but of the others only the
    first. A PLY whose vertex element has more such properties is given to it as a copy whose
    header calls them scalar_NAME (the data bytes unchanged; its export names them NAME again).
    Returns the path to give CloudCompare."""
    path = pathlib.Path(path)
    if path.suffix.lower() != ".ply":
        return path
    data = path.read_bytes()
    end = data.find(b"end_header")
    if end < 0:
        return path
    end = data.index(b"\n", end) + 1
    lines = data[:end].decode("latin-1").split("\n")
    element, plain = None, []
    for i, line in enumerate(lines):
        w = line.split()
        if w[:1] == ["element"]:
            element = w[1] if len(w) > 1 else None
        elif w[:1] == ["property"] and element == "vertex" and len(w) == 3 and w[1] != "list":
            name = w[2]
            if name.lower() not in _CC_PLY_KNOWN and not name.startswith("scalar_"):
                plain.append(i)
    if len(plain) < 2:
        return path
    for i in plain:
        w = lines[i].split()
        lines[i] = "property %s scalar_%s" % (w[1], w[2])
    out = pathlib.Path(workdir) / ("cc_named_%s_%s" % (_path_tag(path), path.name))
    out.write_bytes("\n".join(lines).encode("latin-1") + data[end:])
    return out


def cloudcompare_read(paths, mesh, workdir):
    """CloudCompare loads each file and exports it: a cloud as ASCII with a header and 12
    decimals (-C_EXPORT_FMT ASC -ADD_HEADER -PREC 12), a mesh as binary PLY (with its faces).
    One CloudCompare run for all the files (one per file if that run fails); {path: Reading or
    ReadFailure}."""
    workdir = pathlib.Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    paths = [pathlib.Path(p) for p in paths]

    def batch(group):
        # Named for the whole path: the outputs of different sources share file names (ply.ply).
        outs = [workdir / ("cc_read_%s_%s_%d.%s" % (p.name.replace(".", "_"), _path_tag(p), i, "ply" if mesh else "txt"))
                for i, p in enumerate(group)]
        args = []
        for p in group:
            args += ["-O", str(p)]
        if mesh:
            args += ["-M_EXPORT_FMT", "PLY", "-PLY_EXPORT_FMT", "BINARY_LE", "-SAVE_MESHES", "FILE",
                     " ".join(str(o) for o in outs)]
        else:
            args += ["-C_EXPORT_FMT", "ASC", "-ADD_HEADER", "-PREC", "12", "-SAVE_CLOUDS", "FILE",
                     " ".join(str(o) for o in outs)]
        cmd, _ = cloudcompare(*args, expect=outs)
        res = {}
        for p, o in zip(group, outs):
            # CloudCompare's PLY export calls scalar fields scalar_NAME: the same keys as its ASCII export.
            rd = reading_from_ply("cloudcompare", p, o) if mesh else parse_cc_ascii(p, o)
            rd.command = cmd
            rd.float32_reader()  # float32 coordinates (with a double global shift, none here) and scalars
            res[p] = rd
        return res

    try:
        return batch(paths)
    except ReadFailure:
        if len(paths) == 1:
            return {paths[0]: _capture(lambda: batch(paths)[paths[0]])}
        out = {}
        for p in paths:
            out[p] = _capture(lambda p=p: batch([p])[p])
        return out


def _path_tag(path):
    """A short tag of the file's whole path, to keep the readings of same-named files apart."""
    return hashlib.sha1(str(pathlib.Path(path).resolve()).encode()).hexdigest()[:10]


def _capture(f):
    try:
        return f()
    except ReadFailure as e:
        return e


def file_has_normals(path):
    """Does the file itself hold vertex normals (PLY nx, OFF N..., OBJ vn)?"""
    path = pathlib.Path(path)
    ext = path.suffix.lower()
    head = path.read_bytes()[:1 << 16]
    if ext == ".ply":
        end = head.find(b"end_header")
        return re.search(rb"property\s+\S+\s+nx\b", head[:end] if end >= 0 else head) is not None
    if ext == ".off":
        return b"N" in head.split(None, 1)[0] if head.strip() else False
    if ext == ".obj":
        return re.search(rb"(^|\n)vn\s", path.read_bytes()) is not None
    return False


def meshlab_read(path, workdir):
    """meshlabserver loads the file and saves it as binary PLY with vertex colours, normals and
    quality (-m vc vn vq): binary, so that every float is seen exactly (its ascii PLY writes 7
    significant digits)."""
    out = pathlib.Path(workdir) / ("ml_read_%s_%s.ply" % (pathlib.Path(path).name.replace(".", "_"), _path_tag(path)))
    cmd, _ = meshlab("-i", str(path), "-o", str(out), "-m", "vc", "vn", "vq", expect=[out])
    rd = reading_from_ply("meshlab", path, out)
    rd.command = cmd
    rd.float32_reader()  # vcg's CMeshO: float coordinates, normals, quality
    if "normal" in rd.fields and not file_has_normals(path):
        # MeshLab computes normals from the faces when the file has none: not the file's content.
        del rd.fields["normal"], rd.names["normal"]
    return rd


# ----------------------------------------------------------------------------------------------
# Comparison

def _bits(a):
    """float64 bit patterns of values (NaN as one pattern: a NaN is a NaN whatever its payload)."""
    f = np.asarray(a, dtype=np.float64)
    b = f.view(np.uint64).copy()
    b[np.isnan(f)] = np.uint64(0x7FF8000000000000)
    return b


def _fmt(v):
    v = float(v)
    return "nan" if v != v else "%r (%s)" % (v, v.hex())


def at_capacity(values, capacity):
    """Values as a reader can hold them: 'f4' rounds floats to float32 (a reader that parses into
    float32 whatever the file holds: tinyobjloader in Open3D, vcg in MeshLab, CloudCompare)."""
    v = np.asarray(values)
    if capacity in ("f4", "f4~") and v.dtype.kind == "f":
        return v.astype(np.float32)
    if capacity == "u8" and v.dtype.kind == "f":
        # colours of 0..1 written as 0..255 (hgdeform's PLY and OFF: README): compared as bytes
        return np.round(v * 255).astype(np.int64)
    return v


def compare_values(key, ref, got, ref_name, got_name, problems, ref_tool, rows=None, capacity="f8"):
    a, b = at_capacity(ref, capacity), at_capacity(got, capacity)
    if rows is not None:
        a, b = a[rows], b[rows]
    if a.shape != b.shape:
        problems.append("%s: shape %s in the source, %s in the output" % (ref_name, a.shape, b.shape))
        return
    if a.dtype.kind in "iu" and b.dtype.kind in "iu":
        bad = np.asarray(a, dtype=np.int64) != np.asarray(b, dtype=np.int64)
        if bad.ndim > 1:
            bad = bad.any(axis=tuple(range(1, bad.ndim)))
    else:
        bad = rows_differ(a, b, capacity)
    if bad.any():
        idx = np.flatnonzero(bad)
        ex = []
        for i in idx[:3]:
            av, bv = np.atleast_1d(a[i]), np.atleast_1d(b[i])
            ex.append("point %d: %s -> %s" % (int(rows[i]) if rows is not None else int(i),
                                            ", ".join(_fmt(x) for x in av), ", ".join(_fmt(x) for x in bv)))
        problems.append("%s (%s, as %s reads it%s; output: %s %s): %d of %d points differ; %s" % (
            ref_name, a.dtype, ref_tool, {"f4": ", compared in float32: the reader's precision",
                       "f4~": ", compared in float32 within one ulp: the reader's precision"}.get(capacity, ""),
            got_name, b.dtype, len(idx), len(bad), "; ".join(ex)))


_CC_STANDARD = {"xyz", "normal", "rgb", "alpha"}


def cloudcompare_unnamed(ref, got, keys):
    """CloudCompare's ASCII loader (-SILENT) does not take scalar fields' names from a header row:
    it calls them Scalar_field, Scalar_field_#2, ... in column order. {ref key: got key} pairing
    the source's scalar fields missing by name in the output with those, in order."""
    if got.tool != "cloudcompare":
        return {}
    unnamed = r"Scalar_field(_#\d+)?"
    default = [k for k in got.fields if re.fullmatch(unnamed, got.names[k]) and k not in ref.fields]
    missing = [k for k in keys if k not in got.fields and k not in _CC_STANDARD and not k.startswith("_")]
    if len(missing) == len(default) and default:
        return dict(zip(missing, default))
    # The other way round: the source is CloudCompare's own ASCII file, whose columns it read
    # unnamed (and some not at all), and the output names them (a PLY). Each unnamed column is
    # paired with the output field that holds the same values.
    pairs = {}
    for k in missing:
        if not re.fullmatch(unnamed, ref.names[k]):
            continue
        a = at_capacity(ref.fields[k], "f4")
        for g in got.fields:
            if g in ref.fields or g in _CC_STANDARD or g in pairs.values():
                continue
            b = at_capacity(got.fields[g], "f4")
            if a.shape == b.shape and not rows_differ(a, b, "f4").any():
                pairs[k] = g
                break
    return pairs


def _sort_key(a):
    """Rows' sort key: the values rounded to 1e-4 (so that a reader's one-ulp error does not
    reorder them), then the values themselves."""
    a = np.asarray(a, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        r = np.round(a, 4)
    return r


def triangle_set(values, faces):
    """Triangles as sorted rows of 3 x k values (each polygon fanned; each triangle's corners
    rotated to start at its smallest corner, orientation kept)."""
    tris = []
    for f in faces:
        for k in range(1, len(f) - 1):
            tris.append((f[0], f[k], f[k + 1]))
    v = np.asarray(values, dtype=np.float64)
    v = v.reshape(len(v), -1)
    key = _sort_key(v)
    idx = np.asarray(tris, dtype=np.int64)
    t, tk = v[idx], key[idx]  # (M, 3, k)
    out = []
    for tri, tri_key in zip(t, tk):
        rows = [tuple(r) for r in tri_key]
        s = min(range(3), key=lambda i: rows[i])
        out.append(np.concatenate([tri[s:], tri[:s]]).ravel())
    arr = np.array(out, dtype=np.float64).reshape(len(out), -1)
    return arr[np.lexsort(_sort_key(arr).T[::-1])] if len(arr) else arr


def rows_differ(a, b, capacity):
    """Which rows of a and b (same shape) differ: bit for bit, or (capacity 'f4~') in float32
    within one ulp (Open3D's OBJ reader, tinyobjloader, parses some numbers one float32 ulp off:
    '1.22728e-16' as 1.2272800662599447e-16, the nearest float32 being 1.2272799339110467e-16)."""
    if capacity == "f4~":
        fa, fb = np.asarray(a, dtype=np.float32), np.asarray(b, dtype=np.float32)
        with np.errstate(invalid="ignore"):
            close = (fa == fb) | (np.abs(fa.astype(np.float64) - fb.astype(np.float64)) <=
                                  np.spacing(np.maximum(np.abs(fa), np.abs(fb))).astype(np.float64))
        close |= np.isnan(fa) & np.isnan(fb)
        bad = ~close
    else:
        bad = _bits(at_capacity(a, capacity)) != _bits(at_capacity(b, capacity))
    return bad.any(axis=tuple(range(1, bad.ndim))) if bad.ndim > 1 else bad


def _records(reading, keys, capacity):
    cols = []
    for k in keys:
        v = np.asarray(at_capacity(reading.fields[k], capacity.get(k, "f8")), dtype=np.float64)
        cols.append(v.reshape(len(v), -1))
    return np.concatenate(cols, axis=1)


def _sorted_rows(a):
    return a[np.lexsort(_sort_key(a).T[::-1])] if len(a) else a


def compare_unordered(ref, got, keys, capacity, faces, problems):
    """For a reader that renumbers vertices (Open3D's OBJ reader: one vertex per distinct v/vt/vn
    corner, in face order): the same vertices (all compared values together) and, with faces,
    the same triangles of them, in any order."""
    a, b = _records(ref, keys, capacity), _records(got, keys, capacity)
    what = "+".join(ref.names[k] for k in keys)
    cap = "f4~" if "f4~" in capacity.values() else ("f4" if "f4" in capacity.values() else "f8")
    if faces and ref.faces and got.faces:
        ta, tb = triangle_set(a, ref.faces), triangle_set(b, got.faces)
        if ta.shape != tb.shape:
            problems.append("%d triangles in the source, %d in the output" % (len(ta), len(tb)))
        else:
            bad = np.flatnonzero(rows_differ(ta, tb, cap))
            if len(bad):
                problems.append("%d of %d triangles differ in their corners' %s (as %s reads them, in any vertex "
                                "order%s); first: %s -> %s" % (
                                    len(bad), len(ta), what, ref.tool,
                                    {"f4": ", float32", "f4~": ", float32 within one ulp"}.get(cap, ""),
                                    ta[bad[0]].tolist(), tb[bad[0]].tolist()))
        return
    ua, ub = _sorted_rows(np.unique(a, axis=0)), _sorted_rows(np.unique(b, axis=0))
    if ua.shape != ub.shape or rows_differ(ua, ub, cap).any():
        problems.append("the sets of vertices (%s, as %s reads them, in any order) differ: %d distinct in the "
                        "source, %d in the output" % (what, ref.tool, len(ua), len(ub)))


def merge_capacity(ref, got, k):
    caps = (ref.capacity.get(k), got.capacity.get(k))
    if "f4~" in caps:
        return "f4~"
    if "f4" in caps or _float32_values(ref.fields.get(k)):
        # The source's values are float32 (a PCD's F 4, read into doubles by Open3D): written as
        # text in their shortest float32 spelling they read back, in a double reader, as another
        # double of the same float32. The information is the float32: compared as such.
        return "f4"
    return "f8"


def _float32_values(values):
    """Whether every value of a float array is a float32 (NaNs included)."""
    if values is None:
        return False
    a = np.asarray(values)
    if a.dtype.kind != "f" or a.size == 0:
        return False
    if a.dtype == np.float32:
        return True
    with np.errstate(over="ignore", invalid="ignore"):
        back = a.astype(np.float32).astype(a.dtype)
    return bool(((back == a) | (np.isnan(a) & np.isnan(back))).all())


def compare_triangles(ref, got, problems):
    """STL on either side: the same triangles (positions in float32, STL's type), welded or not,
    in any order; against a points-only output, the same set of distinct positions."""
    a_xyz = np.asarray(ref.fields["xyz"]).astype(np.float32)
    b_xyz = np.asarray(got.fields["xyz"]).astype(np.float32)
    cap = "f4~" if "f4~" in (ref.capacity.get("xyz"), got.capacity.get("xyz")) else "f4"
    if ref.faces and got.faces:
        a, b = triangle_set(a_xyz, ref.faces), triangle_set(b_xyz, got.faces)
        what = "triangles"
    else:
        a = _sorted_rows(np.unique(a_xyz.astype(np.float64), axis=0))
        b = _sorted_rows(np.unique(b_xyz.astype(np.float64), axis=0))
        what = "distinct positions"
    if a.shape != b.shape:
        problems.append("%d %s in the source, %d in the output" % (len(a), what, len(b)))
        return
    bad = np.flatnonzero(rows_differ(a, b, cap))
    if len(bad):
        problems.append("%d of %d %s differ (float32%s, sorted; as %s reads them); first: %s -> %s" % (
            len(bad), len(a), what, " within one ulp" if cap == "f4~" else "", ref.tool, a[bad[0]].tolist(),
            b[bad[0]].tolist()))


def _without_nan_points(reading):
    """The reading without its points whose position is NaN (a copy; itself if it has none)."""
    if "xyz" not in reading.fields or reading.faces:
        return reading
    keep = ~np.isnan(np.asarray(reading.fields["xyz"], dtype=np.float64)).any(axis=1)
    if keep.all():
        return reading
    out = Reading(reading.tool, reading.path)
    out.command, out.capacity, out.unordered = reading.command, dict(reading.capacity), reading.unordered
    for k, v in reading.fields.items():
        out.add(k, np.asarray(v)[keep], reading.names[k])
    return out


def compare(ref, got, expect, own_format, problems, faces_held=True, capacity_override=None, ignore=()):
    """Appends to `problems` every difference between what a tool saw in the source (`ref`) and in
    the output (`got`), for the keys in `expect` (the keys the output's format holds and the tool
    reads; None: all of ref's). Values are compared bit for bit, at the precision of the reader
    (float32 where either reading went through a float32-only reader)."""
    keys = [k for k in ref.fields if (expect is None or k in expect or (k.startswith("_") and own_format))]
    keys = [k for k in keys if not (k.startswith("_") and not own_format)]
    paired_keys = keys  # CloudCompare's unnamed columns are paired in column order, ignored ones too
    keys = [k for k in keys if k not in ignore]
    capacity = {k: merge_capacity(ref, got, k) for k in keys}
    capacity.update({k: c for k, c in (capacity_override or {}).items() if k in capacity})
    want_faces = faces_held and (expect is None or "faces" in expect) and bool(ref.faces)
    if ref.unordered or got.unordered:
        present = [k for k in keys if k in got.fields]
        for k in keys:
            if k not in got.fields:
                problems.append("%s (%s) is missing in the output as %s reads it; it sees: %s" % (
                    ref.names[k], k, ref.tool, got.describe()))
        if ref.n != got.n and not want_faces:
            problems.append("%d points in the source, %d in the output" % (ref.n, got.n))
        compare_unordered(ref, got, present, capacity, want_faces, problems)
        return
    if ref.n != got.n:
        # An organized scan's NaN points ("no return" pixels) are placeholders: a reader that
        # drops them in one file (CloudCompare in a PLY's range grid) and keeps them in another
        # (an XYZ's nan rows) sees the same points.
        ref, got = _without_nan_points(ref), _without_nan_points(got)
    if ref.n != got.n:
        problems.append("%d points in the source, %d in the output" % (ref.n, got.n))
        return
    # At a NaN point the other values are no data either (PCL fills a no-return pixel's floats
    # with NaN, its packed rgb too, where a PLY's uchar colours hold 0): compared at points only.
    rows = None
    if "xyz" in ref.fields and "xyz" in got.fields:
        nan_a = np.isnan(np.asarray(ref.fields["xyz"], dtype=np.float64)).any(axis=1)
        nan_b = np.isnan(np.asarray(got.fields["xyz"], dtype=np.float64)).any(axis=1)
        if (nan_a & nan_b).any():
            rows = np.flatnonzero(~(nan_a & nan_b))
    if own_format and ref.width is not None and (ref.width, ref.height) != (got.width, got.height):
        problems.append("organized %dx%d in the source, %sx%s in the output" % (ref.width, ref.height, got.width, got.height))
    unnamed = cloudcompare_unnamed(ref, got, paired_keys)
    for k in keys:
        if k in unnamed:
            compare_values(k, ref.fields[k], got.fields[unnamed[k]], ref.names[k],
                           got.names[unnamed[k]] + " (CloudCompare's name for an ASCII column it does not name)",
                           problems, ref.tool, rows=rows, capacity=capacity[k])
            continue
        if k not in got.fields:
            problems.append("%s (%s) is missing in the output as %s reads it; it sees: %s" % (
                ref.names[k], k, ref.tool, got.describe()))
            continue
        compare_values(k, ref.fields[k], got.fields[k], ref.names[k], got.names[k], problems, ref.tool,
                       rows=None if k == "xyz" else rows, capacity=capacity[k])
    if "alpha" in got.fields and "alpha" not in ref.fields and "rgb" in ref.fields:
        alpha = np.asarray(got.fields["alpha"])
        opaque = 1.0 if alpha.dtype.kind == "f" else 255
        if (alpha != opaque).any():
            problems.append("an alpha channel was added (%s), %d points not opaque (e.g. %s), where the source has "
                            "colour without alpha (%s)" % (got.names["alpha"], int((alpha != opaque).sum()),
                                                          alpha[alpha != opaque][0], ref.names["rgb"]))
    if want_faces:
        if not got.faces:
            problems.append("the %d faces are missing in the output" % len(ref.faces))
        elif list(map(tuple, ref.faces)) != list(map(tuple, got.faces)):
            a, b = list(map(tuple, ref.faces)), list(map(tuple, got.faces))
            first = next((i for i, (x, y) in enumerate(zip(a, b)) if x != y), min(len(a), len(b)))
            problems.append("faces differ: %d in the source, %d in the output; first difference at face %d: %s -> %s" % (
                len(a), len(b), first, a[first] if first < len(a) else None, b[first] if first < len(b) else None))
