// PLY writing: ascii or binary (big-endian when the PLY read was, else little-endian); a shape
// read from a PLY is written back with every element, property and comment the file had
// (ply.cpp reads them).
#include <algorithm>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "io/internal.h"

namespace hgd::io_internal {

namespace {

/// The byte order a binary PLY of `shape` is written in: the file's own (big-endian when it was
/// read so), else little-endian. Whether values must be swapped from the host's order.
bool bigEndianOut(const Shape& shape) {
  return shape.extras.ply_big_endian;
}
const char* binaryFormat(const Shape& shape) {
  return bigEndianOut(shape) ? "binary_big_endian" : "binary_little_endian";
}

/// The last `size` bytes of `b` in the other byte order, when `swap`.
void swapLast(std::vector<std::uint8_t>& b, std::size_t size, bool swap) {
  if (swap) std::reverse(b.end() - static_cast<std::ptrdiff_t>(size), b.end());
}

/// PCL's organized PLY (read as the organized cloud, ply.cpp): the cloud's point that each
/// vertex record is written from (the pixel its range_grid list names); empty for other shapes.
std::vector<std::size_t> gridOrder(const Shape& shape) {
  const FileExtras::Element* vertex = nullptr;
  const FileExtras::Element* grid = nullptr;
  for (const auto& el : shape.extras.ply_elements) {
    if (el.name == "vertex") vertex = &el;
    if (el.name == "range_grid") grid = &el;
  }
  if (!vertex || !grid || grid->count != shape.size() || vertex->count == shape.size() ||
      std::any_of(vertex->kept.begin(), vertex->kept.end(), [](char k) { return k != 0; }))
    return {};
  return rangeGridPixels(shape.extras, vertex->count);
}

/// Whether a shape's kept PLY elements still fit it (the same vertex and face counts; for PCL's
/// organized PLY, `order` from gridOrder).
bool plyExtrasFit(const Shape& shape, const std::vector<std::size_t>& order) {
  const auto& els = shape.extras.ply_elements;
  if (els.empty()) return false;
  bool vertex = false;
  for (const auto& el : els) {
    if (el.name == "vertex") {
      vertex = true;
      if (el.count != shape.size() && order.empty()) return false;
    }
    const bool indices = std::any_of(el.kept.begin(), el.kept.end(), [](char k) { return !k; });
    if (el.name == "face" && indices && el.count != shape.polygons.size()) return false;
  }
  return vertex;
}

/// A PLY written with every element, property and comment the file it was read from had, in
/// their order: the vertex element's scalars from the cloud (fields added since go last), the
/// faces' vertex lists from the polygons, the rest from FileExtras.
void writePlyWithExtras(const std::string& path, const Shape& shape, bool ascii,
                        const std::vector<const Field*>& fields, const std::vector<std::size_t>& order) {
  const pcl::PCLPointCloud2& c = shape.cloud;
  // An organized PLY of PCL's: the valid points, each from its pixel (`order`, gridOrder).
  const std::size_t n = order.empty() ? shape.size() : order.size();
  std::string h = "ply\nformat ";
  h += ascii ? "ascii" : binaryFormat(shape);
  h += " 1.0\n";
  for (const auto& line : shape.extras.ply_comments) h += line + "\n";
  h += "comment written by hgdeform\n";
  // What each property of each element is written from.
  struct Source {
    const FileExtras::Property* prop = nullptr;
    const Field* field = nullptr;  // a cloud field (vertex scalars)
    bool indices = false;          // the face's vertex list
    bool kept = false;             // FileExtras values
    std::uint8_t count_type = 0;   // the face lists' length type (widened if a face needs it)
    FileExtras::TextColumn text;   // how a cloud field's values are spelt in text
  };
  std::size_t max_face = 0;
  for (const auto& poly : shape.polygons) max_face = std::max(max_face, poly.vertices.size());
  std::vector<std::vector<Source>> sources;
  std::vector<char> used(fields.size(), 0);
  std::unordered_map<std::string, std::vector<std::size_t>> field_of;  // name -> fields, in order
  for (std::size_t f = fields.size(); f-- > 0;) field_of[fields[f]->name].push_back(f);
  for (const auto& el : shape.extras.ply_elements) {
    const bool is_vertex = el.name == "vertex";
    h += "element " + el.name + " " + num(is_vertex ? n : el.count) + "\n";
    std::vector<Source> src;
    for (std::size_t k = 0; k < el.props.size(); ++k) {
      const FileExtras::Property& p = el.props[k];
      Source so;
      so.prop = &p;
      if (el.kept[k]) {
        so.kept = true;
      } else if (is_vertex) {
        if (const auto it = field_of.find(p.name); it != field_of.end())
          for (std::size_t q = it->second.size(); q-- > 0 && !so.field;) {
            const std::size_t f = it->second[q];
            if (!used[f] && fieldCount(*fields[f]) == 1) {
              so.field = fields[f];
              used[f] = 1;
            }
          }
        if (!so.field) continue;  // the field is gone from the cloud
        so.text = decimalsOf(shape.extras, {so.field})[0];
      } else {
        so.indices = true;
        so.count_type = max_face > 127 ? static_cast<std::uint8_t>(Field::UINT32) : p.count_type;
      }
      if (so.field)
        h += std::string("property ") + plyTypeName(so.field->datatype) + " " + p.name + "\n";
      else if (p.list)
        h += std::string("property list ") + plyTypeName(so.indices ? so.count_type : p.count_type) + " " +
             plyTypeName(p.type) + " " + p.name + "\n";
      else
        h += std::string("property ") + plyTypeName(p.type) + " " + p.name + "\n";
      src.push_back(so);
    }
    if (is_vertex)  // fields the file did not have (a computed field), after its own
      for (std::size_t f = 0; f < fields.size(); ++f) {
        if (used[f]) continue;
        Source so;
        so.field = fields[f];
        so.text = decimalsOf(shape.extras, {so.field})[0];
        src.push_back(so);
        const std::size_t cnt = fieldCount(*fields[f]);
        for (std::size_t k = 0; k < cnt; ++k)
          h += std::string("property ") + plyTypeName(fields[f]->datatype) + " " + fields[f]->name +
               (cnt > 1 ? "_" + num(k) : std::string()) + "\n";
      }
    sources.push_back(std::move(src));
  }
  h += "end_header\n";

  AtomicWriter w(path);
  w.write(h);
  const bool swap = bigEndianOut(shape) != kHostBigEndian;
  std::vector<std::uint8_t> bin;
  std::string txt;
  std::vector<std::uint8_t>* b = ascii ? nullptr : &bin;
  std::string* t = ascii ? &txt : nullptr;
  for (std::size_t e = 0; e < shape.extras.ply_elements.size(); ++e) {
    const auto& el = shape.extras.ply_elements[e];
    const bool is_vertex = el.name == "vertex";
    const std::uint64_t records = is_vertex ? n : el.count;
    // Binary vertices made of cloud fields alone (a file's usual case): copied per point, or in
    // one write where the cloud holds exactly those fields in that order, not value by value.
    if (b && !swap && is_vertex && order.empty() &&
        std::all_of(sources[e].begin(), sources[e].end(),
                    [](const Source& so) { return so.field != nullptr; })) {
      std::vector<const Field*> packed;
      for (const Source& so : sources[e]) packed.push_back(so.field);
      w.write(bin.data(), bin.size());
      bin.clear();
      writePackedBinary(w, c, n, packed);
      continue;
    }
    std::size_t at = 0;  // into el.values
    for (std::uint64_t r = 0; r < records; ++r) {
      bool first = true;
      const auto sep = [&] {
        if (t && !first) *t += ' ';
        first = false;
      };
      for (const Source& so : sources[e]) {
        if (so.field) {
          const std::size_t point = order.empty() ? static_cast<std::size_t>(r) : order[r];
          const std::uint8_t* pt = c.data.data() + point * c.point_step + so.field->offset;
          const std::size_t sz = datatypeSize(so.field->datatype);
          for (std::size_t k = 0; k < fieldCount(*so.field); ++k) {
            sep();
            if (t) {
              int dec = 0;
              bool exp = false;
              rowSpelling(so.text, static_cast<std::size_t>(r), n, &dec,
                          &exp);  // (file rows: vertex records)
              appendValue(*t, pt + k * sz, so.field->datatype, dec, exp);
            } else {
              b->insert(b->end(), pt + k * sz, pt + (k + 1) * sz);
              swapLast(*b, sz, swap);
            }
          }
        } else if (so.indices) {
          const auto& poly = shape.polygons[r];
          sep();
          putValue(static_cast<double>(poly.vertices.size()), so.count_type, b, t);
          if (b) swapLast(*b, datatypeSize(so.count_type), swap);
          for (const auto idx : poly.vertices) {
            sep();
            putValue(static_cast<double>(idx), so.prop->type, b, t);
            if (b) swapLast(*b, datatypeSize(so.prop->type), swap);
          }
        } else if (so.prop->list) {
          const auto len = static_cast<std::size_t>(el.values.at(at++));
          sep();
          putValue(static_cast<double>(len), so.prop->count_type, b, t);
          if (b) swapLast(*b, datatypeSize(so.prop->count_type), swap);
          for (std::size_t j = 0; j < len; ++j) {
            sep();
            putValue(el.values.at(at++), so.prop->type, b, t);
            if (b) swapLast(*b, datatypeSize(so.prop->type), swap);
          }
        } else {
          sep();
          putValue(el.values.at(at++), so.prop->type, b, t);
          if (b) swapLast(*b, datatypeSize(so.prop->type), swap);
        }
      }
      if (t) *t += '\n';
      if (bin.size() >= kFlushBytes || txt.size() >= kFlushBytes) {
        w.write(bin.data(), bin.size());
        w.write(txt);
        bin.clear();
        txt.clear();
      }
    }
  }
  w.write(bin.data(), bin.size());
  w.write(txt);
  w.commit();
}

}  // namespace

void writePly(const std::string& path, const Shape& shape, bool ascii) {
  const auto fields = checkShape(path, shape, false);
  if (const std::vector<std::size_t> order = gridOrder(shape); plyExtrasFit(shape, order))
    return writePlyWithExtras(path, shape, ascii, fields, order);
  const pcl::PCLPointCloud2& c = shape.cloud;
  const std::size_t n = shape.size();
  if (n > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()) && !shape.polygons.empty())
    fail(path, "cannot write: too many points for int face indices");
  std::size_t max_face = 0;
  for (const auto& poly : shape.polygons) max_face = std::max(max_face, poly.vertices.size());
  const bool wide_count = max_face > 255;

  std::string h = "ply\nformat ";
  h += ascii ? "ascii" : binaryFormat(shape);
  h += " 1.0\n";
  for (const auto& line : shape.extras.ply_comments) h += line + "\n";
  h += "comment written by hgdeform\nelement vertex " + num(n) + "\n";
  for (const Field* f : fields) {
    const std::size_t cnt = fieldCount(*f);
    for (std::size_t k = 0; k < cnt; ++k) {
      h += std::string("property ") + plyTypeName(f->datatype) + " " + f->name;
      if (cnt > 1) h += "_" + num(k);
      h += "\n";
    }
  }
  if (!shape.polygons.empty()) {
    h += "element face " + num(shape.polygons.size()) + "\n";
    h += wide_count ? "property list uint int vertex_indices\n" : "property list uchar int vertex_indices\n";
  }
  h += "end_header\n";

  AtomicWriter w(path);
  w.write(h);
  if (ascii) {
    writeAsciiPoints(w, c, n, fields, false, decimalsOf(shape.extras, fields));
    std::string buf;
    appendFaceLines(w, buf, shape.polygons);
    w.write(buf);
  } else {
    const bool swap = bigEndianOut(shape) != kHostBigEndian;
    std::vector<std::uint8_t> buf;
    if (!swap) {
      writePackedBinary(w, c, n, fields);
    } else {
      for (std::size_t i = 0; i < n; ++i) {
        const std::uint8_t* pt = c.data.data() + i * c.point_step;
        for (const Field* f : fields) {
          const std::size_t sz = datatypeSize(f->datatype);
          for (std::size_t k = 0; k < fieldCount(*f); ++k) {
            buf.insert(buf.end(), pt + f->offset + k * sz, pt + f->offset + (k + 1) * sz);
            swapLast(buf, sz, true);
          }
        }
        flushIfFull(w, buf);
      }
    }
    for (const auto& poly : shape.polygons) {
      if (wide_count) {
        const auto cnt = static_cast<std::uint32_t>(poly.vertices.size());
        const auto* b = reinterpret_cast<const std::uint8_t*>(&cnt);
        buf.insert(buf.end(), b, b + sizeof cnt);
        swapLast(buf, sizeof cnt, swap);
      } else {
        buf.push_back(static_cast<std::uint8_t>(poly.vertices.size()));
      }
      for (const auto idx : poly.vertices) {
        const auto v = static_cast<std::int32_t>(idx);
        const auto* b = reinterpret_cast<const std::uint8_t*>(&v);
        buf.insert(buf.end(), b, b + sizeof v);
        swapLast(buf, sizeof v, swap);
      }
      flushIfFull(w, buf);
    }
    w.write(buf.data(), buf.size());
  }
  w.commit();
}
}  // namespace hgd::io_internal
