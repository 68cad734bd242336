// ASPRS LAS 1.0-1.4, point formats 0-10, uncompressed.
//
// Reading: every field of the point records becomes a field of the cloud, named as laspy names
// them: x y z (double: the scaled integers times the header's scale plus its offset), intensity,
// return_number, number_of_returns, scan_direction_flag, edge_of_flight_line, classification,
// synthetic, key_point, withheld, (formats 6-10: overlap, scanner_channel), scan_angle_rank
// (formats 0-5) or scan_angle (6-10), user_data, point_source_id, gps_time, red green blue
// (uint16), nir, the waveform packet's wavepacket_index, wavepacket_offset (a double: a byte
// offset, exact below 2^53), wavepacket_size, return_point_wave_location, x_t, y_t, z_t, and the
// extra bytes under the names their VLR descriptions give (raw values; undescribed bytes as the
// uint8 array extra_bytes). The header, the VLRs and everything after the points (waveform
// data, EVLRs) are kept as bytes (FileExtras::las_*).
//
// Writing back as LAS: the same header, point format, record length, VLRs and tail; each record
// from the fields. Coordinates are requantised with the file's scale and offset: an unmoved
// point gets back its exact integers (X * scale + offset, then (x - offset) / scale rounds back
// to X). When a moved point leaves what a 32-bit integer holds about the offset, the offset moves
// by a whole number of scale steps (extrasLost says so), never wraps. The header's bounds, point
// counts and points by return are recomputed from what is written.
//
// Writing another shape as LAS: version 1.4, point format 6 (7 with red green blue, 8 with nir),
// x y z quantised at a power of ten about the box's centre (a billion steps across), intensity,
// gps_time, the flags and colours where the shape has fields of those names and integer values
// that fit, and every other scalar field as extra bytes with their descriptions.
//
// LAZ (LASzip-compressed) is refused with the reason: Debian has no LASzip decoder.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "hgdeform/version.h"
#include "io/internal.h"

namespace hgd::io_internal {
namespace {

constexpr std::size_t kLasStandardSize[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};

template <typename T>
T le(const std::uint8_t* p) {
  std::uint8_t b[sizeof(T)];
  std::memcpy(b, p, sizeof b);
  if (kHostBigEndian) std::reverse(b, b + sizeof b);
  T v;
  std::memcpy(&v, b, sizeof v);
  return v;
}

template <typename T>
void putLe(std::uint8_t* p, T v) {
  std::uint8_t b[sizeof(T)];
  std::memcpy(b, &v, sizeof b);
  if (kHostBigEndian) std::reverse(b, b + sizeof b);
  std::memcpy(p, b, sizeof b);
}

/// What a part of a point record is and where the cloud keeps it.
enum class Kind {
  Coord,   ///< a scaled int32 coordinate (axis 0-2) -> FLOAT64 x/y/z
  Scalar,  ///< a value of `type` (count values) stored as it is
  Bits,    ///< `width` bits from `shift` of the byte at `offset` -> UINT8
  Wide,    ///< a uint64 or int64 -> FLOAT64 (exact below 2^53; larger refused)
};

struct Part {
  std::string name;
  Kind kind = Kind::Scalar;
  std::uint8_t type = Field::UINT8;  ///< the cloud's field type
  std::uint32_t offset = 0;          ///< in the record
  std::uint32_t count = 1;
  int axis = 0, shift = 0, width = 8;
  bool is_signed = false;  ///< Wide: int64
};

struct LasHeader {
  std::uint8_t major = 1, minor = 2, format = 0;
  std::uint16_t header_size = 0, record_length = 0;
  std::uint32_t point_offset = 0, vlr_count = 0;
  std::uint64_t points = 0;
  std::uint64_t evlr_start = 0;
  std::uint32_t evlr_count = 0;
  double scale[3] = {0.01, 0.01, 0.01}, offset[3] = {0, 0, 0};
};

LasHeader parseHeader(const std::string& path, const std::uint8_t* h, std::size_t size) {
  LasHeader r;
  r.major = h[24];
  r.minor = h[25];
  r.header_size = le<std::uint16_t>(h + 94);
  r.point_offset = le<std::uint32_t>(h + 96);
  r.vlr_count = le<std::uint32_t>(h + 100);
  r.format = h[104];
  r.record_length = le<std::uint16_t>(h + 105);
  r.points = le<std::uint32_t>(h + 107);
  for (int a = 0; a < 3; ++a) {
    r.scale[a] = le<double>(h + 131 + 8 * a);
    r.offset[a] = le<double>(h + 155 + 8 * a);
  }
  if (r.major != 1 || r.minor > 4)
    fail(path, "unsupported LAS version " + num(r.major) + "." + num(r.minor) + " (1.0-1.4 are read)");
  const std::size_t need = r.minor >= 4 ? 375 : r.minor == 3 ? 235 : 227;
  if (r.header_size < need || r.header_size > size)
    fail(path, "malformed LAS header: header size " + num(r.header_size) + " (LAS 1." + num(r.minor) +
                   " needs at least " + num(need) + ")");
  if (r.minor >= 4) {
    r.evlr_start = le<std::uint64_t>(h + 235);
    r.evlr_count = le<std::uint32_t>(h + 243);
    const std::uint64_t wide = le<std::uint64_t>(h + 247);
    if (wide != 0) r.points = wide;
  }
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(r.scale[a]) || r.scale[a] == 0 || !std::isfinite(r.offset[a]))
      fail(path, "malformed LAS header: the " + std::string(1, "xyz"[a]) + " scale or offset is " +
                     (std::isfinite(r.scale[a]) && std::isfinite(r.offset[a]) ? "0" : "not finite"));
  return r;
}

void addWavePacket(std::vector<Part>& parts, std::uint32_t at) {
  parts.push_back({"wavepacket_index", Kind::Scalar, Field::UINT8, at});
  Part off{"wavepacket_offset", Kind::Wide, Field::FLOAT64, at + 1};
  parts.push_back(off);
  parts.push_back({"wavepacket_size", Kind::Scalar, Field::UINT32, at + 9});
  parts.push_back({"return_point_wave_location", Kind::Scalar, Field::FLOAT32, at + 13});
  parts.push_back({"x_t", Kind::Scalar, Field::FLOAT32, at + 17});
  parts.push_back({"y_t", Kind::Scalar, Field::FLOAT32, at + 21});
  parts.push_back({"z_t", Kind::Scalar, Field::FLOAT32, at + 25});
}

Part bits(const char* name, std::uint32_t at, int shift, int width) {
  Part p{name, Kind::Bits, Field::UINT8, at};
  p.shift = shift;
  p.width = width;
  return p;
}

/// The standard fields of point format `f`, in record order.
std::vector<Part> standardParts(int f) {
  std::vector<Part> p;
  for (int a = 0; a < 3; ++a) {
    Part c{std::string(1, "xyz"[a]), Kind::Coord, Field::FLOAT64, static_cast<std::uint32_t>(4 * a)};
    c.axis = a;
    p.push_back(c);
  }
  p.push_back({"intensity", Kind::Scalar, Field::UINT16, 12});
  const bool has_rgb = f == 2 || f == 3 || f == 5 || f == 7 || f == 8 || f == 10;
  std::uint32_t at = 0;
  if (f < 6) {
    p.push_back(bits("return_number", 14, 0, 3));
    p.push_back(bits("number_of_returns", 14, 3, 3));
    p.push_back(bits("scan_direction_flag", 14, 6, 1));
    p.push_back(bits("edge_of_flight_line", 14, 7, 1));
    p.push_back(bits("classification", 15, 0, 5));
    p.push_back(bits("synthetic", 15, 5, 1));
    p.push_back(bits("key_point", 15, 6, 1));
    p.push_back(bits("withheld", 15, 7, 1));
    p.push_back({"scan_angle_rank", Kind::Scalar, Field::INT8, 16});
    p.push_back({"user_data", Kind::Scalar, Field::UINT8, 17});
    p.push_back({"point_source_id", Kind::Scalar, Field::UINT16, 18});
    at = 20;
    if (f == 1 || f == 3 || f == 4 || f == 5) {
      p.push_back({"gps_time", Kind::Scalar, Field::FLOAT64, 20});
      at = 28;
    }
  } else {
    p.push_back(bits("return_number", 14, 0, 4));
    p.push_back(bits("number_of_returns", 14, 4, 4));
    p.push_back(bits("synthetic", 15, 0, 1));
    p.push_back(bits("key_point", 15, 1, 1));
    p.push_back(bits("withheld", 15, 2, 1));
    p.push_back(bits("overlap", 15, 3, 1));
    p.push_back(bits("scanner_channel", 15, 4, 2));
    p.push_back(bits("scan_direction_flag", 15, 6, 1));
    p.push_back(bits("edge_of_flight_line", 15, 7, 1));
    p.push_back({"classification", Kind::Scalar, Field::UINT8, 16});
    p.push_back({"user_data", Kind::Scalar, Field::UINT8, 17});
    p.push_back({"scan_angle", Kind::Scalar, Field::INT16, 18});
    p.push_back({"point_source_id", Kind::Scalar, Field::UINT16, 20});
    p.push_back({"gps_time", Kind::Scalar, Field::FLOAT64, 22});
    at = 30;
  }
  if (has_rgb) {
    for (const char* c : {"red", "green", "blue"}) {
      p.push_back({c, Kind::Scalar, Field::UINT16, at});
      at += 2;
    }
  }
  if (f == 8 || f == 10) {
    p.push_back({"nir", Kind::Scalar, Field::UINT16, at});
    at += 2;
  }
  if (f == 4 || f == 5 || f == 9 || f == 10) addWavePacket(p, at);
  return p;
}

/// An extra-bytes descriptor's data type (1-10, and 11-30 the deprecated arrays of 2 and 3) as
/// a cloud field type and count; false for undocumented bytes (0) and unknown types.
bool extraType(int t, std::uint8_t* type, std::uint32_t* count, bool* wide, bool* is_signed) {
  if (t < 1 || t > 30) return false;
  const int base = (t - 1) % 10 + 1;
  *count = static_cast<std::uint32_t>((t - 1) / 10 + 1);
  *wide = base == 7 || base == 8;
  *is_signed = base == 8;
  static const std::uint8_t types[11] = {0,
                                         Field::UINT8,
                                         Field::INT8,
                                         Field::UINT16,
                                         Field::INT16,
                                         Field::UINT32,
                                         Field::INT32,
                                         Field::FLOAT64,
                                         Field::FLOAT64,
                                         Field::FLOAT32,
                                         Field::FLOAT64};
  *type = types[base];
  return !(*wide && *count > 1);  // arrays of 64-bit integers: kept as bytes
}

std::size_t extraSize(int t) {
  static const std::size_t sizes[11] = {0, 1, 1, 2, 2, 4, 4, 8, 8, 4, 8};
  return sizes[(t - 1) % 10 + 1] * static_cast<std::size_t>((t - 1) / 10 + 1);
}

std::string fixedString(const std::uint8_t* p, std::size_t n) {
  std::size_t len = 0;
  while (len < n && p[len] != 0) ++len;
  return std::string(reinterpret_cast<const char*>(p), len);
}

/// The VLRs of a LAS: (user id, record id, data) of each.
struct Vlr {
  std::string user;
  std::uint16_t record = 0;
  const std::uint8_t* data = nullptr;
  std::size_t size = 0;
};

std::vector<Vlr> parseVlrs(const std::string& path, const std::vector<std::uint8_t>& block,
                           std::uint32_t count) {
  std::vector<Vlr> out;
  std::size_t at = 0;
  for (std::uint32_t k = 0; k < count; ++k) {
    if (at + 54 > block.size())
      fail(path, "malformed LAS: VLR " + num(k) + " of " + num(count) + " runs past the start of the points");
    Vlr v;
    v.user = fixedString(block.data() + at + 2, 16);
    v.record = le<std::uint16_t>(block.data() + at + 18);
    v.size = le<std::uint16_t>(block.data() + at + 20);
    v.data = block.data() + at + 54;
    if (at + 54 + v.size > block.size())
      fail(path, "malformed LAS: VLR " + num(k) + " (" + excerpt(v.user) + " " + num(v.record) +
                     ") runs past the start of the points");
    at += 54 + v.size;
    out.push_back(v);
  }
  return out;
}

/// Every part of a record: the standard fields of `format`, then the extra bytes as the
/// extra-bytes VLR describes them, then any undescribed bytes as `extra_bytes`.
std::vector<Part> recordParts(const std::string& path, int format, std::size_t record_length,
                              const std::vector<Vlr>& vlrs) {
  std::vector<Part> parts = standardParts(format);
  std::size_t at = kLasStandardSize[format];
  if (record_length < at)
    fail(path, "malformed LAS header: point format " + num(static_cast<std::uint64_t>(format)) +
                   " records take " + num(at) + " bytes, the header says " + num(record_length));
  const auto taken = [&](const std::string& n) {
    return std::any_of(parts.begin(), parts.end(), [&](const Part& p) { return p.name == n; });
  };
  for (const Vlr& v : vlrs) {
    if (v.user != "LASF_Spec" || v.record != 4) continue;
    for (std::size_t d = 0; d + 192 <= v.size; d += 192) {
      const std::uint8_t* e = v.data + d;
      const int t = e[2];
      std::string name = fixedString(e + 4, 32);
      if (name.empty()) name = "extra";
      while (taken(name)) name = "extra_" + name;
      const std::size_t size = t == 0 ? e[3] : extraSize(t);
      if (t > 30 || size == 0 || at + size > record_length) break;  // the rest stays bytes
      Part p{name, Kind::Scalar, Field::UINT8, static_cast<std::uint32_t>(at)};
      bool wide = false;
      if (t == 0 || !extraType(t, &p.type, &p.count, &wide, &p.is_signed)) {
        p.type = Field::UINT8;
        p.count = static_cast<std::uint32_t>(size);
      } else if (wide) {
        p.kind = Kind::Wide;
      }
      parts.push_back(p);
      at += size;
    }
  }
  if (at < record_length) {
    std::string name = "extra_bytes";
    while (taken(name)) name = "extra_" + name;
    Part p{name, Kind::Scalar, Field::UINT8, static_cast<std::uint32_t>(at)};
    p.count = static_cast<std::uint32_t>(record_length - at);
    parts.push_back(p);
  }
  return parts;
}

}  // namespace

bool isLaz(const std::string& path) {
  const std::string e = lower(path.size() >= 4 ? path.substr(path.size() - 4) : path);
  return e == ".laz";
}

Shape readLas(const std::string& path) {
  InputFile in(path);
  const std::uint64_t size = in.size();
  if (size < 227) fail(path, "truncated data: a LAS header takes 227 bytes, the file holds " + num(size));
  std::vector<std::uint8_t> head(227);
  in.read(head.data(), head.size(), "LAS header");
  if (std::memcmp(head.data(), "LASF", 4) != 0) fail(path, "not a LAS file (no LASF signature)");
  // A header as long as it says (LAS 1.3 and 1.4 have more of it).
  const std::uint16_t header_size = le<std::uint16_t>(head.data() + 94);
  if (header_size > 227) {
    if (header_size > size) fail(path, "truncated data: the LAS header says " + num(header_size) + " bytes");
    head.resize(header_size);
    in.read(head.data() + 227, header_size - 227, "LAS header");
  }
  const LasHeader h = parseHeader(path, head.data(), head.size());
  if ((h.format & 0xC0) != 0)
    fail(path, "LASzip-compressed (LAZ, point format " + num(h.format) +
                   "): hgdeform reads uncompressed LAS only; decompress it first (laszip -i " + path +
                   " -o OUT.las, or pdal translate)");
  if (h.format > 10) fail(path, "unsupported LAS point format " + num(h.format) + " (0-10 are read)");
  if (h.point_offset < h.header_size || h.point_offset > size)
    fail(path, "malformed LAS header: the points start at byte " + num(h.point_offset) +
                   ", the header ends at " + num(h.header_size) + " and the file at " + num(size));
  std::vector<std::uint8_t> vlr_block(h.point_offset - h.header_size);
  in.read(vlr_block.data(), vlr_block.size(), "LAS VLRs");
  const std::vector<Vlr> vlrs = parseVlrs(path, vlr_block, h.vlr_count);
  for (const Vlr& v : vlrs)
    if (v.user == "laszip encoded")
      fail(path,
           "LASzip-compressed (LAZ): hgdeform reads uncompressed LAS only; decompress it first "
           "(laszip -i " +
               path + " -o OUT.las, or pdal translate)");
  const std::vector<Part> parts = recordParts(path, h.format, h.record_length, vlrs);

  std::uint64_t bytes = 0;
  if (!mulOk(h.points, h.record_length, &bytes) || bytes > in.remaining())
    fail(path, "truncated data: the header declares " + num(h.points) + " points of " + num(h.record_length) +
                   " bytes, the file holds " + num(in.remaining()) + " bytes after the VLRs");
  if (h.points == 0) fail(path, "no points: the LAS header declares 0 points");
  if (h.points > std::numeric_limits<std::uint32_t>::max())
    fail(path, "unsupported: more than 4294967295 points");
  const std::size_t n = static_cast<std::size_t>(h.points);

  Shape shape;
  pcl::PCLPointCloud2& c = shape.cloud;
  std::uint32_t step = 0;
  for (const Part& p : parts) {
    Field f;
    f.name = p.name;
    f.datatype = p.type;
    f.count = p.count;
    f.offset = step;
    step += static_cast<std::uint32_t>(datatypeSize(p.type) * p.count);
    c.fields.push_back(f);
  }
  c.width = static_cast<std::uint32_t>(n);
  c.height = 1;
  c.point_step = step;
  c.row_step = step * c.width;
  c.is_bigendian = false;
  c.data.assign(static_cast<std::size_t>(step) * n, 0);
  const std::uint8_t* records = in.take(static_cast<std::size_t>(bytes), "point records");
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* r = records + i * h.record_length;
    std::uint8_t* out = c.data.data() + i * step;
    for (std::size_t k = 0; k < parts.size(); ++k) {
      const Part& p = parts[k];
      std::uint8_t* d = out + c.fields[k].offset;
      switch (p.kind) {
        case Kind::Coord: {
          const double v = le<std::int32_t>(r + p.offset) * h.scale[p.axis] + h.offset[p.axis];
          std::memcpy(d, &v, 8);
          break;
        }
        case Kind::Bits:
          *d = static_cast<std::uint8_t>((r[p.offset] >> p.shift) & ((1u << p.width) - 1));
          break;
        case Kind::Wide: {
          const double v = p.is_signed ? static_cast<double>(le<std::int64_t>(r + p.offset))
                                       : static_cast<double>(le<std::uint64_t>(r + p.offset));
          std::memcpy(d, &v, 8);
          break;
        }
        case Kind::Scalar: {
          const std::size_t sz = datatypeSize(p.type);
          for (std::uint32_t j = 0; j < p.count; ++j) {
            std::memcpy(d + j * sz, r + p.offset + j * sz, sz);
            if (kHostBigEndian) std::reverse(d + j * sz, d + (j + 1) * sz);
          }
          break;
        }
      }
    }
  }
  shape.extras.las_header = std::move(head);
  shape.extras.las_vlrs = std::move(vlr_block);
  const std::uint64_t rest = in.remaining();
  shape.extras.las_tail.resize(static_cast<std::size_t>(rest));
  if (rest) in.read(shape.extras.las_tail.data(), shape.extras.las_tail.size(), "LAS data after the points");
  shape.format = FileFormat::Las;
  c.is_dense = true;
  return shape;
}

namespace {

/// The record layout and header of a shape written as LAS: its own (read from a LAS) or a new
/// one (LAS 1.4, format 6/7/8, extra bytes for its other fields).
struct LasPlan {
  std::vector<std::uint8_t> header, vlrs, tail;
  LasHeader h;
  std::vector<Part> parts;
  std::vector<int> field_of;         ///< per part: the cloud field it is written from, or -1 (zeros)
  std::vector<double> colour_scale;  ///< per part: 257 for uint8 colours into LAS's 16 bits, else 1
};

bool integral(const pcl::PCLPointCloud2& c, int k, double lo, double hi) {
  const Field& f = c.fields[static_cast<std::size_t>(k)];
  if (fieldCount(f) != 1) return false;
  const std::size_t n = static_cast<std::size_t>(c.width) * c.height;
  for (std::size_t i = 0; i < n; ++i) {
    const double v = readValue(c, i, f);
    if (!(v >= lo && v <= hi) || v != std::floor(v)) return false;
  }
  return true;
}

void setString(std::uint8_t* p, std::size_t n, const std::string& s) {
  std::memset(p, 0, n);
  std::memcpy(p, s.data(), std::min(n, s.size()));
}

LasPlan planFor(const std::string& path, const Shape& shape) {
  LasPlan plan;
  const pcl::PCLPointCloud2& c = shape.cloud;
  const XyzFields xyz = findXyzFields(c);
  if (!xyz.hasXyz()) fail(path, "cannot write: no x/y/z fields");
  if (shape.format == FileFormat::Las && !shape.extras.las_header.empty()) {
    plan.header = shape.extras.las_header;
    plan.vlrs = shape.extras.las_vlrs;
    plan.tail = shape.extras.las_tail;
    plan.h = parseHeader(path, plan.header.data(), plan.header.size());
    const std::vector<Vlr> vlrs = parseVlrs(path, plan.vlrs, plan.h.vlr_count);
    plan.parts = recordParts(path, plan.h.format, plan.h.record_length, vlrs);
    for (const Part& p : plan.parts) {
      plan.field_of.push_back(p.kind == Kind::Coord ? (p.axis == 0   ? xyz.x
                                                       : p.axis == 1 ? xyz.y
                                                                     : xyz.z)
                                                    : findField(c, p.name));
      plan.colour_scale.push_back(1.0);
    }
    return plan;
  }
  // A new LAS 1.4 file.
  const auto find = [&](const char* name) {
    for (std::size_t k = 0; k < c.fields.size(); ++k)
      if (lower(c.fields[k].name) == name && fieldCount(c.fields[k]) == 1) return static_cast<int>(k);
    return -1;
  };
  const int r = find("red"), g = find("green"), b = find("blue"), nir = find("nir");
  const bool rgb = r >= 0 && g >= 0 && b >= 0 && integral(c, r, 0, 65535) && integral(c, g, 0, 65535) &&
                   integral(c, b, 0, 65535);
  const int format = rgb ? (nir >= 0 && integral(c, nir, 0, 65535) ? 8 : 7) : 6;
  plan.parts = standardParts(format);
  std::vector<char> used(c.fields.size(), 0);
  used[static_cast<std::size_t>(xyz.x)] = used[static_cast<std::size_t>(xyz.y)] =
      used[static_cast<std::size_t>(xyz.z)] = 1;
  const bool bytes = rgb && c.fields[static_cast<std::size_t>(r)].datatype == Field::UINT8;
  for (const Part& p : plan.parts) {
    int k = -1;
    if (p.kind == Kind::Coord) {
      k = p.axis == 0 ? xyz.x : p.axis == 1 ? xyz.y : xyz.z;
    } else {
      k = find(p.name.c_str());
      if (p.name == "intensity" && k < 0) k = find("scalar_intensity");
      double lo = 0, hi = 0;
      const bool real = p.type == Field::FLOAT64;
      if (p.kind == Kind::Bits) hi = (1 << p.width) - 1;
      if (p.kind == Kind::Scalar && !real) {
        lo = p.type == Field::INT8 ? -128 : p.type == Field::INT16 ? -32768 : 0;
        hi = p.type == Field::UINT8   ? 255
             : p.type == Field::INT8  ? 127
             : p.type == Field::INT16 ? 32767
                                      : 65535;
      }
      if (k >= 0 && !real && !integral(c, k, lo, hi)) k = -1;  // kept as extra bytes instead
      if (k >= 0 && real && fieldCount(c.fields[static_cast<std::size_t>(k)]) != 1) k = -1;
    }
    if (k >= 0) used[static_cast<std::size_t>(k)] = 1;
    plan.field_of.push_back(k);
    const bool colour = p.name == "red" || p.name == "green" || p.name == "blue";
    plan.colour_scale.push_back(colour && bytes ? 257.0 : 1.0);
  }
  // Every other scalar field: extra bytes.
  std::vector<std::uint8_t> descriptors;
  std::uint32_t at = static_cast<std::uint32_t>(kLasStandardSize[format]);
  for (std::size_t k = 0; k < c.fields.size(); ++k) {
    const Field& f = c.fields[k];
    if (used[k] || f.name == "_" || fieldCount(f) != 1) continue;
    static const int code[9] = {0, 2, 1, 4, 3, 6, 5, 9, 10};  // PCL datatype 1-8 -> LAS data type
    if (f.datatype < 1 || f.datatype > 8) continue;
    Part p{f.name, Kind::Scalar, f.datatype, at};
    plan.parts.push_back(p);
    plan.field_of.push_back(static_cast<int>(k));
    plan.colour_scale.push_back(1.0);
    at += static_cast<std::uint32_t>(datatypeSize(f.datatype));
    std::uint8_t d[192] = {};
    d[2] = static_cast<std::uint8_t>(code[f.datatype]);
    setString(d + 4, 32, f.name);
    setString(d + 160, 32, "from " + f.name);
    descriptors.insert(descriptors.end(), d, d + 192);
  }
  if (at > 65535)
    fail(path, "cannot write: the fields take " + num(at) + " bytes a point, more than LAS holds");
  if (!descriptors.empty()) {
    if (descriptors.size() > 65535) fail(path, "cannot write: too many fields for LAS's extra bytes");
    std::uint8_t v[54] = {};
    setString(v + 2, 16, "LASF_Spec");
    putLe<std::uint16_t>(v + 18, 4);
    putLe<std::uint16_t>(v + 20, static_cast<std::uint16_t>(descriptors.size()));
    setString(v + 22, 32, "extra bytes");
    plan.vlrs.assign(v, v + 54);
    plan.vlrs.insert(plan.vlrs.end(), descriptors.begin(), descriptors.end());
  }
  plan.header.assign(375, 0);
  std::uint8_t* hd = plan.header.data();
  std::memcpy(hd, "LASF", 4);
  putLe<std::uint16_t>(hd + 6, 16);  // global encoding: WKT CRS (none given)
  hd[24] = 1;
  hd[25] = 4;
  setString(hd + 26, 32, "hgdeform");
  setString(hd + 58, 32, std::string("hgdeform ") + hgd::version());
  putLe<std::uint16_t>(hd + 94, 375);
  putLe<std::uint32_t>(hd + 96, static_cast<std::uint32_t>(375 + plan.vlrs.size()));
  putLe<std::uint32_t>(hd + 100, descriptors.empty() ? 0u : 1u);
  hd[104] = static_cast<std::uint8_t>(format);
  putLe<std::uint16_t>(hd + 105, static_cast<std::uint16_t>(at));
  // Scale: a power of ten giving about a billion steps across the shape; offset: the box's centre.
  const std::size_t n = shape.size();
  for (int a = 0; a < 3; ++a) {
    const Field& f = c.fields[static_cast<std::size_t>(a == 0 ? xyz.x : a == 1 ? xyz.y : xyz.z)];
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (std::size_t i = 0; i < n; ++i) {
      const double v = readValue(c, i, f);
      if (std::isfinite(v)) {
        lo = std::min(lo, v);
        hi = std::max(hi, v);
      }
    }
    if (!(lo <= hi)) lo = hi = 0;
    // No finer than what a double holds at these coordinates (X * scale + offset must come back
    // to within half a step): a georeferenced 4.2e6 gets 1e-7, not 1e-9.
    const double extent = std::max(hi - lo, 1e-9), magnitude = std::max(std::abs(lo), std::abs(hi));
    const double scale = std::pow(10.0, std::ceil(std::log10(std::max(extent / 1e9, magnitude * 1e-14))));
    const double offset = std::round((lo + hi) / 2 / scale) * scale;
    putLe<double>(hd + 131 + 8 * a, scale);
    putLe<double>(hd + 155 + 8 * a, offset);
  }
  plan.h = parseHeader(path, hd, plan.header.size());
  plan.h.record_length = static_cast<std::uint16_t>(at);
  return plan;
}

/// The integers of each point's coordinates (first pass), with the offsets moved where a point
/// would leave 32 bits; what moved, as text ("" if nothing).
std::string quantise(const pcl::PCLPointCloud2& c, const LasPlan& plan, std::vector<std::int64_t>* q,
                     double offsets[3], const std::string& path) {
  const std::size_t n = static_cast<std::size_t>(c.width) * c.height;
  q->assign(3 * n, 0);
  std::string moved;
  for (int a = 0; a < 3; ++a) {
    offsets[a] = plan.h.offset[a];
    std::size_t k = 0;
    while (plan.parts[k].kind != Kind::Coord || plan.parts[k].axis != a) ++k;
    const Field& f = c.fields[static_cast<std::size_t>(plan.field_of[k])];
    std::int64_t lo = std::numeric_limits<std::int64_t>::max(), hi = std::numeric_limits<std::int64_t>::min();
    for (std::size_t i = 0; i < n; ++i) {
      const double v = readValue(c, i, f);
      if (!std::isfinite(v))
        fail(path, "cannot write: LAS holds no point that is not finite (point " + num(i) + ")");
      const double s = std::round((v - offsets[a]) / plan.h.scale[a]);
      if (!(std::abs(s) < 9e15))
        fail(path, "cannot write: point " + num(i) + "'s " + std::string(1, "xyz"[a]) +
                       " is beyond what the LAS scale can count");
      (*q)[3 * i + static_cast<std::size_t>(a)] = static_cast<std::int64_t>(s);
      lo = std::min(lo, static_cast<std::int64_t>(s));
      hi = std::max(hi, static_cast<std::int64_t>(s));
    }
    if (lo < std::numeric_limits<std::int32_t>::min() || hi > std::numeric_limits<std::int32_t>::max()) {
      const std::int64_t shift = lo + (hi - lo) / 2;
      if (hi - lo > std::int64_t{0xFFFFFFFF})
        fail(path, "cannot write: the points span more " + std::string(1, "xyz"[a]) +
                       " than 2^32 steps of the LAS scale " + std::to_string(plan.h.scale[a]));
      const double before = offsets[a];
      offsets[a] += static_cast<double>(shift) * plan.h.scale[a];
      for (std::size_t i = 0; i < n; ++i) (*q)[3 * i + static_cast<std::size_t>(a)] -= shift;
      char text[160];
      std::snprintf(text, sizeof text,
                    "%s the LAS %c offset moves from %.17g to %.17g so that every point fits",
                    moved.empty() ? "" : ";", "xyz"[a], before, offsets[a]);
      moved += text;
    }
  }
  return moved;
}

}  // namespace

std::string lasLosses(const Shape& shape) {
  if (!findXyzFields(shape.cloud).hasXyz() || shape.size() == 0) return "";
  try {
    const LasPlan plan = planFor(shape.path.empty() ? "LAS" : shape.path, shape);
    std::vector<std::int64_t> q;
    double offsets[3];
    std::string moved = quantise(shape.cloud, plan, &q, offsets, shape.path);
    std::string lost;
    std::vector<char> kept(shape.cloud.fields.size(), 0);
    for (const int k : plan.field_of)
      if (k >= 0) kept[static_cast<std::size_t>(k)] = 1;
    for (std::size_t k = 0; k < shape.cloud.fields.size(); ++k)
      if (!kept[k] && shape.cloud.fields[k].name != "_")
        lost += (lost.empty() ? "" : ", ") + shape.cloud.fields[k].name;
    std::string out = lost.empty() ? "" : "LAS cannot hold the fields " + lost;
    if (!moved.empty()) out += (out.empty() ? "" : "; ") + moved.substr(moved[0] == ';' ? 1 : 0);
    return out;
  } catch (const IoError&) {
    return "";  // writeLas says what is wrong
  }
}

void writeLas(const std::string& path, const Shape& shape) {
  if (isLaz(path)) fail(path, "cannot write LAZ (LASzip): Debian has no LASzip encoder; write .las");
  const LasPlan plan = planFor(path, shape);
  const pcl::PCLPointCloud2& c = shape.cloud;
  const std::size_t n = shape.size();
  if (n > std::numeric_limits<std::uint32_t>::max() && plan.h.minor < 4)
    fail(path, "cannot write: LAS 1." + num(plan.h.minor) + " holds at most 4294967295 points");
  std::vector<std::int64_t> q;
  double offsets[3];
  quantise(c, plan, &q, offsets, path);

  // The header made true: offsets, bounds, counts.
  std::vector<std::uint8_t> header = plan.header;
  std::uint8_t* hd = header.data();
  double lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    putLe<double>(hd + 155 + 8 * a, offsets[a]);
    lo[a] = std::numeric_limits<double>::infinity();
    hi[a] = -lo[a];
  }
  std::array<std::uint64_t, 15> by_return{};
  std::size_t return_part = plan.parts.size();
  for (std::size_t k = 0; k < plan.parts.size(); ++k)
    if (plan.parts[k].name == "return_number" && plan.parts[k].kind == Kind::Bits) return_part = k;
  const std::uint32_t length = plan.h.record_length;
  putLe<std::uint32_t>(hd + 96, static_cast<std::uint32_t>(header.size() + plan.vlrs.size()));
  // The records first (the header's bounds and counts come from them), then all in order.
  std::vector<std::uint8_t> body(static_cast<std::size_t>(length) * n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint8_t* r = body.data() + i * length;
    for (std::size_t k = 0; k < plan.parts.size(); ++k) {
      const Part& p = plan.parts[k];
      const int fk = plan.field_of[k];
      if (p.kind == Kind::Coord) {
        const std::int64_t v = q[3 * i + static_cast<std::size_t>(p.axis)];
        putLe<std::int32_t>(r + p.offset, static_cast<std::int32_t>(v));
        const double world = static_cast<double>(v) * plan.h.scale[p.axis] + offsets[p.axis];
        lo[p.axis] = std::min(lo[p.axis], world);
        hi[p.axis] = std::max(hi[p.axis], world);
        continue;
      }
      if (fk < 0) continue;
      const Field& f = c.fields[static_cast<std::size_t>(fk)];
      const std::uint8_t* src = c.data.data() + i * c.point_step + f.offset;
      if (p.kind == Kind::Bits) {
        const double v = readValue(c, i, f);
        const auto bitsv = static_cast<unsigned>(std::clamp(v, 0.0, double((1u << p.width) - 1)));
        r[p.offset] = static_cast<std::uint8_t>(r[p.offset] | (bitsv << p.shift));
        // A return number of 0 (no return number: Global Mapper writes them) counts as a first
        // return, as the writers of such files count it in their headers.
        if (k == return_part && bitsv <= 15) ++by_return[bitsv == 0 ? 0 : bitsv - 1];
      } else if (p.kind == Kind::Wide) {
        const double v = readValue(c, i, f);
        if (p.is_signed)
          putLe<std::int64_t>(r + p.offset, static_cast<std::int64_t>(v));
        else
          putLe<std::uint64_t>(r + p.offset, static_cast<std::uint64_t>(std::max(v, 0.0)));
      } else if (f.datatype == p.type && fieldCount(f) == p.count && plan.colour_scale[k] == 1.0) {
        const std::size_t sz = datatypeSize(p.type);
        for (std::uint32_t j = 0; j < p.count; ++j) {
          std::memcpy(r + p.offset + j * sz, src + j * sz, sz);
          if (kHostBigEndian != c.is_bigendian)
            std::reverse(r + p.offset + j * sz, r + p.offset + (j + 1) * sz);
        }
      } else {  // another type (a shape from another format): converted
        encodeValue(r + p.offset, p.type, readValue(c, i, f) * plan.colour_scale[k]);
        if (kHostBigEndian) std::reverse(r + p.offset, r + p.offset + datatypeSize(p.type));
      }
    }
  }
  for (int a = 0; a < 3; ++a) {
    putLe<double>(hd + 179 + 16 * a, hi[a]);
    putLe<double>(hd + 187 + 16 * a, lo[a]);
  }
  // Counts: the legacy fields where the file used them (formats 0-5, and a 1.4 file of formats
  // 6-10 whose writer filled them; a new file of formats 6-10 leaves them 0, as LAS 1.4 says).
  const bool legacy = (plan.h.format < 6 || le<std::uint32_t>(plan.header.data() + 107) != 0) &&
                      n <= std::numeric_limits<std::uint32_t>::max();
  putLe<std::uint32_t>(hd + 107, legacy ? static_cast<std::uint32_t>(n) : 0u);
  for (int k = 0; k < 5; ++k)
    putLe<std::uint32_t>(hd + 111 + 4 * k,
                         legacy ? static_cast<std::uint32_t>(by_return[static_cast<std::size_t>(k)]) : 0u);
  if (plan.h.minor >= 4) {
    putLe<std::uint64_t>(hd + 247, n);
    for (int k = 0; k < 15; ++k)
      putLe<std::uint64_t>(hd + 255 + 8 * k, by_return[static_cast<std::size_t>(k)]);
  }
  AtomicWriter w(path);
  w.write(header.data(), header.size());
  w.write(plan.vlrs.data(), plan.vlrs.size());
  w.write(body.data(), body.size());
  w.write(plan.tail.data(), plan.tail.size());
  w.commit();
}

}  // namespace hgd::io_internal
