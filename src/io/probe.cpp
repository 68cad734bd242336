// What a shape file's header says of its size, read without its data (hgd::probeShapeSize):
// for deciding before a read whether the shape fits in memory.
#include <algorithm>
#include <cstring>
#include <string>

#include "io/internal.h"

namespace hgd {

namespace {

using io_internal::InputFile;
using io_internal::lower;
using io_internal::parseU64;
using io_internal::splitWords;

/// The bytes of a PLY scalar type named as a header names it (the reader's own table); 0 when
/// it names none.
std::uint64_t plyTypeBytes(std::string_view name) {
  std::uint8_t type = 0;
  return io_internal::plyTypeFromName(name, &type) ? datatypeSize(type) : 0;
}

/// The header's lines, up to and including the one `last` names (its first word, any case).
std::vector<std::string> headerLines(InputFile& in, const char* last) {
  std::vector<std::string> lines;
  std::string line;
  while (lines.size() < 100000 && in.readLine(&line, io_internal::kMaxHeaderLine)) {
    lines.push_back(line);
    const auto w = splitWords(line);
    if (!w.empty() && lower(w[0]) == last) break;
  }
  return lines;
}

void probePly(InputFile& in, ShapeSize& s, std::uint64_t& data) {
  std::string element;
  bool fixed = true;
  for (const std::string& line : headerLines(in, "end_header")) {
    const auto w = splitWords(line);
    if (w.size() == 3 && w[0] == "format") s.binary = w[1] != "ascii";
    if (w.size() == 3 && w[0] == "element") {
      element = std::string(w[1]);
      std::uint64_t count = 0;
      if (!parseU64(w[2], &count)) continue;
      if (element == "vertex") {
        s.points = count;
        s.exact = true;
      } else if (element == "face") {
        s.faces = count;
      }
    } else if (w.size() >= 3 && w[0] == "property" && element == "vertex") {
      if (w[1] == "list") {
        fixed = false;
      } else {
        s.record_bytes += plyTypeBytes(w[1]);
      }
    }
  }
  data = in.remaining();
  if (!fixed) s.record_bytes = std::max<std::uint64_t>(s.record_bytes, 24);
}

void probePcd(InputFile& in, ShapeSize& s, std::uint64_t& data) {
  std::vector<std::uint64_t> sizes, counts;
  std::uint64_t width = 0, height = 1, points = 0;
  for (const std::string& line : headerLines(in, "data")) {
    const auto w = splitWords(line);
    if (w.empty()) continue;
    const std::string kw = lower(w[0]);
    std::vector<std::uint64_t>* list = kw == "size" ? &sizes : kw == "count" ? &counts : nullptr;
    if (list) {
      for (std::size_t k = 1; k < w.size(); ++k) {
        std::uint64_t v = 0;
        list->push_back(parseU64(w[k], &v) ? v : 0);
      }
    } else if (w.size() == 2 && kw == "data") {
      s.binary = lower(w[1]) != "ascii";
      s.compressed = lower(w[1]) == "binary_compressed";
    } else if (w.size() == 2 && (kw == "width" || kw == "height" || kw == "points")) {
      std::uint64_t v = 0;
      if (!parseU64(w[1], &v)) continue;
      (kw == "width" ? width : kw == "height" ? height : points) = v;
    }
  }
  data = in.remaining();
  if (points == 0) points = width * height;
  s.points = points;
  s.exact = points > 0;
  for (std::size_t k = 0; k < sizes.size(); ++k)
    s.record_bytes += sizes[k] * (k < counts.size() && counts[k] > 0 ? counts[k] : 1);
}

void probeLas(InputFile& in, ShapeSize& s, std::uint64_t& data) {
  std::uint8_t h[375] = {};
  const std::size_t got = static_cast<std::size_t>(std::min<std::uint64_t>(in.remaining(), sizeof h));
  in.read(h, got, "the header");
  if (got < 227) return;
  auto le = [&](std::size_t at, std::size_t bytes) {
    std::uint64_t v = 0;
    for (std::size_t b = 0; b < bytes; ++b) v |= static_cast<std::uint64_t>(h[at + b]) << (8 * b);
    return v;
  };
  s.binary = true;
  const std::uint64_t start = le(96, 4);  // the offset to the point records
  data = start < s.file_bytes ? s.file_bytes - start : 0;
  s.record_bytes = le(105, 2);
  s.points = le(107, 4);
  if (s.points == 0 && got >= 255) s.points = le(247, 8);  // LAS 1.4: the 64-bit count
  s.exact = true;
}

void probeOff(InputFile& in, ShapeSize& s) {
  std::string line;
  int numbers_seen = 0;
  while (numbers_seen == 0 && in.readLine(&line, io_internal::kMaxHeaderLine)) {
    const auto w = splitWords(line);
    if (w.empty() || w[0][0] == '#') continue;
    std::size_t k = lower(w[0]).find("off") != std::string::npos ? 1 : 0;
    if (k == 1 && w.size() == 1) continue;  // "OFF" alone: the counts follow
    std::uint64_t v = 0, f = 0;
    if (k + 1 < w.size() && parseU64(w[k], &v) && parseU64(w[k + 1], &f)) {
      s.points = v;
      s.faces = f;
      s.exact = true;
    }
    numbers_seen = 1;
  }
  s.record_bytes = 12;
}

}  // namespace

ShapeSize probeShapeSize(const std::string& path) {
  ShapeSize s;
  FileFormat format = FileFormat::Ply;
  try {
    format = sniffFormat(path);
  } catch (const IoError&) {  // missing, unreadable, of no format: readShape says which, as it reads
    return s;
  }
  InputFile in(path);
  s.format = format;
  s.file_bytes = in.size();
  std::uint64_t data = s.file_bytes;  // the bytes after the header
  try {
    switch (format) {
      case FileFormat::Ply: probePly(in, s, data); break;
      case FileFormat::Pcd: probePcd(in, s, data); break;
      case FileFormat::Las: probeLas(in, s, data); break;
      case FileFormat::Off: probeOff(in, s); break;
      case FileFormat::Stl: {
        // Binary: 50 bytes a triangle, three vertices each (shared ones merged: at most this);
        // ascii: about 250 bytes a triangle.
        std::uint8_t head[84] = {};
        const std::size_t got =
            static_cast<std::size_t>(std::min<std::uint64_t>(in.remaining(), sizeof head));
        in.read(head, got, "the header");
        const bool binary = got == 84 && std::memcmp(head, "solid", 5) != 0;
        const std::uint64_t triangles = binary ? (s.file_bytes - 84) / 50 : s.file_bytes / 250;
        s.record_bytes = 12;
        s.points = 3 * triangles;
        s.faces = triangles;
        break;
      }
      case FileFormat::Obj:
      case FileFormat::Xyz:
      case FileFormat::Pts:
        // Text rows: at least 24 bytes a point as scanners and converters write them ("x y z" at
        // six decimals), so this is at most the count; their values are read as doubles.
        s.points = s.file_bytes / 24;
        s.record_bytes = 24;
        break;
    }
  } catch (const IoError&) {  // a malformed header: readShape says what is wrong
    s.points = 0;
    s.exact = false;
  }
  // A count the file cannot hold (each point takes at least a byte; binary records their whole
  // size, compressed PCD at most a hundredth of it) is no size: the reader says what is wrong.
  const double least = s.binary ? static_cast<double>(s.record_bytes) / (s.compressed ? 100.0 : 1.0) : 1.0;
  if (static_cast<double>(s.points) * least > static_cast<double>(data)) {
    s.points = 0;
    s.exact = false;
  }
  return s;
}

}  // namespace hgd
