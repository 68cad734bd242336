// OFF meshes (Geomview's Object File Format) and its COFF, NOFF and CNOFF variants: a keyword
// line, "vertices faces edges", one vertex per line (x y z, then nx ny nz for N, then r g b [a]
// for C), one face per line ("k i1 ... ik", a face colour after it is dropped with a warning).
// '#' starts a comment anywhere.
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "io/internal.h"

namespace hgd::io_internal {
namespace {

/// The next line's words without its comment; false at the end of the text.
bool nextWords(Lexer& lex, std::vector<std::string_view>* words) {
  while (lex.nextLine()) {
    std::string_view line = lex.lineText();
    line = line.substr(0, line.find('#'));
    *words = splitWords(line);
    if (!words->empty()) return true;
  }
  return false;
}

}  // namespace

Shape readOff(const std::string& path) {
  TextFile off(path);
  std::vector<std::string_view> w;
  if (!nextWords(off.lex, &w)) fail(path, "malformed header: no OFF line");
  const std::string_view kw = w[0];
  if (kw != "OFF" && kw != "COFF" && kw != "NOFF" && kw != "CNOFF" && kw != "NCOFF")
    fail(path, "malformed header: line " + num(off.lex.line()) + " is " + excerpt(off.lex.lineText()) +
                   ", expected OFF, COFF, NOFF or CNOFF");
  const bool colour = kw.find('C') != std::string_view::npos,
             normals = kw.find('N') != std::string_view::npos;
  std::vector<std::string_view> counts(w.begin() + 1, w.end());
  if (counts.empty()) {
    if (!nextWords(off.lex, &w)) fail(path, "malformed header: no vertex and face counts");
    counts = w;
  }
  std::uint64_t nv = 0, nf = 0, ne = 0;
  if (counts.size() < 2 || counts.size() > 3 || !parseU64(counts[0], &nv) || !parseU64(counts[1], &nf) ||
      (counts.size() == 3 && !parseU64(counts[2], &ne)))
    fail(path, "malformed header: line " + num(off.lex.line()) + ": expected '<vertices> <faces> <edges>'");
  if (nv == 0) fail(path, "no points: the header declares 0 vertices");
  // Each vertex line holds at least "0 0 0\n", each face line "3 0 1 2\n": checked before allocating.
  if (nv > off.in.remaining() / 6 || nf > off.in.remaining() / 8 || nv * 6 + nf * 8 > off.in.remaining())
    fail(path, "truncated data: the header declares " + num(nv) + " vertices and " + num(nf) +
                   " faces, more than the file's " + num(off.in.remaining()) + " bytes hold");
  if (nv > std::numeric_limits<std::int32_t>::max()) fail(path, "unsupported: more than 2147483647 vertices");

  const std::size_t base = 3 + (normals ? 3 : 0);
  std::size_t ncolour = 0;
  std::vector<double> values;
  bool colour_bytes = false, colour_integral = true;
  DecimalsSeen decimals;  // per column, for writing the values back as spelt
  for (std::uint64_t i = 0; i < nv; ++i) {
    if (!nextWords(off.lex, &w))
      fail(path, "truncated data: the header declares " + num(nv) + " vertices, the file holds " + num(i));
    std::size_t want = base;
    if (colour) {
      if (i == 0) ncolour = w.size() >= base + 4 ? 4 : 3;
      want += ncolour;
    }
    if (w.size() < want)
      fail(path, "malformed data: line " + num(off.lex.line()) + ": a vertex needs " + num(want) +
                     " values, found " + num(w.size()));
    for (std::size_t k = 0; k < want; ++k) {
      double d = 0;
      if (!parseFloating(w[k], &d))
        fail(path, "non-numeric value " + excerpt(w[k]) + " at line " + num(off.lex.line()));
      decimals.see(k, w[k]);
      if (k >= base) {
        colour_integral = colour_integral && d == std::floor(d) && d >= 0 && d <= 255;
        colour_bytes = colour_bytes || d > 1;
      }
      values.push_back(d);
    }
  }
  Shape shape;
  bool face_colours = false;
  for (std::uint64_t f = 0; f < nf; ++f) {
    if (!nextWords(off.lex, &w))
      fail(path, "truncated data: the header declares " + num(nf) + " faces, the file holds " + num(f));
    std::uint64_t k = 0;
    if (!parseU64(w[0], &k) || k < 3 || k >= w.size())  // (k + 1 would wrap at 2^64 - 1)
      fail(path, "bad face: line " + num(off.lex.line()) + " " + excerpt(off.lex.lineText()) +
                     " (expected '<k> <i1> ... <ik>', k at least 3)");
    pcl::Vertices poly;
    for (std::uint64_t j = 1; j <= k; ++j) {
      std::uint64_t idx = 0;
      if (!parseU64(w[j], &idx) || idx >= nv)
        fail(path, "bad face index " + excerpt(w[j]) + " at line " + num(off.lex.line()) + " (" + num(nv) +
                       " vertices)");
      poly.vertices.push_back(static_cast<pcl::index_t>(idx));
    }
    face_colours = face_colours || w.size() > k + 1;
    shape.polygons.push_back(std::move(poly));
  }
  // More lines than the header declares: its counts are wrong, and reading on would silently
  // drop faces (as PLY, an error).
  if (nextWords(off.lex, &w))
    fail(path, "malformed data: line " + num(off.lex.line()) + " " + excerpt(off.lex.lineText()) +
                   ": more lines than the header declares (" + num(nv) + " vertices, " + num(nf) + " faces)");
  std::vector<std::pair<std::string, std::uint8_t>> fields = {
      {"x", Field::FLOAT64}, {"y", Field::FLOAT64}, {"z", Field::FLOAT64}};
  if (normals)
    for (const char* name : {"nx", "ny", "nz"}) fields.emplace_back(name, Field::FLOAT32);
  const std::uint8_t ctype = colour_integral && colour_bytes ? Field::UINT8 : Field::FLOAT32;
  const char* cnames[] = {"red", "green", "blue", "alpha"};
  for (std::size_t k = 0; k < ncolour; ++k) fields.emplace_back(cnames[k], ctype);
  shape.cloud = makeCloud(static_cast<std::size_t>(nv), fields, values);
  std::vector<std::string> names;
  for (const auto& f : fields) names.push_back(f.first);
  decimals.store(shape.extras, names);
  if (face_colours) shape.warnings.push_back(path + ": the OFF's face colours were dropped");
  return shape;
}

void writeOff(const std::string& path, const Shape& shape) {
  checkShape(path, shape, false);
  const pcl::PCLPointCloud2& c = shape.cloud;
  const XyzFields xyz = findXyzFields(c);
  if (!xyz.hasXyz()) fail(path, "cannot write: no x/y/z fields");
  std::vector<int> colour = {findField(c, "red"), findField(c, "green"), findField(c, "blue")};
  const bool has_colour = std::all_of(colour.begin(), colour.end(), [](int i) { return i >= 0; });
  if (!has_colour) colour.clear();
  // Colours without alpha get an opaque one, 255: Open3D's and CloudCompare's OFF readers take
  // four colour values (r g b a) and misread three, and read every value as 0..255 (MeshLab an
  // alpha of 1 as 1/255).
  const bool opaque = has_colour && findField(c, "alpha") < 0;
  if (has_colour && !opaque) colour.push_back(findField(c, "alpha"));
  std::vector<int> cols = {xyz.x, xyz.y, xyz.z};
  if (xyz.hasNormals()) cols.insert(cols.end(), {xyz.nx, xyz.ny, xyz.nz});
  cols.insert(cols.end(), colour.begin(), colour.end());
  const std::size_t n = shape.size();
  std::string buf = std::string(has_colour ? "C" : "") + (xyz.hasNormals() ? "N" : "") + "OFF\n" + num(n) +
                    " " + num(shape.polygons.size()) + " 0\n";
  AtomicWriter w(path);
  std::vector<const Field*> col_fields;
  for (const int k : cols) col_fields.push_back(&c.fields[static_cast<std::size_t>(k)]);
  const std::vector<FileExtras::TextColumn> decimals = decimalsOf(shape.extras, col_fields);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* pt = c.data.data() + i * c.point_step;
    for (std::size_t k = 0; k < cols.size(); ++k) {
      if (k) buf += ' ';
      const Field& f = c.fields[static_cast<std::size_t>(cols[k])];
      int dec = 0;
      bool exp = false;
      rowSpelling(decimals[k], i, n, &dec, &exp);
      appendValue(buf, pt + f.offset, f.datatype, dec, exp);
    }
    if (opaque) buf += " 255";
    buf += '\n';
    flushIfFull(w, buf);
  }
  appendFaceLines(w, buf, shape.polygons);
  w.write(buf);
  w.commit();
}

}  // namespace hgd::io_internal
