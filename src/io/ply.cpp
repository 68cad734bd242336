// PLY reading: ascii, binary little and big endian, with every element, property and comment
// of the file kept (FileExtras) so that a shape written back loses nothing (ply_write.cpp).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "io/internal.h"

namespace hgd::io_internal {
namespace {

struct PlyProperty {
  std::string name;
  std::uint8_t type = 0;  // value type (list items for lists)
  bool list = false;
  std::uint8_t count_type = 0;
};

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> props;
  bool allScalar() const {
    return std::none_of(props.begin(), props.end(), [](const PlyProperty& p) { return p.list; });
  }
  /// Bytes of one binary record without list items.
  std::uint64_t minBytes() const {
    std::uint64_t n = 0;
    for (const auto& p : props) n += datatypeSize(p.list ? p.count_type : p.type);
    return n;
  }
};

enum class PlyFormat { Ascii, BinaryLE, BinaryBE };

/// PCL's organized PLY (rangeGridPixels) read as PCL's PLYReader reads it: the organized cloud
/// of obj_info num_cols x num_rows, row by row, with NaN points (NaN in every float field, zero
/// elsewhere) at the empty pixels. The grid stays with the extras: a PLY written back holds the
/// valid points and the same grid (ply_write.cpp). Left as read when anything does not fit (a
/// mesh, per-vertex lists, no or other sizes).
void organizeRangeGrid(Shape& shape) {
  const FileExtras& x = shape.extras;
  if (!shape.polygons.empty()) return;
  const FileExtras::Element* grid = nullptr;
  for (const auto& el : x.ply_elements) {
    if (el.name == "range_grid") grid = &el;
    if (el.name == "vertex" && std::any_of(el.kept.begin(), el.kept.end(), [](char k) { return k != 0; }))
      return;
  }
  if (!grid) return;
  std::uint64_t cols = 0, rows = 0;
  for (const auto& line : x.ply_comments) {
    const auto w = splitWords(line);
    if (w.size() == 3 && w[0] == "obj_info" && w[1] == "num_cols") parseU64(w[2], &cols);
    if (w.size() == 3 && w[0] == "obj_info" && w[1] == "num_rows") parseU64(w[2], &rows);
  }
  if (cols == 0 || rows == 0 || cols > grid->count || cols * rows != grid->count ||
      cols > std::numeric_limits<std::uint32_t>::max() || rows > std::numeric_limits<std::uint32_t>::max())
    return;
  // A grid with a point at every pixel: PCL's reader keeps the vertices' order (it rebuilds the
  // grid only to place NaN points), and so does this one.
  if (grid->count == shape.size()) return;
  const std::vector<std::size_t> pixel = rangeGridPixels(x, shape.size());
  if (pixel.empty()) return;
  pcl::PCLPointCloud2& c = shape.cloud;
  const std::size_t step = c.point_step;
  std::vector<std::uint8_t> nan_point(step, 0);
  for (const auto& f : c.fields)
    for (std::size_t k = 0; k < fieldCount(f); ++k) {
      if (f.datatype == Field::FLOAT32) {
        const float v = std::numeric_limits<float>::quiet_NaN();
        std::memcpy(nan_point.data() + f.offset + 4 * k, &v, 4);
      } else if (f.datatype == Field::FLOAT64) {
        const double v = std::numeric_limits<double>::quiet_NaN();
        std::memcpy(nan_point.data() + f.offset + 8 * k, &v, 8);
      }
    }
  std::vector<std::uint8_t> data(static_cast<std::size_t>(grid->count) * step);
  for (std::size_t k = 0; k < grid->count; ++k) std::memcpy(data.data() + k * step, nan_point.data(), step);
  for (std::size_t v = 0; v < pixel.size(); ++v)
    std::memcpy(data.data() + pixel[v] * step, c.data.data() + v * step, step);
  c.data = std::move(data);
  c.width = static_cast<std::uint32_t>(cols);
  c.height = static_cast<std::uint32_t>(rows);
  c.row_step = static_cast<std::uint32_t>(step * cols);
  c.is_dense = false;
}

}  // namespace

Shape readPly(const std::string& path, RecordLayout* layout) {
  InputFile in(path);
  std::string line;
  if (!in.readLine(&line, 64) || splitWords(line).size() != 1 || splitWords(line)[0] != "ply")
    fail(path, "malformed header: first line is " + excerpt(line) + ", expected 'ply'");

  PlyFormat format = PlyFormat::Ascii;
  bool have_format = false, ended = false;
  std::vector<PlyElement> elements;
  std::vector<std::string> comments;
  std::unordered_set<std::string> prop_names;  // of the last element: a second one is refused
  while (in.readLine(&line, kMaxHeaderLine)) {
    const auto bad = [&](const std::string& why) {
      fail(path, "malformed header: line " + num(in.linesRead()) + ": " + why + " (" + excerpt(line) + ")");
    };
    const auto words = splitWords(line);
    if (words.empty()) continue;
    const std::string_view kw = words[0];
    if (kw == "comment" || kw == "obj_info") {
      if (line.rfind("comment written by hgdeform", 0) != 0) comments.push_back(line);
      continue;
    }
    if (kw == "end_header") {
      ended = true;
      break;
    }
    if (kw == "format") {
      if (words.size() != 3) bad("expected 'format <type> 1.0'");
      if (have_format) bad("second format line");
      if (words[1] == "ascii")
        format = PlyFormat::Ascii;
      else if (words[1] == "binary_little_endian")
        format = PlyFormat::BinaryLE;
      else if (words[1] == "binary_big_endian")
        format = PlyFormat::BinaryBE;
      else
        fail(path, "unsupported PLY format " + excerpt(words[1]));
      if (words[2] != "1.0" && words[2] != "1") fail(path, "unsupported PLY version " + excerpt(words[2]));
      have_format = true;
    } else if (kw == "element") {
      PlyElement el;
      if (words.size() != 3 || !parseU64(words[2], &el.count)) bad("expected 'element <name> <count>'");
      el.name = std::string(words[1]);
      for (const auto& e : elements)
        if (e.name == el.name) bad("second element '" + el.name + "'");
      elements.push_back(std::move(el));
      prop_names.clear();
    } else if (kw == "property") {
      if (elements.empty()) bad("property before any element");
      PlyProperty p;
      if (words.size() == 5 && words[1] == "list") {
        p.list = true;
        if (!plyTypeFromName(words[2], &p.count_type) || !plyTypeFromName(words[3], &p.type))
          fail(path, "unsupported PLY property type in line " + num(in.linesRead()) + " " + excerpt(line));
        if (!isIntegerType(p.count_type))
          fail(path, "unsupported PLY list count type in line " + num(in.linesRead()) + " " + excerpt(line));
        p.name = std::string(words[4]);
      } else if (words.size() == 3 && words[1] != "list") {
        if (!plyTypeFromName(words[1], &p.type))
          fail(path, "unsupported PLY property type in line " + num(in.linesRead()) + " " + excerpt(line));
        p.name = std::string(words[2]);
      } else {
        bad("expected 'property <type> <name>' or 'property list <type> <type> <name>'");
      }
      if (!prop_names.insert(p.name).second) bad("second property '" + p.name + "'");
      elements.back().props.push_back(std::move(p));
    } else {
      bad("unknown keyword");
    }
  }
  if (!ended) fail(path, "malformed header: no end_header line");
  if (!have_format) fail(path, "malformed header: no format line");

  int vertex_el = -1, face_el = -1, face_prop = -1;
  for (std::size_t e = 0; e < elements.size(); ++e) {
    if (elements[e].name == "vertex") vertex_el = static_cast<int>(e);
    if (elements[e].name == "face") {
      for (std::size_t k = 0; k < elements[e].props.size(); ++k) {
        const auto& p = elements[e].props[k];
        if (p.list && (p.name == "vertex_indices" || p.name == "vertex_index")) {
          face_el = static_cast<int>(e);
          face_prop = static_cast<int>(k);
          break;
        }
      }
    }
  }
  if (vertex_el < 0) fail(path, "no points: the file has no vertex element");
  const PlyElement& vel = elements[vertex_el];
  const auto hasScalar = [&](const char* name) {
    return std::any_of(vel.props.begin(), vel.props.end(),
                       [&](const PlyProperty& p) { return !p.list && p.name == name; });
  };
  if (!hasScalar("x") || !hasScalar("y") || !hasScalar("z"))
    fail(path, "no x/y/z fields: the vertex element has no scalar x, y and z properties");
  if (vel.count == 0) fail(path, "no points: the vertex element is empty");

  // Check the declared counts against the data actually present, before allocating anything.
  const bool binary = format != PlyFormat::Ascii;
  const std::uint64_t avail = in.remaining();
  std::uint64_t total = 0;
  for (const auto& el : elements) {
    // A record of no properties is counted as a byte: it holds nothing, yet writing it back
    // as ascii takes a line, and a count of them no file could hold (1e18) is no shape.
    const std::uint64_t per = std::max<std::uint64_t>(binary ? el.minBytes() : 2 * el.props.size(), 1);
    std::uint64_t need = 0;
    if (!mulOk(el.count, per, &need) || !addOk(total, need, &total))
      fail(path, "truncated data: header declares " + num(el.count) + " '" + el.name +
                     "' records, more than any file can hold");
    if ((binary && total > avail) || (!binary && total > avail + 1))
      fail(path, "truncated data: header declares " + num(el.count) + " '" + el.name +
                     "' records (at least " + num(need) + " bytes" + (binary ? "" : " of text") +
                     "), the file holds " + num(avail) + " bytes of data");
  }
  if (vel.count > std::numeric_limits<std::uint32_t>::max())
    fail(path, "unsupported: " + num(vel.count) + " vertices (at most 4294967295)");

  if (layout) {  // the vertex records placed, not read: they must be records of one size, first
    const auto cannot = [&](const std::string& why) {
      fail(path, "cannot read the points in place (" + why + "); read the whole file instead");
    };
    if (format == PlyFormat::Ascii) cannot("ascii PLY");
    if ((format == PlyFormat::BinaryBE) != kHostBigEndian) cannot("big-endian PLY");
    if (!vel.allScalar()) cannot("the vertex element has list properties");
    for (int e = 0; e < vertex_el; ++e)
      if (elements[static_cast<std::size_t>(e)].count > 0 &&
          !elements[static_cast<std::size_t>(e)].props.empty())
        cannot("element '" + elements[static_cast<std::size_t>(e)].name + "' comes before the vertices");
    for (const auto& el : elements)
      if (el.name == "range_grid") cannot("an organized PLY (range_grid)");
  }

  Shape shape;
  pcl::PCLPointCloud2& cloud = shape.cloud;
  // Everything not held in the cloud's fields or the polygons is kept aside (FileExtras).
  std::vector<FileExtras::Element> extra(elements.size());
  bool any_extra = false;
  for (std::size_t e = 0; e < elements.size(); ++e) {
    FileExtras::Element& x = extra[e];
    x.name = elements[e].name;
    x.count = elements[e].count;
    for (std::size_t k = 0; k < elements[e].props.size(); ++k) {
      const PlyProperty& p = elements[e].props[k];
      x.props.push_back({p.name, p.type, p.list, p.count_type});
      const bool held = (static_cast<int>(e) == vertex_el && !p.list) ||
                        (static_cast<int>(e) == face_el && static_cast<int>(k) == face_prop);
      x.kept.push_back(held ? 0 : 1);
      any_extra = any_extra || !held;
    }
    any_extra = any_extra || (static_cast<int>(e) != vertex_el && static_cast<int>(e) != face_el);
  }
  std::vector<std::uint32_t> offsets(vel.props.size(), 0);
  std::uint32_t step = 0;
  for (std::size_t k = 0; k < vel.props.size(); ++k) {
    const auto& p = vel.props[k];
    if (p.list) continue;
    Field f;
    f.name = p.name;
    f.offset = step;
    f.datatype = p.type;
    f.count = 1;
    offsets[k] = step;
    step += static_cast<std::uint32_t>(datatypeSize(p.type));
    cloud.fields.push_back(f);
  }
  const std::uint32_t nverts = static_cast<std::uint32_t>(vel.count);
  cloud.width = nverts;
  cloud.height = 1;
  cloud.point_step = step;
  cloud.row_step = step * nverts;
  cloud.is_bigendian = false;
  if (!layout) cloud.data.resize(static_cast<std::size_t>(nverts) * step);

  if (binary) {
    const bool swap = (format == PlyFormat::BinaryBE) != kHostBigEndian;
    for (std::size_t e = 0; e < elements.size(); ++e) {
      const PlyElement& el = elements[e];
      if (el.props.empty() || el.count == 0) continue;
      const bool is_vertex = static_cast<int>(e) == vertex_el;
      std::vector<double>& kept_values = extra[e].values;
      if (el.allScalar()) {
        if (is_vertex && layout) {
          layout->offset = in.offset();
          layout->count = nverts;
          layout->bytes = step;
          in.skip(static_cast<std::uint64_t>(nverts) * step, "vertex data");
        } else if (is_vertex) {
          in.read(cloud.data.data(), cloud.data.size(), "vertex data");
        } else {
          const std::uint8_t* d = in.take(el.count * el.minBytes(), "element data");
          kept_values.reserve(el.count * el.props.size());
          for (std::uint64_t r = 0; r < el.count; ++r)
            for (const PlyProperty& p : el.props) {
              kept_values.push_back(decodeValue(d, p.type, swap));
              d += datatypeSize(p.type);
            }
        }
        continue;
      }
      // Each face takes at least a count and three indices: reserve no more than the data can hold.
      if (static_cast<int>(e) == face_el)
        shape.polygons.reserve(std::min<std::uint64_t>(el.count, in.remaining() / 4));
      for (std::uint64_t r = 0; r < el.count; ++r) {
        std::uint8_t* out = is_vertex ? cloud.data.data() + r * step : nullptr;
        for (std::size_t k = 0; k < el.props.size(); ++k) {
          const PlyProperty& p = el.props[k];
          const std::size_t isz = datatypeSize(p.type);
          if (!p.list) {
            const std::uint8_t* src = in.take(isz, "element data");
            if (out)
              std::memcpy(out + offsets[k], src, isz);
            else if (extra[e].kept[k])
              kept_values.push_back(decodeValue(src, p.type, swap));
            continue;
          }
          const double n =
              decodeValue(in.take(datatypeSize(p.count_type), "list length"), p.count_type, swap);
          if (n < 0) fail(path, "malformed data: negative list length in '" + el.name + "' record " + num(r));
          const auto len = static_cast<std::uint64_t>(n);
          if (static_cast<int>(e) != face_el || static_cast<int>(k) != face_prop) {
            const std::uint8_t* items = in.take(len * isz, "list data");
            kept_values.push_back(n);
            for (std::uint64_t j = 0; j < len; ++j)
              kept_values.push_back(decodeValue(items + j * isz, p.type, swap));
            continue;
          }
          if (len < 3)
            fail(path, "bad face: face " + num(r) + " has " + num(len) + " vertices, at least 3 needed");
          const std::uint8_t* items = in.take(len * isz, "face data");
          pcl::Vertices poly;
          poly.vertices.resize(len);
          for (std::uint64_t j = 0; j < len; ++j) {
            const double idx = decodeValue(items + j * isz, p.type, swap);
            if (!(idx >= 0 && idx < nverts && idx == std::floor(idx))) {
              std::string text;
              if (idx == std::floor(idx) && std::abs(idx) < 9e15)
                appendInt(text, static_cast<long long>(idx));
              else
                appendFloat(text, idx);
              fail(path, "bad face index " + text + " in face " + num(r) + " (byte " +
                             num(in.size() - in.remaining() - (len - j) * isz) + "): " +
                             (idx == std::floor(idx) ? "the file has " + num(nverts) +
                                                           " vertices, indices 0 to " + num(nverts - 1)
                                                     : std::string("not an integer")));
            }
            poly.vertices[j] = static_cast<pcl::index_t>(idx);
          }
          shape.polygons.push_back(std::move(poly));
        }
      }
    }
    if (swap) swapCloud(cloud);
    // Data beyond the last element that could hold another vertex: the header's counts are
    // wrong, and reading on would silently drop points.
    if (in.remaining() > 1 && in.remaining() >= vel.minBytes())
      fail(path, "malformed data: " + num(in.remaining()) +
                     " bytes after the last element: more data than the header declares (" + num(vel.count) +
                     " vertices)");
  } else {
    Lexer lex(in.rest(), in.linesRead());
    std::vector<std::string> vertex_names;
    DecimalsSeen decimals;  // per vertex property, for writing the values back as spelt
    for (std::size_t e = 0; e < elements.size(); ++e) {
      const PlyElement& el = elements[e];
      if (el.props.empty()) continue;
      const bool is_vertex = static_cast<int>(e) == vertex_el;
      if (is_vertex) {
        std::vector<std::string> names;
        for (const auto& p : el.props) names.push_back(p.name);
        // Stored once the values are read (below), under the properties' names.
        vertex_names = std::move(names);
      }
      for (std::uint64_t r = 0; r < el.count; ++r) {
        if (!lex.nextLine())
          fail(path,
               "truncated data: expected " + num(el.count) + " '" + el.name + "' records, found " + num(r));
        std::uint8_t* out = is_vertex ? cloud.data.data() + r * step : nullptr;
        const auto next = [&](const PlyProperty& p) {
          const std::string_view tok = lex.token();
          if (tok.empty())
            fail(path, "truncated data: line " + num(lex.line()) + " has too few values for property '" +
                           p.name + "' of element '" + el.name + "'");
          return tok;
        };
        const auto nonNumeric = [&](std::string_view tok, const PlyProperty& p) {
          fail(path, "non-numeric value " + excerpt(tok) + " at line " + num(lex.line()) + " (property '" +
                         p.name + "' of element '" + el.name + "')");
        };
        for (std::size_t k = 0; k < el.props.size(); ++k) {
          const PlyProperty& p = el.props[k];
          std::uint8_t scratch[8];
          if (!p.list) {
            const std::string_view tok = next(p);
            const Parse st = parseValue(tok, p.type, out ? out + offsets[k] : scratch);
            if (out) decimals.see(k, tok);
            if (st == Parse::Bad) nonNumeric(tok, p);
            if (st == Parse::Range)
              fail(path, "value out of range " + excerpt(tok) + " at line " + num(lex.line()) +
                             " for property '" + p.name + "' of type " + plyTypeName(p.type));
            if (!out && extra[e].kept[k]) extra[e].values.push_back(decodeValue(scratch, p.type, false));
            continue;
          }
          const std::string_view ctok = next(p);
          long long len = 0;
          if (parseInteger(ctok, &len) != Parse::Ok) nonNumeric(ctok, p);
          if (len < 0)
            fail(path, "malformed data: negative list length at line " + num(lex.line()) + " (element '" +
                           el.name + "')");
          const bool is_face = static_cast<int>(e) == face_el && static_cast<int>(k) == face_prop;
          if (is_face && len < 3)
            fail(path, "bad face: face " + num(r) + " at line " + num(lex.line()) + " has " +
                           std::to_string(len) + " vertices, at least 3 needed");
          pcl::Vertices poly;
          if (!is_face) extra[e].values.push_back(static_cast<double>(len));
          for (long long j = 0; j < len; ++j) {
            const std::string_view tok = next(p);
            if (!is_face) {  // as the declared type holds it (in range; text may carry more digits)
              std::uint8_t item[8];
              const Parse st = parseValue(tok, p.type, item);
              if (st == Parse::Bad) nonNumeric(tok, p);
              if (st == Parse::Range)
                fail(path, "value out of range " + excerpt(tok) + " at line " + num(lex.line()) +
                               " for property '" + p.name + "' of type " + plyTypeName(p.type));
              extra[e].values.push_back(decodeValue(item, p.type, false));
              continue;
            }
            double v = 0;
            if (!parseFloating(tok, &v)) nonNumeric(tok, p);
            if (!(v >= 0 && v < nverts && v == std::floor(v)))
              fail(path, "bad face index " + excerpt(tok) + " at line " + num(lex.line()) + " (" +
                             num(nverts) + " vertices)");
            poly.vertices.push_back(static_cast<pcl::index_t>(v));
          }
          if (is_face) shape.polygons.push_back(std::move(poly));
        }
        if (!lex.atLineEnd())
          fail(path, "malformed data: line " + num(lex.line()) +
                         " has more values than the header declares for " + "element '" + el.name + "'");
      }
    }
    if (lex.nextLine())
      fail(path, "malformed data: line " + num(lex.line()) + ": more data than the header declares (" +
                     num(vel.count) + " vertices)");
    decimals.store(shape.extras, vertex_names);
  }

  cloud.is_dense = layout ? false : computeDense(cloud);
  shape.extras.ply_comments = std::move(comments);
  shape.extras.ply_big_endian = format == PlyFormat::BinaryBE;
  if (any_extra) shape.extras.ply_elements = std::move(extra);
  if (!layout) organizeRangeGrid(shape);
  return shape;
}

}  // namespace hgd::io_internal
