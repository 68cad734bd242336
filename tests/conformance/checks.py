"""The three checks of every source file, shared by the writers' test modules:

- `check_python_reads`: hgdeform.read (the Python module) reads the source as its writer does;
- `check_roundtrip`: hgdeform deform with a move that moves nothing, written as OUTPUT; a tool
  that reads both formats (the writer when it can) sees the same values, bit for bit, in every
  field the output's format holds;
- `check_move`: a real move (the far end dragged, the near end fixed), in the source's own
  format, read by its writer: the handle moved, the fixed end bit-identical, normals turned with
  the handle, every other field unchanged.
"""

import pathlib
import threading

import numpy as np
import pytest

import cases as cs
import conformance_lib as lib

MESH_EXTS = ("ply", "obj", "off", "stl")
CLOUD_EXTS = ("ply", "pcd", "xyz", "txt", "xyzn", "xyzrgb", "pts", "asc")


def _mode(case, target):
    return "mesh" if case.mesh and target in MESH_EXTS else "cloud"


def reads(tool, case, target):
    """Can `tool` read the source and the output `target` the same way?"""
    src, mode = case.ext, _mode(case, target)
    if tool == "pcl":
        return src in lib.PCL_READS and target in lib.PCL_READS
    if tool == "open3d":
        if mode == "mesh":
            return src in MESH_EXTS and target in MESH_EXTS
        # read_point_cloud picks its reader by the extension: no .txt or .asc
        o3d_cloud = ("ply", "pcd", "xyz", "xyzn", "xyzrgb", "pts")
        return src in o3d_cloud and target in o3d_cloud
    if tool == "cloudcompare":
        if mode == "mesh":
            # CloudCompare 2.11 reads plain OFF only ("malformed file" for COFF/NOFF/CNOFF): it judges
            # OFF files only as the writer of a plain OFF (its own), and OFF outputs only of those.
            if "off" in (src, target) and not (case.writer == "cloudcompare" and src == "off"):
                return False
            return src in MESH_EXTS and target in MESH_EXTS
        # CloudCompare reads an XYZ row of nan as the point (0, 0, 0) but leaves a PLY range
        # grid's empty pixels out: the XYZ of such a PLY (its no-return pixels as nan rows) is
        # judged by another reader.
        if case.range_grid and target in ("xyz", "txt"):
            return False
        return (not case.mesh) and src in ("ply", "xyz", "txt", "asc") and target in ("ply", "xyz", "txt")
    if tool == "meshlab":
        # meshlabserver 2020.09 (Debian) cannot read any OBJ, not even its own or a one-triangle file:
        # vcg's import_obj.h:640 asserts (numTriangles + numVertices) == numVerticesPlusFaces + extraTriangles
        # and the process aborts. Its OBJ files are judged by another reader.
        ok = ("ply", "off", "stl")
        return src in ok and target in ok
    if tool == "hgdeform":
        return True
    return False


def reader_for(case, target):
    """The tool that judges this output: the writer when it reads the output's format, else the
    first of PCL, CloudCompare, Open3D, MeshLab that reads both formats, else hgdeform's own
    Python reader (a self-check, named so in the test's id)."""
    for tool in (case.writer, "pcl", "cloudcompare", "open3d", "meshlab", "hgdeform"):
        if reads(tool, case, target):
            return tool
    return "hgdeform"


def open3d_format(case, target, role):
    if role == "source":
        return case.open3d_format
    if cs.FAMILY[target] == "xyz":
        if case.family == "xyz" and case.ext != "pts":
            return case.open3d_format
        return "xyz"
    return "auto"


def expected(tool, case, target):
    """The keys the output's format holds as `tool` reads it (None: every key of the source's
    reading). 'faces' stands for the polygons."""
    fam = cs.FAMILY[target]
    if tool == "pcl":
        return None
    if tool == "open3d":
        if fam == "xyz":
            return {"xyz": {"xyz"}, "xyzn": {"xyz", "normal"}, "xyzrgb": {"xyz", "rgb"}}.get(
                open3d_format(case, target, "output"), {"xyz"})
        return {"xyz", "normal", "rgb", "faces"}
    if tool == "cloudcompare":
        # CloudCompare 2.11 loads an OBJ's 'vn' as per-triangle normals, which its PLY export (how
        # the suite sees what it read) leaves out: OBJ normals are judged by Open3D's reader.
        return {"obj": {"xyz", "faces"}, "off": {"xyz", "faces"}}.get(fam)
    if tool == "meshlab":
        return {"obj": {"xyz", "normal", "rgb", "alpha", "faces"},
                "off": {"xyz", "normal", "rgb", "alpha", "faces"}}.get(fam)
    if tool == "hgdeform":
        return {"obj": {"xyz", "normal", "rgb", "alpha", "faces"},
                "off": {"xyz", "normal", "rgb", "alpha", "faces"}}.get(fam)
    return None


# ----------------------------------------------------------------------------------------------
# Session state: sources made once, readings cached

class Session:
    def __init__(self, root):
        self.root = pathlib.Path(root)
        self.sources = {}
        self.readings = {}
        self.lock = threading.Lock()
        self.scenarios = {
            "rest": lib.scenario_file(self.root, "rest", lib.REST),
            "identity": lib.scenario_file(self.root, "identity", lib.IDENTITY),
            "drag": lib.scenario_file(self.root, "drag", lib.DRAG),
        }

    def dir(self, *parts):
        d = self.root.joinpath(*parts)
        d.mkdir(parents=True, exist_ok=True)
        return d

    def source(self, case):
        """The source file, made by its writer (once). A writer that cannot run: skip, or fail in CI."""
        if case.id not in self.sources:
            try:
                self.sources[case.id] = ("ok", case.make(self.dir("sources")))
            except lib.ToolUnavailable as e:
                self.sources[case.id] = ("unavailable", str(e))
            except cs.WriterFailure as e:
                self.sources[case.id] = ("failed", str(e))
        state, value = self.sources[case.id]
        if state == "unavailable":
            lib.unavailable("%s cannot write %s: %s" % (case.writer, case.id, value))
        if state == "failed":
            pytest.fail("the writer failed to make the source file (a problem of the suite or of %s, not of "
                        "hgdeform): %s" % (case.writer, value), pytrace=False)
        return value

    def read(self, tool, path, case, target, role):
        """What `tool` sees in `path` (the source or an output), cached. A tool that cannot run:
        skip, or fail in CI. A tool that cannot read the file: the test fails with its message."""
        mode = _mode(case, target)
        fmt = open3d_format(case, target, role) if tool == "open3d" else None
        key = (tool, str(path), mode, fmt)
        if key not in self.readings:
            try:
                self.readings[key] = self._read(tool, pathlib.Path(path), mode, fmt)
            except lib.ToolUnavailable as e:
                self.readings[key] = ("unavailable", str(e))
            except lib.ReadFailure as e:
                self.readings[key] = ("failed", str(e))
        r = self.readings[key]
        if isinstance(r, tuple):
            if r[0] == "unavailable":
                lib.unavailable("%s is needed to read %s back: %s" % (tool, path, r[1]))
            pytest.fail("%s cannot read %s %s: %s" % (tool, role, path, r[1]), pytrace=False)
        return r

    def _read(self, tool, path, mode, fmt):
        if tool == "pcl":
            return lib.pcl_read(path)
        if tool == "open3d":
            return lib.open3d_read(path, mesh=(mode == "mesh"), fmt=fmt)
        if tool == "cloudcompare":
            given = lib.cc_scalar_named_ply(path, self.dir("cc_named"))
            r = lib.cloudcompare_read([given], mode == "mesh", self.dir("cc_reads"))[given]
            if isinstance(r, Exception):
                raise r
            return r
        if tool == "meshlab":
            return lib.meshlab_read(path, self.dir("ml_reads"))
        if tool == "hgdeform":
            return hgdeform_reading(path)
        raise AssertionError(tool)


def hgdeform_reading(path):
    s = lib.hgdeform_read(path)
    rd = lib.Reading("hgdeform", path)
    rd.command = "hgdeform.read(%r)" % str(path)
    rd.add("xyz", np.asarray(s.points), "points")
    if s.normals is not None:
        rd.add("normal", np.asarray(s.normals), "normals")
    fields = dict(s.fields)
    if s.normals is None:
        lower = {n.lower(): n for n in fields}
        if {"nx", "ny", "nz"} <= set(lower):
            rd.add("normal", np.stack([fields.pop(lower[c]) for c in ("nx", "ny", "nz")], axis=1).astype(np.float64),
                   "%s %s %s (fields)" % tuple(lower[c] for c in ("nx", "ny", "nz")))
    if {"red", "green", "blue"} <= set(fields):
        rd.add("rgb", np.stack([fields.pop("red"), fields.pop("green"), fields.pop("blue")], axis=1), "red green blue")
        if "alpha" in fields:
            rd.add("alpha", fields.pop("alpha"), "alpha")
    for packed in ("rgb", "rgba"):
        if packed in fields:
            v = np.asarray(fields.pop(packed))
            bits = v.view("<u4") if v.dtype.itemsize == 4 else v.astype("<u4")
            rd.add("rgb", np.stack([(bits >> 16) & 255, (bits >> 8) & 255, bits & 255], axis=1).astype(np.uint8), packed)
            if packed == "rgba":
                rd.add("alpha", ((bits >> 24) & 255).astype(np.uint8), packed)
            break
    for name, v in fields.items():
        rd.add(lib.canonical(name), np.asarray(v), name)
    faces = s.faces
    if faces is not None and len(faces):
        rd.faces = [tuple(int(i) for i in f) for f in faces]
    rd.width, rd.height = s.width, s.height
    return rd


# ----------------------------------------------------------------------------------------------
# The checks

def roundtrip_params(case_list):
    params = []
    for case in case_list:
        for label, ext, ascii in case.outputs():
            tool = reader_for(case, ext)
            cid = "%s-to-%s" % (case.id, label)
            if tool != case.writer:
                cid += "-read_by_" + tool
            params.append(pytest.param(case, label, ext, ascii, tool, id=cid))
    return params


def _geometry_mode(case, target):
    return "stl" in (case.ext, target)


def _context(case, src, out, cmd, tool, ref, got):
    return ("\n  source: %s (written by %s)\n  hgdeform: %s\n  read by %s: %s\n             %s" % (
        src, case.writer, cmd, tool, ref.command or "", got.command or ""))


def own_output(case):
    """(label, extension, --ascii) of the output in the source's own format and encoding."""
    ext = {"xyzn": "xyz", "xyzrgb": "xyz", "pts": "xyz", "asc": "txt"}.get(case.ext, case.ext)
    ascii = case.ascii and ext in ("ply", "pcd", "stl")
    return ext + ("-ascii" if ascii else ""), ext, ascii


def check_identity(session, case):
    """A move that moves nothing (a frame motion of zero), in the source's own format: read by its
    writer (or, where it cannot read that format, as reader_for picks), nothing may differ (README: a point whose clusters do not move is not rewritten)."""
    label, ext, ascii = own_output(case)
    check_roundtrip(session, case, label, ext, ascii, reader_for(case, ext), scenario="identity")


def check_roundtrip(session, case, label, ext, ascii, tool, scenario="rest"):
    src = session.source(case)
    out = session.dir("outputs" if scenario == "rest" else "outputs_" + scenario, case.id) / ("%s.%s" % (label, ext))
    cmd, stderr = lib.run_hgdeform(src, out, session.scenarios[scenario], ascii=ascii)
    if tool == "open3d" and ext == "pcd":
        limit = lib.open3d_binary_f8_limit(out)
        if limit:
            pytest.xfail(limit)
    ref = session.read(tool, src, case, ext, "source")
    got = session.read(tool, out, case, ext, "output")
    problems = []
    own = case.family == cs.FAMILY[ext]
    if _geometry_mode(case, ext):
        lib.compare_triangles(ref, got, problems)
    else:
        # 0..1 colours become 0..255 in a PLY or OFF of another format's source (README).
        quantised = {"rgb": "u8"} if ext in ("ply", "off") and not own else None
        # CloudCompare 2.11 reads an ASCII column named intensity as a grey colour (all 0 for
        # values that are not bytes), even in the file of its own ASCII export of an intensity
        # field: it cannot judge that column of an XYZ/TXT output.
        ignore = ("intensity",) if tool == "cloudcompare" and ext in ("xyz", "txt") else ()
        lib.compare(ref, got, expected(tool, case, ext), own, problems, faces_held=ext in MESH_EXTS,
                    capacity_override=quantised, ignore=ignore)
    if problems:
        pytest.fail("%s -> %s%s: %s%s\n  hgdeform stderr: %s" % (
            case.id, label, " (%s scenario)" % scenario, "\n  ".join(problems), _context(case, src, out, cmd, tool, ref, got),
            stderr.strip().replace("\n", "\n    ") or "(none)"), pytrace=False)


def check_python_reads(session, case):
    src = session.source(case)
    try:
        shape = lib.hgdeform_read(src)
    except lib.ToolUnavailable as e:
        lib.unavailable(str(e))
    except lib.ReadFailure as e:
        pytest.fail(str(e), pytrace=False)
    tool = reader_for(case, case.ext)
    ref = session.read(tool, src, case, case.ext, "source")
    pts = np.asarray(shape.points, dtype=np.float64)
    want = np.asarray(ref.fields["xyz"], dtype=np.float64)
    if case.ext == "stl" or ref.unordered:
        a = lib._sorted_rows(np.unique(want.astype(np.float32), axis=0))
        b = lib._sorted_rows(np.unique(pts.astype(np.float32), axis=0))
        cap = "f4~" if ref.unordered else "f4"
        assert a.shape == b.shape and not lib.rows_differ(a, b, cap).any(), \
            "hgdeform.read(%s): %d distinct positions, %s sees %d (or other ones)" % (src, len(b), tool, len(a))
        return
    assert len(pts) == len(want), "hgdeform.read(%s): %d points, %s reads %d" % (src, len(pts), tool, len(want))
    finite = np.isfinite(want).all(axis=1)
    assert (np.isfinite(pts).all(axis=1) == finite).all(), "hgdeform.read(%s): NaN points not where %s has them" % (
        src, tool)
    # At the reader's precision: float32 readers (CloudCompare, MeshLab, Open3D's OFF) see text as
    # float32, hgdeform as double. Equal values (a reader may read "-0.00000000" as +0).
    if ref.capacity.get("xyz") in ("f4", "f4~"):
        pts, want = pts.astype(np.float32), want.astype(np.float32)
    bad = np.flatnonzero(finite & (pts != want).any(axis=1))
    assert not len(bad), "hgdeform.read(%s): %d positions differ from %s's, e.g. point %d: %r -> %r" % (
        src, len(bad), tool, bad[0], want[bad[0]].tolist(), pts[bad[0]].tolist())


def _kabsch(a, b):
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    h = (a - ca).T @ (b - cb)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T))
    return vt.T @ np.diag([1, 1, d]) @ u.T


def check_move(session, case):
    """The drag, written in the source's own format, read by the writer."""
    src = session.source(case)
    _, ext, ascii = own_output(case)
    out = session.dir("moves", case.id) / ("moved.%s" % ext)
    cmd, stderr = lib.run_hgdeform(src, out, session.scenarios["drag"], ascii=ascii)
    tool = case.writer
    ref = session.read(tool, src, case, ext, "source")
    got = session.read(tool, out, case, ext, "output")
    ctx = _context(case, src, out, cmd, tool, ref, got)
    problems = []
    if ref.n != got.n:
        pytest.fail("%d points in the source, %d after the move%s" % (ref.n, got.n, ctx), pytrace=False)
    p0 = np.asarray(ref.fields["xyz"], dtype=np.float64)
    p1 = np.asarray(got.fields["xyz"], dtype=np.float64)
    finite = np.isfinite(p0).all(axis=1)
    if (np.isfinite(p1).all(axis=1) != finite).any():
        problems.append("%d points are NaN after the move where the source's are not, or the reverse" % int(
            (np.isfinite(p1).all(axis=1) != finite).sum()))
    fixed = np.flatnonzero(finite & (p0[:, 0] <= 1.0))
    handle = np.flatnonzero(finite & (p0[:, 0] >= 9.0))
    keys = expected(tool, case, ext)
    keys = [k for k in ref.fields if (keys is None or k in keys) and not k.startswith("_")]
    cap = {k: lib.merge_capacity(ref, got, k) for k in keys}
    # the fixed end: every value bit-identical
    for k in keys:
        if k not in got.fields:
            problems.append("%s is missing after the move; %s sees %s" % (ref.names[k], tool, got.describe()))
            continue
        lib.compare_values(k, ref.fields[k], got.fields[k], ref.names[k] + " (fixed end)", got.names[k],
                           problems, tool, rows=fixed, capacity=cap[k])
    # every value other than positions and normals: unchanged everywhere
    for k in keys:
        if k in ("xyz", "normal") or k not in got.fields:
            continue
        lib.compare_values(k, ref.fields[k], got.fields[k], ref.names[k] + " (all points)", got.names[k],
                           problems, tool, capacity=cap[k])
    # the handle: moved
    d = np.linalg.norm(p1[handle] - p0[handle], axis=1)
    if len(handle) == 0:
        problems.append("no point in the handle region (x >= 9): the suite's shape is wrong")
    elif (d < 0.5).any():
        problems.append("%d of %d handle points moved less than 0.5 (min %g, max %g): the move is not seen" % (
            int((d < 0.5).sum()), len(handle), d.min(), d.max()))
    # normals: turned with the handle (the rotation that best maps the handle's points)
    if "normal" in keys and "normal" in got.fields and len(handle) >= 3:
        n0 = np.asarray(ref.fields["normal"], dtype=np.float64)[handle]
        n1 = np.asarray(got.fields["normal"], dtype=np.float64)[handle]
        rot = _kabsch(p0[handle], p1[handle])
        turn = np.degrees(np.arccos(np.clip((np.trace(rot) - 1) / 2, -1, 1)))
        pred = n0 @ rot.T
        cosang = np.einsum("ij,ij->i", pred, n1) / (np.linalg.norm(pred, axis=1) * np.linalg.norm(n1, axis=1))
        ang = np.degrees(np.arccos(np.clip(cosang, -1, 1)))
        seen = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", n0, n1) / (
            np.linalg.norm(n0, axis=1) * np.linalg.norm(n1, axis=1)), -1, 1)))
        if turn < 2.0:
            problems.append("the handle turned by only %.2f degrees: the scenario does not test normals" % turn)
        elif np.median(seen) < 0.5 * turn:
            problems.append("normals did not turn: the handle turned %.1f degrees, its normals by a median %.2f" % (
                turn, np.median(seen)))
        elif np.percentile(ang, 95) > 3.0:
            problems.append("normals turned wrongly: 95%% within %.2f degrees of the handle's rotation (%.1f)" % (
                np.percentile(ang, 95), turn))
    if problems:
        pytest.fail("%s moved: %s%s\n  hgdeform stderr: %s" % (case.id, "\n  ".join(problems), ctx,
                                                              stderr.strip().replace("\n", "\n    ") or "(none)"),
                    pytrace=False)


# ----------------------------------------------------------------------------------------------
# The four tests of a writer's module


def writer_tests(case_list, move_names):
    """The test functions of one writer's module (test_writer_<writer>.py): every source read by
    hgdeform.read, written back in every format, moved by zero, and (`move_names`) dragged."""
    moves = [c for c in case_list if c.name in move_names]

    @pytest.mark.parametrize("case", case_list, ids=lambda c: c.id)
    def test_python_reads(session, case):
        check_python_reads(session, case)

    @pytest.mark.parametrize("case,label,ext,ascii,tool", roundtrip_params(case_list))
    def test_roundtrip(session, case, label, ext, ascii, tool):
        check_roundtrip(session, case, label, ext, ascii, tool)

    @pytest.mark.parametrize("case", case_list, ids=lambda c: c.id)
    def test_identity_move(session, case):
        check_identity(session, case)

    @pytest.mark.parametrize("case", moves, ids=lambda c: c.id)
    def test_move(session, case):
        check_move(session, case)

    return test_python_reads, test_roundtrip, test_identity_move, test_move
