// OBJ reading and writing: 'v' and 'f' lines, per-vertex colours, and every other line
// (texture coordinates, normals, groups, materials, face corners) kept to be written back.
// Normals ('vn') are paired with the vertices that faces give them, or, in a point cloud
// without faces and with one 'vn' per 'v', by order.
#include <algorithm>
#include <charconv>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "io/internal.h"

namespace hgd::io_internal {

Shape readObj(const std::string& path) {
  InputFile in(path);
  Lexer lex(in.rest(), 0);
  std::vector<double> xyz, rgb;
  bool all_rgb = true;
  Shape shape;
  struct PendingIndex {
    std::size_t line;
    long long value;
  };
  PendingIndex worst{0, 0};             // the largest positive index, checked once all vertices are known
  std::vector<std::string_view> lines;  // every line, kept when the file has more than v and f
  bool extras = false;
  DecimalsSeen decimals;  // of x, y, z, for writing the values back as spelt
  std::vector<Eigen::Vector3f> normals;
  std::vector<int> normal_vertex;
  std::vector<std::pair<long long, long long>> corner_normals;  // (vertex, normal) of each v//vn corner
  bool corners_without_normal = false;
  while (lex.nextLine()) {
    lines.push_back(lex.lineText());
    if (lex.peek() == '#') {
      extras = true;
      continue;
    }
    const std::string_view kw = lex.token();
    if (kw == "v") {
      double vals[7];
      std::size_t n = 0;
      for (std::string_view tok = lex.token(); !tok.empty(); tok = lex.token()) {
        double v = 0;
        if (!parseFloating(tok, &v))
          fail(path, "non-numeric value " + excerpt(tok) + " at line " + num(lex.line()));
        if (n < 3) decimals.see(n, tok);
        if (n < 7) vals[n] = v;
        ++n;
      }
      if (n < 3)
        fail(path,
             "malformed data: line " + num(lex.line()) + ": a vertex needs 3 coordinates, found " + num(n));
      xyz.insert(xyz.end(), vals, vals + 3);
      if (n != 3 && n != 6) extras = true;  // a weight (x y z w), or more: kept with the lines
      if (n == 6)
        rgb.insert(rgb.end(), vals + 3, vals + 6);
      else
        all_rgb = false;
    } else if (kw == "f") {
      pcl::Vertices poly;
      for (std::string_view tok = lex.token(); !tok.empty(); tok = lex.token()) {
        const std::string_view head = tok.substr(0, tok.find('/'));
        if (head.size() != tok.size()) extras = true;  // v/vt/vn corners: kept as written
        long long v = 0;
        const auto r = std::from_chars(head.data(), head.data() + head.size(), v);
        const std::size_t nv = xyz.size() / 3;
        if (r.ec != std::errc() || r.ptr != head.data() + head.size() || v == 0 ||
            (v < 0 && v < -static_cast<long long>(nv)) || v > std::numeric_limits<pcl::index_t>::max())
          fail(path, "bad face index " + excerpt(tok) + " at line " + num(lex.line()) + " (" + num(nv) +
                         " vertices so far)");
        const long long idx = v > 0 ? v - 1 : static_cast<long long>(nv) + v;
        if (v > 0 && v > worst.value) worst = {lex.line(), v};
        poly.vertices.push_back(static_cast<pcl::index_t>(idx));
        // The corner's normal (v/vt/vn or v//vn): the first vertex it is paired with turns it.
        const auto s2 = head.size() < tok.size() ? tok.find('/', head.size() + 1) : std::string_view::npos;
        if (s2 != std::string_view::npos) {
          const std::string_view vn = tok.substr(s2 + 1);
          long long k = 0;
          const auto rk = std::from_chars(vn.data(), vn.data() + vn.size(), k);
          const long long nn = static_cast<long long>(normals.size());
          const long long j = k > 0 ? k - 1 : nn + k;
          if (rk.ec == std::errc() && k != 0 && j >= 0 && j < nn) {
            if (normal_vertex[static_cast<std::size_t>(j)] < 0)
              normal_vertex[static_cast<std::size_t>(j)] = static_cast<int>(idx);
            corner_normals.emplace_back(idx, j);
          } else {
            corners_without_normal = true;
          }
        } else {
          corners_without_normal = true;
        }
      }
      if (poly.vertices.size() < 3)
        fail(path, "bad face: line " + num(lex.line()) + " has " + num(poly.vertices.size()) +
                       " vertices, at least 3 needed");
      shape.polygons.push_back(std::move(poly));
    } else {
      // vn, vt, vp, o, g, s, l, usemtl, mtllib and anything else: kept as lines (FileExtras);
      // normals are also read, to be turned with the shape.
      extras = true;
      if (kw == "vn") {
        float vals[3] = {0, 0, 0};
        for (float& v : vals) {
          double d = 0;
          const std::string_view tok = lex.token();
          if (!parseFloating(tok, &d))
            fail(path,
                 "non-numeric value " + excerpt(tok) + " at line " + num(lex.line()) + " (a 'vn' line)");
          v = static_cast<float>(d);
        }
        normals.emplace_back(vals[0], vals[1], vals[2]);
        normal_vertex.push_back(-1);
      }
    }
  }
  const std::size_t nverts = xyz.size() / 3;
  if (nverts == 0) fail(path, "no points: the file has no 'v' lines");
  // Colours on some vertices only: not fields of the cloud, but kept with the lines.
  if (!rgb.empty() && !all_rgb) extras = true;
  if (static_cast<unsigned long long>(worst.value) > nverts)
    fail(path, "bad face index " + std::to_string(worst.value) + " at line " + num(worst.line) + " (" +
                   num(nverts) + " vertices)");
  if (nverts > std::numeric_limits<std::uint32_t>::max())
    fail(path, "unsupported: more than 4294967295 vertices");
  // A point cloud (no faces) with one 'vn' per 'v': the k-th normal is the k-th vertex's, as
  // MeshLab and CloudCompare read it, so that it turns with the shape as a mesh's does.
  if (shape.polygons.empty() && normals.size() == nverts)
    for (std::size_t k = 0; k < nverts; ++k) normal_vertex[k] = static_cast<int>(k);

  // Vertex normals: when every vertex has one 'vn' (each of its face corners names the same
  // one, or, in a cloud, one per 'v' in order), they are also the cloud's nx/ny/nz, as Open3D,
  // MeshLab and CloudCompare read them, so that a conversion keeps them. Otherwise (normals per
  // corner, or on some vertices only) they stay with the lines, kept when writing OBJ.
  std::vector<long long> vertex_normal;
  if (shape.polygons.empty() && normals.size() == nverts) {
    vertex_normal.resize(nverts);
    for (std::size_t k = 0; k < nverts; ++k) vertex_normal[k] = static_cast<long long>(k);
  } else if (!shape.polygons.empty() && !corners_without_normal && !corner_normals.empty()) {
    vertex_normal.assign(nverts, -1);
    for (const auto& [v, j] : corner_normals) {
      long long& slot = vertex_normal[static_cast<std::size_t>(v)];
      if (slot >= 0 && slot != j) {
        vertex_normal.clear();
        break;
      }
      slot = j;
    }
    if (std::find(vertex_normal.begin(), vertex_normal.end(), -1) != vertex_normal.end())
      vertex_normal.clear();
  }

  // x/y/z as doubles (as written), colours and normals as floats.
  const bool colour = all_rgb && rgb.size() == xyz.size();
  const bool vnormals = !vertex_normal.empty();
  std::vector<std::pair<std::string, std::uint8_t>> fields = {
      {"x", Field::FLOAT64}, {"y", Field::FLOAT64}, {"z", Field::FLOAT64}};
  if (!colour && !vnormals) {
    shape.cloud = makeCloud(nverts, fields, xyz);
  } else {
    if (vnormals)
      for (const char* c : {"nx", "ny", "nz"}) fields.emplace_back(c, Field::FLOAT32);
    if (colour)
      for (const char* c : {"red", "green", "blue"}) fields.emplace_back(c, Field::FLOAT32);
    const std::size_t w = fields.size();
    std::vector<double> values(nverts * w);
    for (std::size_t i = 0; i < nverts; ++i) {
      double* row = values.data() + w * i;
      std::size_t k = 0;
      for (std::size_t a = 0; a < 3; ++a) row[k++] = xyz[3 * i + a];
      if (vnormals)
        for (std::size_t a = 0; a < 3; ++a)
          row[k++] = normals[static_cast<std::size_t>(vertex_normal[i])][static_cast<Eigen::Index>(a)];
      if (colour)
        for (std::size_t a = 0; a < 3; ++a) row[k++] = rgb[3 * i + a];
    }
    shape.cloud = makeCloud(nverts, fields, values);
  }
  decimals.store(shape.extras, {"x", "y", "z"});
  if (extras) {
    shape.extras.obj_lines.assign(lines.begin(), lines.end());
    shape.extras.obj_normals = std::move(normals);
    shape.extras.obj_normal_vertex = std::move(normal_vertex);
  }
  return shape;
}

namespace {

/// " x y z" of the point at `pt`, each at its declared type (an OBJ vertex's coordinates).
void appendXyz(std::string& buf, const pcl::PCLPointCloud2& c, std::size_t i, const XyzFields& xyz,
               const std::vector<FileExtras::TextColumn>& decimals) {
  const std::uint8_t* pt = c.data.data() + i * c.point_step;
  const std::size_t n = static_cast<std::size_t>(c.width) * c.height;
  const int idx[3] = {xyz.x, xyz.y, xyz.z};
  for (int a = 0; a < 3; ++a) {
    buf += ' ';
    int dec = 0;
    bool exp = false;
    rowSpelling(decimals[static_cast<std::size_t>(a)], i, n, &dec, &exp);
    appendValue(buf, pt + c.fields[idx[a]].offset, c.fields[idx[a]].datatype, dec, exp);
  }
}

std::vector<FileExtras::TextColumn> xyzDecimals(const Shape& shape, const XyzFields& xyz) {
  const auto& f = shape.cloud.fields;
  return decimalsOf(shape.extras, {&f[xyz.x], &f[xyz.y], &f[xyz.z]});
}

/// An OBJ is text, but a reader that knows formats by their content takes any file of a binary
/// STL's size for one (84 + 50 n bytes with n in bytes 80-83; hgdeform's own does, unless the
/// text says OBJ before its first byte that is not text, and a kept statement can hold any
/// bytes). One more line end, which every OBJ reader skips, makes the size another.
void padPastBinaryStlSize(AtomicWriter& w) {
  if (w.hasBinaryStlSize()) w.write("\n");
}

/// An OBJ written line by line as it was read: 'v' lines with the cloud's x/y/z (the rest of
/// the line, colours or a weight, as it was), 'vn' lines with the turned normals, every other
/// line (vt, g, o, usemtl, mtllib, s, l, comments, faces with their v/vt/vn corners) unchanged.
bool writeObjLines(const std::string& path, const Shape& shape, const XyzFields& xyz) {
  const FileExtras& x = shape.extras;
  const std::vector<Eigen::Vector3f>& vn = x.obj_normals_out.empty() ? x.obj_normals : x.obj_normals_out;
  std::size_t nv = 0, nn = 0;
  for (const auto& line : x.obj_lines) {
    nv += line.rfind("v ", 0) == 0 || line.rfind("v\t", 0) == 0;
    nn += line.rfind("vn ", 0) == 0 || line.rfind("vn\t", 0) == 0;
  }
  if (nv != shape.size() || nn != vn.size()) return false;  // the shape no longer fits its lines
  const pcl::PCLPointCloud2& c = shape.cloud;
  AtomicWriter w(path);
  std::string buf;
  std::size_t i = 0, j = 0;
  const std::vector<FileExtras::TextColumn> decimals = xyzDecimals(shape, xyz);
  for (const auto& line : x.obj_lines) {
    const std::vector<std::string_view> words = splitWords(line);
    if (!words.empty() && words[0] == "v") {
      buf += 'v';
      appendXyz(buf, c, i++, xyz, decimals);
      for (std::size_t k = 4; k < words.size(); ++k) {
        buf += ' ';
        buf += words[k];
      }
    } else if (!words.empty() && words[0] == "vn") {
      buf += "vn";
      for (int a = 0; a < 3; ++a) {
        buf += ' ';
        appendFloat(buf, vn[j][a]);
      }
      ++j;
    } else {
      buf += line;
    }
    buf += '\n';
    flushIfFull(w, buf);
  }
  w.write(buf);
  padPastBinaryStlSize(w);
  w.commit();
  return true;
}

}  // namespace

void writeObj(const std::string& path, const Shape& shape) {
  checkShape(path, shape, false);
  const pcl::PCLPointCloud2& c = shape.cloud;
  const XyzFields xyz = findXyzFields(c);
  if (!xyz.hasXyz()) fail(path, "cannot write: no x/y/z fields");
  if (!shape.extras.obj_lines.empty() && writeObjLines(path, shape, xyz)) return;
  const int r = findField(c, "red"), g = findField(c, "green"), b = findField(c, "blue");
  const bool colour = r >= 0 && g >= 0 && b >= 0;
  const std::size_t n = shape.size();
  // Per-vertex normals as one 'vn' per 'v', in order, and faces that name them ("f a//a b//b"):
  // what Open3D, CloudCompare and MeshLab write and read as vertex normals.
  const bool normals = xyz.hasNormals();

  AtomicWriter w(path);
  std::string buf = "# written by hgdeform\n";
  const std::vector<FileExtras::TextColumn> decimals = xyzDecimals(shape, xyz);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* pt = c.data.data() + i * c.point_step;
    buf += 'v';
    appendXyz(buf, c, i, xyz, decimals);
    if (colour) {
      for (const int idx : {r, g, b}) {
        const Field& f = c.fields[idx];
        buf += ' ';
        if (f.datatype == Field::FLOAT32 || f.datatype == Field::FLOAT64)
          appendValue(buf, pt + f.offset, f.datatype);
        else
          appendFloat(buf, static_cast<float>(readValue(c, i, f) / 255.0));
      }
    }
    buf += '\n';
    if (normals) {
      buf += "vn";
      for (const int idx : {xyz.nx, xyz.ny, xyz.nz}) {
        const Field& f = c.fields[static_cast<std::size_t>(idx)];
        buf += ' ';
        appendValue(buf, pt + f.offset, f.datatype);
      }
      buf += '\n';
    }
    flushIfFull(w, buf);
  }
  for (const auto& poly : shape.polygons) {
    buf += 'f';
    for (const auto idx : poly.vertices) {
      buf += ' ';
      appendInt(buf, static_cast<long long>(idx) + 1);
      if (normals) {
        buf += "//";
        appendInt(buf, static_cast<long long>(idx) + 1);
      }
    }
    buf += '\n';
    flushIfFull(w, buf);
  }
  w.write(buf);
  padPastBinaryStlSize(w);
  w.commit();
}

}  // namespace hgd::io_internal

namespace hgd {

void turnObjNormals(FileExtras& extras,
                    const std::function<bool(int vertex, Eigen::Quaterniond& rotation)>& turn) {
  extras.obj_normals_out = extras.obj_normals;
  if (!turn) return;
  Eigen::Quaterniond q;
  for (std::size_t j = 0; j < extras.obj_normals.size() && j < extras.obj_normal_vertex.size(); ++j)
    if (turn(extras.obj_normal_vertex[j], q))
      extras.obj_normals_out[j] = (q * extras.obj_normals[j].cast<double>()).cast<float>();
}

}  // namespace hgd
