#!/usr/bin/env python3
"""Writes the fuzzers' seed corpus (fuzz/corpus/<target>/): small valid and near-valid files.

Run from anywhere: python3 fuzz/make_corpus.py. The files are committed; rerun only to change them.
"""
import json
import math
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))


def out(target, name, data):
    d = os.path.join(HERE, "corpus", target)
    os.makedirs(d, exist_ok=True)
    if isinstance(data, str):
        data = data.encode("utf-8")
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


PTS = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 1.0, 0.0), (0.0, 1.0, 0.0), (0.5, 0.5, 1.0)]
NRM = [(0.0, 0.0, 1.0)] * 5
FACES = [(0, 1, 2), (0, 2, 3), (0, 1, 4, 3)]

# --- PLY -----------------------------------------------------------------------------------


def ply_header(fmt, n, props, faces=0, extra=""):
    h = "ply\nformat %s 1.0\ncomment seed\nelement vertex %d\n" % (fmt, n)
    h += "".join("property %s %s\n" % p for p in props)
    if faces:
        h += "element face %d\nproperty list uchar int vertex_indices\n" % faces
    return h + extra + "end_header\n"


xyz = [("float", "x"), ("float", "y"), ("float", "z")]
out("ply", "ascii_cloud.ply",
    ply_header("ascii", 5, xyz) + "".join("%g %g %g\n" % p for p in PTS))
out("ply", "ascii_mesh.ply",
    ply_header("ascii", 5, xyz + [("uchar", "red")], faces=3) +
    "".join("%g %g %g 200\n" % p for p in PTS) +
    "".join("%d %s\n" % (len(f), " ".join(map(str, f))) for f in FACES))
body = b"".join(struct.pack("<6f", *p, *n) for p, n in zip(PTS, NRM))
out("ply", "binary_le_normals.ply",
    ply_header("binary_little_endian", 5, xyz + [("float", "nx"), ("float", "ny"), ("float", "nz")]).encode() + body)
body = b"".join(struct.pack(">3d", *p) for p in PTS)
body += b"".join(struct.pack(">B", len(f)) + struct.pack(">%di" % len(f), *f) for f in FACES)
out("ply", "binary_be_double_mesh.ply",
    ply_header("binary_big_endian", 5, [("double", "x"), ("double", "y"), ("double", "z")], faces=3).encode() + body)
body = b"".join(struct.pack("<3f", *p) for p in PTS)
out("ply", "binary_extra_element.ply",
    ply_header("binary_little_endian", 5, xyz,
               extra="element edge 1\nproperty int vertex1\nproperty int vertex2\n").encode() +
    body + struct.pack("<2i", 0, 1))
out("ply", "ascii_nan.ply", ply_header("ascii", 3, xyz) + "nan 0 0\n1 inf 0\n0 1 0\n")
out("ply", "truncated.ply", ply_header("ascii", 5, xyz) + "0 0 0\n1 0")
out("ply", "crlf.ply", (ply_header("ascii", 2, [("float32", "x"), ("float32", "y"), ("float32", "z")]) +
                        "1 2 3\n4 5 6\n").replace("\n", "\r\n"))

# --- PCD -----------------------------------------------------------------------------------


def pcd_header(fields, size, typ, count, width, height, data):
    return ("# .PCD v0.7\nVERSION 0.7\nFIELDS %s\nSIZE %s\nTYPE %s\nCOUNT %s\nWIDTH %d\nHEIGHT %d\n"
            "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS %d\nDATA %s\n" %
            (fields, size, typ, count, width, height, width * height, data))


out("pcd", "ascii.pcd", pcd_header("x y z", "4 4 4", "F F F", "1 1 1", 5, 1, "ascii") +
    "".join("%g %g %g\n" % p for p in PTS))
out("pcd", "binary_rgb.pcd", pcd_header("x y z rgb", "4 4 4 4", "F F F U", "1 1 1 1", 5, 1, "binary").encode() +
    b"".join(struct.pack("<3fI", *p, 0xff8040) for p in PTS))
out("pcd", "organized_nan.pcd", pcd_header("x y z", "4 4 4", "F F F", "1 1 1", 3, 2, "binary").encode() +
    b"".join(struct.pack("<3f", *p) for p in PTS) + struct.pack("<3f", math.nan, math.nan, math.nan))
out("pcd", "padding.pcd", pcd_header("x y z _ intensity", "4 4 4 1 2", "F F F U U", "1 1 1 4 1", 2, 1,
                                     "ascii") + "1 2 3 7\n4 5 6 8\n")
out("pcd", "double_count.pcd", pcd_header("x y z normal", "8 8 8 4", "F F F F", "1 1 1 3", 2, 1, "binary").encode() +
    struct.pack("<3d3f", 1, 2, 3, 0, 0, 1) + struct.pack("<3d3f", 4, 5, 6, 0, 1, 0))


def lzf_literals(raw):
    """LZF stream of literal runs only (what the decoder must accept)."""
    o = bytearray()
    for i in range(0, len(raw), 32):
        chunk = raw[i:i + 32]
        o.append(len(chunk) - 1)
        o += chunk
    return bytes(o)


soa = b"".join(struct.pack("<5f", *[p[k] for p in PTS]) for k in range(3))
comp = lzf_literals(soa)
out("pcd", "compressed.pcd", pcd_header("x y z", "4 4 4", "F F F", "1 1 1", 5, 1, "binary_compressed").encode() +
    struct.pack("<2I", len(comp), len(soa)) + comp)
# A back reference: 8 zero bytes as one literal then a copy of length 7 + 2 from offset 1.
zeros = bytes([0, 0]) + bytes([(7 << 5) | 0, 0])
out("pcd", "compressed_backref.pcd",
    pcd_header("x y", "4 4", "F F", "1 1", 1, 1, "binary_compressed").encode() +
    struct.pack("<2I", len(zeros), 8) + zeros)
out("pcd", "old_columns.pcd", "COLUMNS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n")
out("pcd", "truncated.pcd", pcd_header("x y z", "4 4 4", "F F F", "1 1 1", 5, 1, "binary").encode() + b"\0" * 17)

# --- OBJ -----------------------------------------------------------------------------------

out("obj", "mesh.obj", "# seed\nmtllib a.mtl\no thing\n" + "".join("v %g %g %g\n" % p for p in PTS) +
    "vn 0 0 1\nvt 0 0\ng g1\nusemtl m\ns 1\nf 1 2 3\nf 1/1 3/1 4/1\nf 1//1 2//1 5//1 4//1\nl 1 2\n")
out("obj", "colours.obj", "".join("v %g %g %g 0.5 0.25 1\n" % p for p in PTS) + "f -3 -2 -1\n")
out("obj", "cloud.obj", "v 1 2 3\nv 4 5 6\nv nan 0 0\nv 7 8 9 1.0\n")
out("obj", "bad_face.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n")

# --- XYZ, OFF, STL ----------------------------------------------------------------------------

out("xyz", "plain.xyz", "# seed\n" + "".join("%g %g %g\n" % p for p in PTS))
out("xyz", "normals.xyz", "".join("%g,%g,%g,%g,%g,%g\n" % (p + n) for p, n in zip(PTS, NRM)))
out("xyz", "header.xyz", "//X Y Z intensity\n\n" + "".join("%g %g %g 7\n" % p for p in PTS))
out("xyz", "ragged.xyz", "1 2 3\n4 5 6 7\n")
out("off", "mesh.off", "OFF\n# seed\n%d %d 0\n" % (len(PTS), len(FACES)) + "".join("%g %g %g\n" % p for p in PTS) +
    "".join("%d %s\n" % (len(f), " ".join(map(str, f))) for f in FACES))
out("off", "cnoff.off", "CNOFF %d 1 0\n" % len(PTS) +
    "".join("%g %g %g %g %g %g 255 0 0 255\n" % (p + n) for p, n in zip(PTS, NRM)) + "3 0 1 2 1 0 0\n")
out("off", "truncated.off", "OFF\n5 2 0\n0 0 0\n1 0 0\n")
TRIS = [(PTS[a], PTS[b], PTS[c]) for a, b, c in [(0, 1, 2), (0, 2, 3), (0, 1, 4)]]
out("stl", "ascii.stl", "solid seed\n" + "".join(
    "facet normal 0 0 1\nouter loop\n" + "".join("vertex %g %g %g\n" % v for v in t) + "endloop\nendfacet\n"
    for t in TRIS) + "endsolid seed\n")
out("stl", "binary.stl", b" " * 80 + struct.pack("<I", len(TRIS)) + b"".join(
    struct.pack("<3f", 0, 0, 1) + b"".join(struct.pack("<3f", *v) for v in t) + struct.pack("<H", 0) for t in TRIS))
out("stl", "bad_count.stl", b" " * 80 + struct.pack("<I", 9) + b"\0" * 50)

# --- PTS (Leica) ------------------------------------------------------------------------------

out("pts", "plain.pts", "5\n" + "".join("%g %g %g\n" % p for p in PTS))
out("pts", "intensity_rgb.pts", "5\n" + "".join("%g %g %g -1200 10 200 30\n" % p for p in PTS))
out("pts", "intensity.pts", "5\n" + "".join("%g %g %g 17\n" % p for p in PTS))
out("pts", "count_wrong.pts", "9\n1 2 3\n4 5 6\n")
out("pts", "no_count.pts", "1 2 3\n4 5 6\n")

# --- LAS -----------------------------------------------------------------------------------


def las_file(minor, fmt, rec_len, points, vlrs=b"", nvlr=0, evlrs=b"", nevlr=0):
    """An ASPRS LAS file: 1.<minor> header, the VLR bytes, the point records, the EVLR bytes."""
    hsize = {0: 227, 1: 227, 2: 227, 3: 235, 4: 375}[minor]
    offset = hsize + len(vlrs)
    n = len(points) // rec_len
    h = b"LASF" + struct.pack("<HH", 7, 0) + b"\0" * 16 + struct.pack("<BB", 1, minor)
    h += b"seed".ljust(32, b"\0") + b"make_corpus.py".ljust(32, b"\0") + struct.pack("<HH", 1, 2026)
    h += struct.pack("<HIIBH", hsize, offset, nvlr, fmt, rec_len)
    h += struct.pack("<I", n if fmt < 6 else 0) + struct.pack("<5I", n, 0, 0, 0, 0)
    h += struct.pack("<3d", 0.01, 0.01, 0.01) + struct.pack("<3d", 100.0, 200.0, 0.0)
    h += struct.pack("<6d", 101.0, 100.0, 201.0, 200.0, 1.0, 0.0)
    if minor >= 3:
        h += struct.pack("<Q", 0)
    if minor >= 4:
        h += struct.pack("<QI", offset + len(points) if nevlr else 0, nevlr)
        h += struct.pack("<Q", n) + struct.pack("<15Q", n, *([0] * 14))
    assert len(h) == hsize
    return h + vlrs + points + evlrs


def vlr(user, rid, data, desc=b"seed"):
    return struct.pack("<H", 0) + user.ljust(16, b"\0") + struct.pack("<HH", rid, len(data)) + desc.ljust(
        32, b"\0") + data


def ints(p):
    return struct.pack("<3i", int(p[0] * 100), int(p[1] * 100), int(p[2] * 100))


# format 0 (1.0), format 3 (1.2, GPS time and RGB), format 1 with a truncated record block
f0 = b"".join(ints(p) + struct.pack("<HBBbBH", 10 * i, 0x09, 2, -5, 1, 7) for i, p in enumerate(PTS))
out("las", "format0_v10.las", las_file(0, 0, 20, f0))
f3 = b"".join(ints(p) + struct.pack("<HBBbBHd3H", i, 0x11, 5, 3, 0, 1, 1e5 + i, 65535, i, 0)
              for i, p in enumerate(PTS))
out("las", "format3_v12.las", las_file(2, 3, 34, f3, vlr(b"LASF_Projection", 34735, struct.pack("<8H", 1, 1, 0, 1,
                                                                                                  1024, 0, 1, 1)), 1))
out("las", "truncated.las", las_file(2, 1, 28, f0[:40] + b"\0" * 16)[:-10])
# format 6 (1.4) with two extra bytes (a scaled short), its descriptor VLR and a WKT EVLR
eb = struct.pack("<2sBB32s4s", b"\0\0", 4, 0x08, b"height".ljust(32, b"\0"), b"\0" * 4) + b"\0" * 72
eb += struct.pack("<d", 0.1) + b"\0" * 16 + b"\0" * 24 + b"above ground".ljust(32, b"\0")
assert len(eb) == 192
f6 = b"".join(ints(p) + struct.pack("<HBBBBhHd", 3, 0x11, 0x40, 2, 0, -100, 4, 1e6 + i) + struct.pack("<h", i)
              for i, p in enumerate(PTS))
wkt = b'LOCAL_CS["seed"]\0'
evlr = struct.pack("<H", 0) + b"LASF_Projection".ljust(16, b"\0") + struct.pack("<HQ", 2112, len(wkt)) + b"wkt".ljust(
    32, b"\0") + wkt
out("las", "format6_extra_v14.las", las_file(4, 6, 32, f6, vlr(b"LASF_Spec", 4, eb), 1, evlr, 1))

# --- scenario --------------------------------------------------------------------------------

F = "hgdeform-scenario/1"
sc = [
    {"format": F, "fixed": [{"box": {"min": [-1, -1, -1], "max": [0.1, 1, 1]}}],
     "manipulated": {"box": {"min": [0.9, -1, -1], "max": [2, 1, 1]}},
     "move": {"frame": {"translate": [0, 0.2, 0]}}},
    {"fixed": [{"sphere": {"center": [0, 0, 0], "radius": 0.1}}, {"indices": [1, 2, 3]}],
     "manipulated": {"sphere": {"center": [1, 0, 0], "radius": 0.1}}, "clusters": 8,
     "move": {"drag": {"from": [1, 0, 0], "to": [1, 0.3, 0]}}},
    {"fixed": [{"indices": [0]}], "manipulated": {"indices": [9, 10]},
     "joints": [{"sphere": {"center": [0.5, 0, 0], "radius": 0.05}}],
     "move": [{"frame": {"rotate": {"axis": [0, 0, 1], "degrees": 30, "center": [0, 0, 0]}}},
              {"frame": {"translate": [1, 2, 3], "rotate": {"axis": [1, 0, 0], "degrees": -10}}},
              [{"drag": {"from": [0, 0, 0], "to": [1, 1, 1]}}]]},
    {"fixed": [{"box": {"min": [0, 0, 0], "max": [1e6, 1e6, 1e6]}}], "manipulated": {"indices": [5]}},
]
for i, s in enumerate(sc):
    out("scenario", "valid%d.json" % i, json.dumps(s, indent=1))
out("scenario", "unknown_key.json", '{"fixed": [{"indices": [0]}], "manipulated": {"indices": [1]}, "fixd": 1}')
out("scenario", "bad_radius.json",
    '{"fixed": [{"sphere": {"center": [0, 0, 0], "radius": -1}}], "manipulated": {"indices": [1]}}')
out("scenario", "truncated.json", '{"fixed": [{"indices": [0, 1')
out("scenario", "overflow.json", '{"fixed": [{"indices": [1e400]}], "manipulated": {"indices": [1]}}')
