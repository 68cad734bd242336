// LAS layouts: the header block, the VLRs and the parts of a point record (io/las_layout.h).
#include "io/las_layout.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

namespace hgd::io_internal::las {

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

namespace {

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

}  // namespace

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

namespace {

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

}  // namespace

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

}  // namespace hgd::io_internal::las
