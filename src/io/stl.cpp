// STL meshes, ascii ("solid" ... "endsolid") and binary (an 80-byte header, a triangle count,
// 50 bytes per triangle). Corners at exactly the same position are welded into one vertex so
// that the mesh is connected; facet normals are not kept (written ones are computed from the
// triangle), nor are binary attribute bytes (a warning says so when any is not zero).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <unordered_map>
#include <vector>

#include "io/internal.h"

namespace hgd::io_internal {
namespace {

using Key = std::array<std::uint32_t, 3>;
struct KeyHash {
  std::size_t operator()(const Key& k) const {
    std::uint64_t h = 1469598103934665603ull;
    for (const std::uint32_t v : k) h = (h ^ v) * 1099511628211ull;
    return static_cast<std::size_t>(h);
  }
};

/// A corner's position as welding sees it: -0 and 0 are one position, and so are all NaNs.
Key weldKey(const float p[3]) {
  Key k;
  for (int a = 0; a < 3; ++a) {
    const float v = p[a] == 0.0f ? 0.0f : std::isnan(p[a]) ? std::numeric_limits<float>::quiet_NaN() : p[a];
    std::memcpy(&k[static_cast<std::size_t>(a)], &v, 4);
  }
  return k;
}

/// Corners welded by exact position (weldKey).
class Welder {
 public:
  pcl::index_t add(const float p[3]) {
    const Key k = weldKey(p);
    const auto [it, fresh] = index_.try_emplace(k, static_cast<pcl::index_t>(xyz_.size() / 3));
    if (fresh) xyz_.insert(xyz_.end(), p, p + 3);
    return it->second;
  }
  const std::vector<double>& xyz() const { return xyz_; }

 private:
  std::unordered_map<Key, pcl::index_t, KeyHash> index_;
  std::vector<double> xyz_;
};

Shape finish(const std::string& path, Welder& welder, std::vector<pcl::Vertices> faces) {
  if (faces.empty()) fail(path, "no points: the STL holds no triangles");
  Shape shape;
  shape.cloud =
      makeCloud(welder.xyz().size() / 3,
                {{"x", Field::FLOAT32}, {"y", Field::FLOAT32}, {"z", Field::FLOAT32}}, welder.xyz());
  shape.polygons = std::move(faces);
  return shape;
}

Shape readAsciiStl(const std::string& path, std::string_view text) {
  Lexer lex(text, 0);
  Welder welder;
  std::vector<pcl::Vertices> faces;
  pcl::Vertices face;
  std::size_t facet_line = 0;  // the line of the open facet, 0 if none
  bool in_solid = false;
  const auto bad = [&](const std::string& why) {
    fail(path, "malformed data: line " + num(lex.line()) + ": " + why + " (" + excerpt(lex.lineText()) + ")");
  };
  while (lex.nextLine()) {
    // Keywords in any case: some exporters write SOLID, FACET NORMAL, VERTEX, ...
    const std::string kw = lower(lex.token());
    if (kw == "solid") {
      if (in_solid) bad("'solid' inside a solid");
      in_solid = true;
    } else if (!in_solid) {
      bad("expected 'solid'");
    } else if (kw == "endsolid") {
      if (facet_line) bad("'endsolid' inside a facet");
      in_solid = false;
    } else if (kw == "facet") {
      if (facet_line) bad("'facet' inside a facet");
      facet_line = lex.line();
      face.vertices.clear();
    } else if (kw == "vertex") {
      if (!facet_line) bad("'vertex' outside a facet");
      float p[3];
      for (float& v : p) {
        const std::string_view tok = lex.token();
        if (!parseFloating(tok, &v))
          fail(path, "non-numeric value " + excerpt(tok) + " at line " + num(lex.line()));
      }
      face.vertices.push_back(welder.add(p));
    } else if (kw == "endfacet") {
      if (!facet_line) bad("'endfacet' outside a facet");
      if (face.vertices.size() < 3)
        fail(path, "bad face: the facet of line " + num(facet_line) + " has " + num(face.vertices.size()) +
                       " vertices, at least 3 needed");
      faces.push_back(face);
      facet_line = 0;
    } else if (kw != "outer" && kw != "endloop") {
      bad("unexpected " + excerpt(kw));
    }
  }
  if (facet_line) fail(path, "truncated data: the facet of line " + num(facet_line) + " has no 'endfacet'");
  if (in_solid) fail(path, "truncated data: no 'endsolid'");
  return finish(path, welder, std::move(faces));
}

}  // namespace

Shape readStl(const std::string& path) {
  InputFile in(path);
  const std::uint64_t size = in.size();
  const std::string_view body = in.rest();
  // A byte-order mark skipped by InputFile is part of a binary header: count from the file.
  const std::size_t skipped = static_cast<std::size_t>(size - body.size());
  std::uint32_t n = 0;
  if (size >= 84)
    n = static_cast<std::uint32_t>(decodeValue(
        reinterpret_cast<const std::uint8_t*>(body.data()) + 80 - skipped, Field::UINT32, kHostBigEndian));
  const bool binary = size >= 84 && 84 + 50 * std::uint64_t{n} == size;
  if (!binary) {
    std::size_t b = 0;
    while (b < body.size() && (isSpace(body[b]) || body[b] == '\n')) ++b;
    if (lower(body.substr(b, 5)) == "solid" && body.find('\0') == std::string_view::npos)
      return readAsciiStl(path, body);
    if (size < 84)
      fail(path, "truncated data: a binary STL needs at least 84 bytes, the file holds " + num(size));
    fail(path, "malformed data: the binary STL's header declares " + num(n) + " triangles (" +
                   num(84 + 50 * std::uint64_t{n}) + " bytes), the file holds " + num(size) + " bytes");
  }
  if (n == 0) fail(path, "no points: the STL holds no triangles");
  Welder welder;
  std::vector<pcl::Vertices> faces(n);
  bool attributes = false;
  const auto* p = reinterpret_cast<const std::uint8_t*>(body.data()) + 84 - skipped;
  for (std::uint32_t t = 0; t < n; ++t, p += 50) {
    faces[t].vertices.resize(3);
    for (int c = 0; c < 3; ++c) {
      float v[3];
      for (int a = 0; a < 3; ++a)
        v[a] = static_cast<float>(decodeValue(p + 12 + 12 * c + 4 * a, Field::FLOAT32, kHostBigEndian));
      faces[t].vertices[static_cast<std::size_t>(c)] = welder.add(v);
    }
    attributes = attributes || p[48] || p[49];
  }
  Shape shape = finish(path, welder, std::move(faces));
  if (attributes)
    shape.warnings.push_back(path +
                             ": the binary STL's attribute bytes (per-triangle colours in some exporters) "
                             "were dropped");
  return shape;
}

namespace {
/// Point i's position as an STL stores it (float).
Eigen::Vector3f storedCorner(const pcl::PCLPointCloud2& c, const XyzFields& xyz, std::size_t i) {
  return Eigen::Vector3f(static_cast<float>(readValue(c, i, c.fields[static_cast<std::size_t>(xyz.x)])),
                         static_cast<float>(readValue(c, i, c.fields[static_cast<std::size_t>(xyz.y)])),
                         static_cast<float>(readValue(c, i, c.fields[static_cast<std::size_t>(xyz.z)])));
}
}  // namespace

std::string stlLosses(const Shape& shape) {
  const pcl::PCLPointCloud2& c = shape.cloud;
  const XyzFields xyz = findXyzFields(c);
  const std::size_t n = shape.size();
  if (!shape.isMesh() || !xyz.hasXyz() || n == 0) return "";
  std::vector<char> used(n, 0);
  for (const auto& poly : shape.polygons)
    for (const auto v : poly.vertices)
      if (v >= 0 && static_cast<std::size_t>(v) < n) used[static_cast<std::size_t>(v)] = 1;
  // The used points' positions as the writer stores them and the reader welds them.
  std::vector<Key> keys;
  for (std::size_t i = 0; i < n; ++i)
    if (used[i]) keys.push_back(weldKey(storedCorner(c, xyz, i).data()));
  const std::size_t on_faces = keys.size();
  std::sort(keys.begin(), keys.end());
  const std::size_t distinct = static_cast<std::size_t>(std::unique(keys.begin(), keys.end()) - keys.begin());
  std::string out;
  if (on_faces < n)
    out = "STL holds triangles only: the " + num(n - on_faces) + " of " + num(n) +
          " points on no face are dropped";
  if (distinct < on_faces)
    out += (out.empty() ? "" : "; ") + std::string("STL has no shared vertices: ") +
           num(on_faces - distinct) + " points at the position of another come back as one with it";
  return out;
}

void writeStl(const std::string& path, const Shape& shape, bool ascii) {
  checkShape(path, shape, false);
  const pcl::PCLPointCloud2& c = shape.cloud;
  const XyzFields xyz = findXyzFields(c);
  if (!xyz.hasXyz()) fail(path, "cannot write: no x/y/z fields");
  if (shape.polygons.empty())
    fail(path,
         "cannot write: STL holds triangles and the shape has no faces (write .ply, .pcd, .xyz or .off)");
  std::uint64_t count = 0;
  for (const auto& poly : shape.polygons) count += poly.vertices.size() - 2;  // a fan per polygon
  if (count > std::numeric_limits<std::uint32_t>::max())
    fail(path, "cannot write: too many triangles for STL");
  const auto point = [&](pcl::index_t i) { return storedCorner(c, xyz, static_cast<std::size_t>(i)); };
  AtomicWriter w(path);
  std::string buf;
  if (ascii) {
    buf = "solid hgdeform\n";
  } else {
    buf = "binary STL written by hgdeform";
    buf.resize(80, ' ');
    std::uint8_t b[4];
    encodeValue(b, Field::UINT32, static_cast<double>(count));
    if (kHostBigEndian) std::reverse(b, b + 4);
    buf.append(reinterpret_cast<const char*>(b), 4);
  }
  const auto putFloats = [&](const Eigen::Vector3f& v) {
    for (int a = 0; a < 3; ++a) {
      if (ascii) {
        buf += ' ';
        appendFloat(buf, v[a]);
      } else {
        std::uint8_t b[4];
        encodeValue(b, Field::FLOAT32, v[a]);
        if (kHostBigEndian) std::reverse(b, b + 4);
        buf.append(reinterpret_cast<const char*>(b), 4);
      }
    }
  };
  for (const auto& poly : shape.polygons) {
    for (std::size_t j = 1; j + 1 < poly.vertices.size(); ++j) {
      const Eigen::Vector3f a = point(poly.vertices[0]), b = point(poly.vertices[j]),
                            d = point(poly.vertices[j + 1]);
      Eigen::Vector3f nrm = (b - a).cross(d - a);
      nrm = nrm.norm() > 0 && std::isfinite(nrm.norm()) ? Eigen::Vector3f(nrm.normalized())
                                                        : Eigen::Vector3f::Zero();
      if (ascii) buf += "facet normal";
      putFloats(nrm);
      if (ascii) buf += "\n outer loop\n";
      for (const Eigen::Vector3f* v : {&a, &b, &d}) {
        if (ascii) buf += "  vertex";
        putFloats(*v);
        if (ascii) buf += '\n';
      }
      if (ascii)
        buf += " endloop\nendfacet\n";
      else
        buf.append(2, '\0');
      flushIfFull(w, buf);
    }
  }
  if (ascii) buf += "endsolid hgdeform\n";
  w.write(buf);
  w.commit();
}

}  // namespace hgd::io_internal
