// Writing LAS (las.cpp describes the format and how a shape is written back).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "hgdeform/version.h"
#include "io/internal.h"
#include "io/las_layout.h"

namespace hgd::io_internal {

using las::Kind;
using las::kLasStandardSize;
using las::LasHeader;
using las::le;
using las::parseHeader;
using las::parseVlrs;
using las::Part;
using las::putLe;
using las::recordParts;
using las::standardParts;
using las::Vlr;

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
