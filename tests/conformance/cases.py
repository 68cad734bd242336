"""The files of the suite, each written at test time by a third-party tool (PCL, Open3D,
CloudCompare, MeshLab), and which formats each is converted to.

Every shape is a tube along x from 0 to 10 (radius about 1, a little radial noise), so that the
scenarios of conformance_lib (the end x < 1 fixed, the end x > 9 the handle) fit all of them.
Clouds have about 2000 points in random order; meshes 2000 vertices (shuffled) and 3960 triangles.
"""

import pathlib
import shutil
import subprocess

import numpy as np

import conformance_lib as lib

CLOUD_TARGETS = ("ply", "pcd", "xyz")
MESH_TARGETS = ("ply", "pcd", "xyz", "obj", "off", "stl")
# The family of an extension: an output "in the source's own format" is one of the same family.
FAMILY = {"pcd": "pcd", "ply": "ply", "xyz": "xyz", "txt": "xyz", "xyzn": "xyz", "xyzrgb": "xyz",
          "pts": "xyz", "asc": "xyz", "obj": "obj", "off": "off", "stl": "stl"}


class Case:
    """One source file: `writer` wrote it (`make(dir)` returns its path, raising
    lib.ToolUnavailable when the writer cannot run); `ext` its extension, `ascii` whether it is
    text, `mesh` whether it has faces; `open3d_format` the format Open3D reads it with."""

    def __init__(self, writer, name, ext, make, ascii=False, mesh=False, open3d_format="auto", range_grid=False):
        self.writer, self.name, self.ext, self.make = writer, name, ext, make
        self.ascii, self.mesh, self.open3d_format = ascii, mesh, open3d_format
        self.range_grid = range_grid  # a PLY holding PCL's organized layout (NaN pixels not in the vertices)

    @property
    def id(self):
        return "%s-%s" % (self.writer, self.name)

    @property
    def family(self):
        return FAMILY[self.ext]

    def outputs(self):
        """(label, extension, --ascii) of every output hgdeform writes for this source: each of
        its formats (points-only formats for clouds), and the own format as the source is
        encoded (ascii sources also with --ascii; an .xyzn/.pts/... source as .xyz, a .txt as .txt)."""
        out = [(t, t, False) for t in (MESH_TARGETS if self.mesh else CLOUD_TARGETS)]
        if self.ext == "txt":
            out.append(("txt", "txt", False))
        if self.ascii and self.ext in ("ply", "pcd", "stl"):
            out.append((self.ext + "-ascii", self.ext, True))
        return out

    def __repr__(self):
        return self.id


# ----------------------------------------------------------------------------------------------
# Shapes (numpy, deterministic)

def tube_cloud(n=2000, seed=11):
    """Points on a tube along x (0..10, radius 1 +- 0.01), random order: positions (float64),
    outward normals, colours as 0..255 integers, and an intensity."""
    rng = np.random.default_rng(seed)
    t = rng.uniform(0.0, 10.0, n)
    a = rng.uniform(0.0, 2 * np.pi, n)
    r = 1.0 + rng.uniform(-0.01, 0.01, n)
    xyz = np.stack([t, r * np.cos(a), r * np.sin(a)], axis=1)
    normals = np.stack([np.zeros(n), np.cos(a), np.sin(a)], axis=1)
    rgb = np.stack([np.round(t * 25.5), np.round(127.5 + 127.5 * np.cos(a)),
                    (np.floor(t * 37) + 11) % 256], axis=1).astype(np.uint8)
    intensity = (100.0 + 90.0 * t + 7.25 * np.sin(5 * a)).astype(np.float32)
    return xyz, normals, rgb, intensity


def tube_mesh(nu=100, nv=20, seed=12):
    """A triangulated tube along x (0..10): vertices (shuffled, radial noise), outward normals,
    colours, triangles facing out."""
    rng = np.random.default_rng(seed)
    u = np.linspace(0.0, 10.0, nu)
    a = np.linspace(0.0, 2 * np.pi, nv, endpoint=False)
    uu, aa = np.meshgrid(u, a, indexing="ij")
    uu, aa = uu.ravel(), aa.ravel()
    r = 1.0 + rng.uniform(-0.01, 0.01, uu.size)
    xyz = np.stack([uu, r * np.cos(aa), r * np.sin(aa)], axis=1)
    normals = np.stack([np.zeros(uu.size), np.cos(aa), np.sin(aa)], axis=1)
    rgb = np.stack([np.round(uu * 25.5), np.round(127.5 + 127.5 * np.cos(aa)),
                    np.full(uu.size, 40)], axis=1).astype(np.uint8)
    faces = []
    for i in range(nu - 1):
        for j in range(nv):
            p, q = i * nv + j, i * nv + (j + 1) % nv
            faces.append([p, q, p + nv])
            faces.append([q, q + nv, p + nv])
    faces = np.array(faces, dtype=np.int64)
    # outward: (q - p) x (p+nv - p) points along +radial for this winding? check and flip
    e1 = xyz[faces[:, 1]] - xyz[faces[:, 0]]
    e2 = xyz[faces[:, 2]] - xyz[faces[:, 0]]
    fn = np.cross(e1, e2)
    centre = xyz[faces].mean(axis=1)
    radial = centre.copy()
    radial[:, 0] = 0
    if (np.einsum("ij,ij->i", fn, radial) < 0).mean() > 0.5:
        faces = faces[:, [0, 2, 1]]
    perm = rng.permutation(len(xyz))            # new order: vertex perm[k] becomes k
    inv = np.empty_like(perm)
    inv[perm] = np.arange(len(perm))
    return xyz[perm], normals[perm], rgb[perm], inv[faces]


def write_ply(path, columns, faces=None, ascii=False):
    """A PLY of the given (name, array) columns (dtype kept) and triangles."""
    names = {"f4": "float", "f8": "double", "u1": "uchar", "i4": "int", "u4": "uint"}
    n = len(columns[0][1])
    header = ["ply", "format %s 1.0" % ("ascii" if ascii else "binary_little_endian"), "element vertex %d" % n]
    header += ["property %s %s" % (names[np.asarray(v).dtype.str[1:]], name) for name, v in columns]
    if faces is not None:
        header += ["element face %d" % len(faces), "property list uchar int vertex_indices"]
    header.append("end_header")
    with open(path, "wb") as f:
        f.write(("\n".join(header) + "\n").encode())
        if ascii:
            rows = []
            for i in range(n):
                rows.append(" ".join(repr(float(v[i])) if np.asarray(v).dtype.kind == "f" else str(int(v[i]))
                                     for _, v in columns))
            f.write(("\n".join(rows) + "\n").encode())
            if faces is not None:
                f.write(("\n".join("3 %d %d %d" % tuple(t) for t in faces) + "\n").encode())
        else:
            dt = np.dtype([(name, "<" + np.asarray(v).dtype.str[1:]) for name, v in columns])
            rec = np.empty(n, dt)
            for name, v in columns:
                rec[name] = v
            f.write(rec.tobytes())
            if faces is not None:
                tri = np.empty(len(faces), dtype=[("k", "u1"), ("v", "<i4", (3,))])
                tri["k"] = 3
                tri["v"] = faces
                f.write(tri.tobytes())


# ----------------------------------------------------------------------------------------------
# PCL: tests/conformance/pcl_probe (savePCDFile*, PLYWriter) and the pcl_* converters

PCL_TYPES = ("xyz", "xyzi", "xyzrgb", "xyzrgbnormal", "pointnormal", "organized")


def _pcl_write(type_, encoding, ext):
    def make(d):
        out = pathlib.Path(d) / ("pcl_%s_%s.%s" % (type_, encoding, ext))
        if not out.exists():
            _run([lib.pcl_probe(), "write", type_, encoding, out], "pcl_probe")
        return out
    return make


def _pcl_tool(name):
    exe = shutil.which(name)
    if not exe:
        raise lib.ToolUnavailable("%s is not installed (package pcl-tools)" % name)
    return exe


def _run(args, what):
    args = [str(a) for a in args]
    r = subprocess.run(args, capture_output=True, text=True, timeout=300)
    if r.returncode != 0:
        raise WriterFailure("%s failed (exit %d): %s\n%s" % (what, r.returncode, lib.tool_cmd(*args),
                                                             (r.stdout + r.stderr).strip()[-2000:]))
    return r


class WriterFailure(Exception):
    pass


def _pcl_convert(kind, name, src_type, src_enc, src_ext, args_before, ext, args_after=()):
    def make(d):
        src = _pcl_write(src_type, src_enc, src_ext)(d)
        out = pathlib.Path(d) / ("pcl_%s.%s" % (name, ext))
        if not out.exists():
            _run([_pcl_tool(kind)] + list(args_before) + [src, out] + list(args_after), kind)
        return out
    return make


def _pcl_chain(name, src_type, args):
    """PLYWriter (binary) -> pcl_ply2pcd (binary) -> pcl_pcd2ply ARGS."""
    def make(d):
        pcd = _pcl_convert("pcl_ply2pcd", "ply2pcd_for_%s" % name, src_type, "binary", "ply", ["-format", "1"], "pcd")(d)
        out = pathlib.Path(d) / ("pcl_%s.ply" % name)
        if not out.exists():
            _run([_pcl_tool("pcl_pcd2ply")] + list(args) + [pcd, out], "pcl_pcd2ply")
        return out
    return make


def pcl_cases():
    cases = []
    for t in PCL_TYPES:
        for enc in ("ascii", "binary", "binary_compressed"):
            cases.append(Case("pcl", "pcd_%s_%s" % (enc, t), "pcd", _pcl_write(t, enc, "pcd"), ascii=enc == "ascii"))
        for enc in ("ascii", "binary"):
            cases.append(Case("pcl", "ply_%s_%s" % (enc, t), "ply", _pcl_write(t, enc, "ply"), ascii=enc == "ascii"))
    cases += [
        Case("pcl", "pcl_ply2pcd_binary", "pcd",
             _pcl_convert("pcl_ply2pcd", "ply2pcd_binary", "xyzrgbnormal", "binary", "ply", ["-format", "1"], "pcd")),
        Case("pcl", "pcl_ply2pcd_ascii", "pcd",
             _pcl_convert("pcl_ply2pcd", "ply2pcd_ascii", "xyzi", "ascii", "ply", ["-format", "0"], "pcd"), ascii=True),
        # pcl_pcd2ply is given PCDs that pcl_ply2pcd made (rgb of TYPE F): from a PCD that PCL 1.13's
        # savePCDFile wrote (rgb of TYPE U) it writes PLYs that PCL itself cannot read (the packed
        # value in place of red green blue in ascii; a corrupt camera element in binary).
        Case("pcl", "pcl_pcd2ply_ascii_organized", "ply",
             _pcl_chain("pcd2ply_ascii_organized", "organized", ["-format", "0", "-use_camera", "0"]), ascii=True,
             range_grid=True),
        Case("pcl", "pcl_pcd2ply_binary_camera", "ply",
             _pcl_chain("pcd2ply_binary_camera", "xyzrgbnormal", ["-format", "1", "-use_camera", "1"])),
        Case("pcl", "pcl_convert_to_compressed_organized", "pcd",
             _pcl_convert("pcl_convert_pcd_ascii_binary", "convert_compressed_organized", "organized", "ascii", "pcd",
                          [], "pcd", ["2"])),
        Case("pcl", "pcl_convert_to_ascii_xyzrgb", "pcd",
             _pcl_convert("pcl_convert_pcd_ascii_binary", "convert_ascii_xyzrgb", "xyzrgb", "binary", "pcd",
                          [], "pcd", ["0"]), ascii=True),
    ]
    return cases


# ----------------------------------------------------------------------------------------------
# Open3D: write_point_cloud / write_triangle_mesh

def _open3d_cloud(ext, ascii=False, compressed=False, with_normals=True, with_colors=True):
    def make(d):
        o3d = lib.open3d()
        out = pathlib.Path(d) / ("o3d_cloud_%s%s%s.%s" % ("ascii" if ascii else "binary",
                                                         "_compressed" if compressed else "", "", ext))
        if not out.exists():
            xyz, normals, rgb, _ = tube_cloud(seed=21)
            pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(xyz))
            if with_normals:
                pc.normals = o3d.utility.Vector3dVector(normals)
            if with_colors:
                pc.colors = o3d.utility.Vector3dVector(rgb.astype(np.float64) / 255.0)
            if not o3d.io.write_point_cloud(str(out), pc, write_ascii=ascii, compressed=compressed):
                raise WriterFailure("open3d.io.write_point_cloud(%r, write_ascii=%r, compressed=%r) returned False"
                                    % (str(out), ascii, compressed))
        return out
    return make


def _open3d_mesh(ext, ascii=False):
    def make(d):
        o3d = lib.open3d()
        out = pathlib.Path(d) / ("o3d_mesh_%s.%s" % ("ascii" if ascii else "binary", ext))
        if not out.exists():
            xyz, normals, rgb, faces = tube_mesh(seed=22)
            m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(xyz), o3d.utility.Vector3iVector(faces.astype(np.int32)))
            m.vertex_normals = o3d.utility.Vector3dVector(normals)
            m.vertex_colors = o3d.utility.Vector3dVector(rgb.astype(np.float64) / 255.0)
            if ext == "stl":
                m.compute_triangle_normals()  # Open3D's STL writer refuses a mesh without them
            if not o3d.io.write_triangle_mesh(str(out), m, write_ascii=ascii):
                raise WriterFailure("open3d.io.write_triangle_mesh(%r, write_ascii=%r) returned False" % (str(out), ascii))
        return out
    return make


def open3d_cases():
    return [
        Case("open3d", "cloud_ply_binary", "ply", _open3d_cloud("ply")),
        Case("open3d", "cloud_ply_ascii", "ply", _open3d_cloud("ply", ascii=True), ascii=True),
        Case("open3d", "cloud_pcd_binary", "pcd", _open3d_cloud("pcd")),
        Case("open3d", "cloud_pcd_ascii", "pcd", _open3d_cloud("pcd", ascii=True), ascii=True),
        Case("open3d", "cloud_pcd_compressed", "pcd", _open3d_cloud("pcd", compressed=True)),
        Case("open3d", "cloud_xyz", "xyz", _open3d_cloud("xyz"), ascii=True, open3d_format="xyz"),
        Case("open3d", "cloud_xyzn", "xyzn", _open3d_cloud("xyzn"), ascii=True, open3d_format="xyzn"),
        Case("open3d", "cloud_xyzrgb", "xyzrgb", _open3d_cloud("xyzrgb", with_normals=False), ascii=True,
             open3d_format="xyzrgb"),
        Case("open3d", "cloud_pts", "pts", _open3d_cloud("pts", with_normals=False), ascii=True, open3d_format="pts"),
        Case("open3d", "mesh_ply_binary", "ply", _open3d_mesh("ply"), mesh=True),
        Case("open3d", "mesh_ply_ascii", "ply", _open3d_mesh("ply", ascii=True), ascii=True, mesh=True),
        Case("open3d", "mesh_obj", "obj", _open3d_mesh("obj"), ascii=True, mesh=True),
        Case("open3d", "mesh_off", "off", _open3d_mesh("off"), ascii=True, mesh=True),
        Case("open3d", "mesh_stl_binary", "stl", _open3d_mesh("stl"), mesh=True),
    ]


# ----------------------------------------------------------------------------------------------
# CloudCompare: command line, from a PLY of ours (CloudCompare loads it, then writes)

def _cc_input(d, mesh):
    """The PLY CloudCompare loads: float x y z, nx ny nz, uchar colours, scalar_Intensity (float)
    and scalar_GpsTime (double, about 1634567890.123456); a mesh has triangles too."""
    path = pathlib.Path(d) / ("cc_input_%s.ply" % ("mesh" if mesh else "cloud"))
    if not path.exists():
        if mesh:
            xyz, normals, rgb, faces = tube_mesh(seed=31)
            intensity = (100.0 + 9.0 * xyz[:, 0]).astype(np.float32)
        else:
            xyz, normals, rgb, intensity = tube_cloud(seed=31)
            faces = None
        n = len(xyz)
        gps = 1634567890.123456 + np.arange(n) * 0.000731
        cols = [("x", xyz[:, 0].astype(np.float32)), ("y", xyz[:, 1].astype(np.float32)),
                ("z", xyz[:, 2].astype(np.float32)), ("nx", normals[:, 0].astype(np.float32)),
                ("ny", normals[:, 1].astype(np.float32)), ("nz", normals[:, 2].astype(np.float32)),
                ("red", rgb[:, 0]), ("green", rgb[:, 1]), ("blue", rgb[:, 2]),
                ("scalar_Intensity", intensity.astype(np.float32)), ("scalar_GpsTime", gps.astype(np.float64))]
        write_ply(path, cols, faces)
    return path


def _cc(name, mesh, args, ext):
    def make(d):
        out = pathlib.Path(d) / ("cc_%s.%s" % (name, ext))
        if not out.exists():
            src = _cc_input(d, mesh)
            save = ["-SAVE_MESHES" if mesh else "-SAVE_CLOUDS", "FILE", str(out)]
            try:
                lib.cloudcompare("-O", str(src), *args, *save, expect=[out])
            except lib.ReadFailure as e:
                raise WriterFailure(str(e))
        return out
    return make


def cloudcompare_cases():
    return [
        Case("cloudcompare", "cloud_ply_binary", "ply",
             _cc("cloud_ply_binary", False, ["-C_EXPORT_FMT", "PLY", "-PLY_EXPORT_FMT", "BINARY_LE"], "ply")),
        Case("cloudcompare", "cloud_ply_ascii", "ply",
             _cc("cloud_ply_ascii", False, ["-C_EXPORT_FMT", "PLY", "-PLY_EXPORT_FMT", "ASCII"], "ply"), ascii=True),
        Case("cloudcompare", "cloud_asc_header_txt", "txt",
             _cc("cloud_asc_header", False, ["-C_EXPORT_FMT", "ASC", "-ADD_HEADER", "-PREC", "12"], "txt"),
             ascii=True),
        Case("cloudcompare", "cloud_asc_header_comma_txt", "txt",
             _cc("cloud_asc_header_comma", False, ["-C_EXPORT_FMT", "ASC", "-SEP", "COMMA", "-ADD_HEADER",
                                                   "-PREC", "12"], "txt"), ascii=True),
        Case("cloudcompare", "mesh_ply_binary", "ply",
             _cc("mesh_ply_binary", True, ["-M_EXPORT_FMT", "PLY", "-PLY_EXPORT_FMT", "BINARY_LE"], "ply"), mesh=True),
        Case("cloudcompare", "mesh_obj", "obj", _cc("mesh_obj", True, ["-M_EXPORT_FMT", "OBJ"], "obj"),
             ascii=True, mesh=True),
        Case("cloudcompare", "mesh_off", "off", _cc("mesh_off", True, ["-M_EXPORT_FMT", "OFF"], "off"),
             ascii=True, mesh=True),
        Case("cloudcompare", "mesh_stl", "stl", _cc("mesh_stl", True, ["-M_EXPORT_FMT", "STL"], "stl"), mesh=True),
    ]


# ----------------------------------------------------------------------------------------------
# MeshLab: meshlabserver, a filter script (normals, quality from a function, colours from it)

MLX = """<!DOCTYPE FilterScript>
<FilterScript>
 <filter name="Re-Compute Vertex Normals">
  <Param type="RichEnum" value="1" name="weightMode" enum_val0="None (avg)" enum_val1="By Angle" enum_val2="By Area" enum_val3="As defined by N. Max" enum_cardinality="4"/>
 </filter>
 <filter name="Per Vertex Quality Function">
  <Param type="RichString" value="x*x/7+3*y+z/3" name="q"/>
  <Param type="RichBool" value="false" name="normalize"/>
  <Param type="RichBool" value="true" name="map"/>
  <Param type="RichBool" value="false" name="onselected"/>
 </filter>
</FilterScript>
"""


def _ml(name, ext, mask):
    def make(d):
        d = pathlib.Path(d)
        out = d / ("ml_%s.%s" % (name, ext))
        if not out.exists():
            src = d / "ml_input.ply"
            if not src.exists():
                xyz, _, _, faces = tube_mesh(seed=41)
                write_ply(src, [("x", xyz[:, 0].astype(np.float32)), ("y", xyz[:, 1].astype(np.float32)),
                                ("z", xyz[:, 2].astype(np.float32))], faces)
            script = d / "ml_script.mlx"
            script.write_text(MLX)
            try:
                lib.meshlab("-i", str(src), "-s", str(script), "-o", str(out), "-m", *mask, expect=[out])
            except lib.ReadFailure as e:
                raise WriterFailure(str(e))
        return out
    return make


def meshlab_cases():
    return [
        Case("meshlab", "ply_binary", "ply", _ml("ply_binary", "ply", ["vc", "vn", "vq"]), mesh=True),
        Case("meshlab", "ply_ascii", "ply", _ml("ply_ascii", "ply", ["vc", "vn", "vq", "sa"]), ascii=True, mesh=True),
        Case("meshlab", "obj", "obj", _ml("obj", "obj", ["vc", "vn"]), ascii=True, mesh=True),
        Case("meshlab", "off", "off", _ml("off", "off", ["vc", "vn"]), ascii=True, mesh=True),
        Case("meshlab", "stl_binary", "stl", _ml("stl_binary", "stl", ["vn"]), mesh=True),
        Case("meshlab", "stl_ascii", "stl", _ml("stl_ascii", "stl", ["vn", "sa"]), ascii=True, mesh=True),
    ]
