// A shape about to be written: its checks, and its points packed as binary or ascii rows.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "io/internal.h"
#include "util/parallel.h"

namespace hgd::io_internal {

std::vector<const Field*> checkShape(const std::string& path, const Shape& shape, bool keep_padding) {
  const pcl::PCLPointCloud2& c = shape.cloud;
  const std::size_t n = shape.size();
  std::uint64_t need = 0;
  if (!mulOk(n, c.point_step, &need) || (c.data.size() < need && !t_streamed_records))
    fail(path, "cannot write: invalid shape: " + num(c.data.size()) + " data bytes for " + num(n) +
                   " points of " + num(c.point_step) + " bytes");
  std::vector<const Field*> out;
  for (const auto& f : c.fields) {
    const std::size_t sz = datatypeSize(f.datatype);
    if (sz == 0) fail(path, "cannot write: unsupported datatype of field '" + f.name + "'");
    if (std::uint64_t{f.offset} + sz * fieldCount(f) > c.point_step)
      fail(path, "cannot write: invalid shape: field '" + f.name + "' lies outside the point");
    if (f.name.empty() || std::any_of(f.name.begin(), f.name.end(),
                                      [](char ch) { return isSpace(ch) || ch == '\n' || ch == '\0'; }))
      fail(path, "cannot write: invalid field name " + excerpt(f.name));
    if (f.name == "_" && !keep_padding) continue;
    out.push_back(&f);
  }
  if (out.empty()) fail(path, "cannot write: the shape has no fields");
  for (const auto& poly : shape.polygons)
    for (const auto idx : poly.vertices)
      if (idx < 0 || static_cast<std::uint64_t>(idx) >= n)
        fail(path, "cannot write: bad face index " + std::to_string(idx) + " (" + num(n) + " points)");
  return out;
}

bool isPacked(const std::vector<const Field*>& fields, std::uint32_t point_step) {
  std::uint64_t off = 0;
  for (const Field* f : fields) {
    if (f->offset != off) return false;
    off += datatypeSize(f->datatype) * fieldCount(*f);
  }
  return off == point_step;
}

thread_local const std::function<void(AtomicWriter&)>* t_streamed_records = nullptr;

void writePackedBinary(AtomicWriter& w, const pcl::PCLPointCloud2& c, std::size_t n,
                       const std::vector<const Field*>& fields) {
  if (t_streamed_records) {
    if (!isPacked(fields, c.point_step))
      fail(w.path(), "cannot write the records as they come: the points' fields are not written as read");
    (*t_streamed_records)(w);
    return;
  }
  if (isPacked(fields, c.point_step)) {
    w.write(c.data.data(), n * c.point_step);
    return;
  }
  std::vector<std::uint8_t> buf;
  buf.reserve(kFlushBytes + c.point_step);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* pt = c.data.data() + i * c.point_step;
    for (const Field* f : fields)
      buf.insert(buf.end(), pt + f->offset, pt + f->offset + datatypeSize(f->datatype) * fieldCount(*f));
    flushIfFull(w, buf);
  }
  w.write(buf.data(), buf.size());
}

void appendFaceLines(AtomicWriter& w, std::string& buf, const std::vector<pcl::Vertices>& polygons) {
  for (const auto& poly : polygons) {
    appendInt(buf, poly.vertices.size());
    for (const auto idx : poly.vertices) {
      buf += ' ';
      appendInt(buf, idx);
    }
    buf += '\n';
    flushIfFull(w, buf);
  }
}

void writeAsciiPoints(AtomicWriter& w, const pcl::PCLPointCloud2& c, std::size_t n,
                      const std::vector<const Field*>& fields, bool colour_bits,
                      const std::vector<FileExtras::TextColumn>& decimals, std::string_view separator) {
  std::string buf;
  buf.reserve(kFlushBytes + 1024);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* pt = c.data.data() + i * c.point_step;
    bool first = true;
    for (std::size_t fi = 0; fi < fields.size(); ++fi) {
      const Field* f = fields[fi];
      const std::size_t sz = datatypeSize(f->datatype);
      const std::uint8_t type = colour_bits && packedColour(*f) ? std::uint8_t{Field::UINT32} : f->datatype;
      int dec = 0;
      bool exp = false;
      if (fi < decimals.size()) rowSpelling(decimals[fi], i, n, &dec, &exp);
      for (std::size_t k = 0; k < fieldCount(*f); ++k) {
        if (!first) buf += separator;
        first = false;
        appendValue(buf, pt + f->offset + k * sz, type, dec, exp);
      }
    }
    buf += '\n';
    flushIfFull(w, buf);
  }
  w.write(buf);
}

}  // namespace hgd::io_internal
