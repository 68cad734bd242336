// Clouds the readers and writers build and convert: a format's conventional fields from
// another's, the dense flag, and a cloud from a table of values.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <unordered_map>

#include "io/internal.h"
#include "util/parallel.h"

namespace hgd::io_internal {

bool unitColours(const pcl::PCLPointCloud2& c, std::initializer_list<long> channels) {
  const std::size_t n = static_cast<std::size_t>(c.width) * c.height;
  for (const long k : channels) {
    const Field& f = c.fields[static_cast<std::size_t>(k)];
    if ((f.datatype != Field::FLOAT32 && f.datatype != Field::FLOAT64) || fieldCount(f) != 1) return false;
    for (std::size_t i = 0; i < n; ++i) {
      const double v = readValue(c, i, f);
      if (std::isnan(v)) continue;  // a NaN point's (an organized scan's empty pixel): no colour
      if (!(v >= 0 && v <= 1)) return false;
    }
  }
  return true;
}

std::vector<std::size_t> rangeGridPixels(const FileExtras& extras, std::uint64_t vertices) {
  const FileExtras::Element* grid = nullptr;
  for (const auto& el : extras.ply_elements)
    if (el.name == "range_grid") grid = &el;
  if (!grid || vertices == 0 || grid->props.size() != 1 || !grid->props[0].list || grid->kept.size() != 1 ||
      !grid->kept[0] || grid->count < vertices)
    return {};
  constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();
  std::vector<std::size_t> pixel(static_cast<std::size_t>(vertices), kNone);
  const std::vector<double>& v = grid->values;
  std::size_t at = 0, named = 0;
  for (std::uint64_t k = 0; k < grid->count; ++k) {
    if (at >= v.size()) return {};
    const double len = v[at++];
    if (len == 0) continue;
    if (len != 1 || at >= v.size()) return {};
    const double idx = v[at++];
    if (!(idx >= 0 && idx < static_cast<double>(vertices)) || idx != std::floor(idx)) return {};
    std::size_t& p = pixel[static_cast<std::size_t>(idx)];
    if (p != kNone) return {};
    p = static_cast<std::size_t>(k);
    ++named;
  }
  if (named != vertices || at != v.size()) return {};
  return pixel;
}

bool conventionalCloud(const Shape& shape, FileFormat target, pcl::PCLPointCloud2* out) {
  if (shape.format == target || target == FileFormat::Stl) return false;
  const pcl::PCLPointCloud2& c = shape.cloud;
  const std::vector<Field>& in = c.fields;
  std::unordered_map<std::string, std::size_t> exact;  // name -> first field of that name
  std::vector<std::string> low(in.size());
  for (std::size_t k = 0; k < in.size(); ++k) {
    exact.emplace(in[k].name, k);
    low[k] = lower(in[k].name);
  }
  const auto scalarOf = [&](std::size_t k) {
    return fieldCount(in[k]) == 1 && datatypeSize(in[k].datatype) > 0;
  };
  std::vector<std::string> name(in.size());
  for (std::size_t k = 0; k < in.size(); ++k) name[k] = in[k].name;
  std::vector<char> narrow(in.size(), 0);  // double fields written as float
  bool changed = false;
  // The first field whose name is one of `aliases` (any case), unless a field is called `to`.
  const auto findAlias = [&](std::initializer_list<const char*> aliases, const char* to) -> long {
    if (exact.count(to)) return -1;
    for (std::size_t k = 0; k < in.size(); ++k)
      for (const char* a : aliases)
        if (low[k] == a && scalarOf(k)) return static_cast<long>(k);
    return -1;
  };
  const bool ply = target == FileFormat::Ply, pcd = target == FileFormat::Pcd;
  if (ply || pcd) {
    static const char* const normal_names[2][3] = {{"nx", "ny", "nz"}, {"normal_x", "normal_y", "normal_z"}};
    long idx[3];
    for (int a = 0; a < 3; ++a)
      idx[a] = findAlias({normal_names[0][a], normal_names[1][a]}, normal_names[pcd ? 1 : 0][a]);
    if (idx[0] >= 0 && idx[1] >= 0 && idx[2] >= 0)
      for (int a = 0; a < 3; ++a) {
        name[static_cast<std::size_t>(idx[a])] = normal_names[pcd ? 1 : 0][a];
        // PCD normals are floats: PCL's typed readers and Open3D's binary reader see no
        // double ones (extrasLost says so).
        if (pcd && in[static_cast<std::size_t>(idx[a])].datatype == Field::FLOAT64)
          narrow[static_cast<std::size_t>(idx[a])] = 1;
      }
    const long i = findAlias({"intensity", "scalar_intensity"}, "intensity");
    if (i >= 0) name[static_cast<std::size_t>(i)] = "intensity";
    const long cv = findAlias({"curvature", "scalar_curvature"}, "curvature");
    if (cv >= 0) name[static_cast<std::size_t>(cv)] = "curvature";
  }
  // PLY's readers (MeshLab, Open3D, CloudCompare, PCL) take colours as uchar, and OFF's (Open3D,
  // MeshLab) as 0..255 whatever their spelling: colours of 0..1 floats (an OBJ's, an XYZ's)
  // become 0..255 (extrasLost says so).
  std::vector<char> unit_colour(in.size(), 0);
  if (ply || target == FileFormat::Off) {
    const long r = exact.count("red") ? static_cast<long>(exact["red"]) : -1,
               gr = exact.count("green") ? static_cast<long>(exact["green"]) : -1,
               b = exact.count("blue") ? static_cast<long>(exact["blue"]) : -1;
    if (r >= 0 && gr >= 0 && b >= 0 && unitColours(c, {r, gr, b}))
      for (const long k : {r, gr, b}) unit_colour[static_cast<std::size_t>(k)] = 1;
    const long al = exact.count("alpha") ? static_cast<long>(exact["alpha"]) : -1;
    if (al >= 0 && r >= 0 && unit_colour[static_cast<std::size_t>(r)] && unitColours(c, {al}))
      unit_colour[static_cast<std::size_t>(al)] = 1;  // an RGBA of 0..1 floats: its alpha too
  }
  if (target == FileFormat::Pts) {
    const long i = findAlias({"intensity", "scalar_intensity"}, "intensity");
    if (i >= 0) name[static_cast<std::size_t>(i)] = "intensity";
  }
  for (std::size_t k = 0; k < in.size(); ++k)
    changed = changed || name[k] != in[k].name || narrow[k] || unit_colour[k];

  // The fields written, each a copy of a field (renamed), a byte of a packed colour, or a
  // packed colour made of red/green/blue(/alpha) bytes.
  struct Part {
    Field f;
    long src = -1;                    // a field copied
    int shift = -1;                   // a byte of the packed colour `src`
    long rgba[4] = {-1, -1, -1, -1};  // packed from these bytes
    bool narrow = false;              // `src` is a double, written as a float
    bool unit_colour = false;         // `src` is a 0..1 colour, written as a byte
  };
  std::vector<Part> parts;
  const auto byteField = [&](const char* n) {
    const auto it = exact.find(n);
    return it != exact.end() && scalarOf(it->second) && in[it->second].datatype == Field::UINT8
               ? static_cast<long>(it->second)
               : -1L;
  };
  long packed = -1;  // a packed colour (its bits: only PCD and PLY files hold one) to split
  if (!pcd && (shape.format == FileFormat::Pcd || shape.format == FileFormat::Ply)) {
    for (const char* n : {"rgb", "rgba"}) {
      const auto it = exact.find(n);
      if (packed < 0 && it != exact.end() && scalarOf(it->second) &&
          datatypeSize(in[it->second].datatype) == 4 && in[it->second].datatype != Field::INT32)
        packed = static_cast<long>(it->second);
    }
    if (packed >= 0 && (exact.count("red") || exact.count("green") || exact.count("blue") ||
                        (in[static_cast<std::size_t>(packed)].name == "rgba" && exact.count("alpha"))))
      packed = -1;
  }
  long pack[4] = {-1, -1, -1, -1};  // red, green, blue, alpha to pack
  if (pcd && !exact.count("rgb") && !exact.count("rgba")) {
    pack[0] = byteField("red");
    pack[1] = byteField("green");
    pack[2] = byteField("blue");
    pack[3] = byteField("alpha");
    if (pack[0] < 0 || pack[1] < 0 || pack[2] < 0) pack[0] = pack[1] = pack[2] = pack[3] = -1;
  }
  const auto packedPart = [&](long k) { return k == pack[1] || k == pack[2] || k == pack[3]; };
  for (std::size_t k = 0; k < in.size(); ++k) {
    const long kl = static_cast<long>(k);
    if (kl == packed) {
      // rgba has an alpha. rgb's alpha byte means nothing to PCL, which writes it as 255 or as
      // 0 (a cloud converted from PLY): either for every point is no alpha (an alpha of 0 would
      // show every point transparent in MeshLab); any other alpha is kept.
      bool alpha = in[k].name == "rgba";
      const std::size_t npts = static_cast<std::size_t>(c.width) * c.height;
      const auto alphaOf = [&](std::size_t i) {
        return c.data[i * c.point_step + in[k].offset + (kHostBigEndian ? 0 : 3)];
      };
      for (std::size_t i = 0; i < npts && !alpha; ++i)
        alpha = alphaOf(i) != alphaOf(0) || (alphaOf(i) != 0 && alphaOf(i) != 255);
      const char* const channel[4] = {"red", "green", "blue", "alpha"};
      const int shifts[4] = {16, 8, 0, 24};
      for (int j = 0; j < (alpha ? 4 : 3); ++j) {
        Part p;
        p.f.name = channel[j];
        p.f.datatype = Field::UINT8;
        p.f.count = 1;
        p.src = kl;
        p.shift = shifts[j];
        parts.push_back(p);
      }
      changed = true;
    } else if (pack[0] >= 0 && kl == pack[0]) {
      Part p;
      p.f.name = pack[3] >= 0 ? "rgba" : "rgb";
      p.f.datatype = pack[3] >= 0 ? Field::UINT32 : Field::FLOAT32;
      p.f.count = 1;
      std::copy(pack, pack + 4, p.rgba);
      parts.push_back(p);
      changed = true;
    } else if (pack[0] >= 0 && packedPart(kl)) {
      continue;
    } else {
      Part p;
      p.f = in[k];
      p.f.name = name[k];
      p.src = kl;
      if (narrow[k]) {
        p.f.datatype = Field::FLOAT32;
        p.narrow = true;
      }
      if (unit_colour[k]) {
        p.f.datatype = Field::UINT8;
        p.unit_colour = true;
      }
      parts.push_back(p);
    }
  }
  if (!changed) return false;

  pcl::PCLPointCloud2 r;
  r.header = c.header;
  r.width = c.width;
  r.height = c.height;
  r.is_bigendian = c.is_bigendian;
  r.is_dense = c.is_dense;
  std::uint32_t step = 0;
  for (Part& p : parts) {
    p.f.offset = step;
    step += static_cast<std::uint32_t>(datatypeSize(p.f.datatype) * fieldCount(p.f));
    r.fields.push_back(p.f);
  }
  r.point_step = step;
  r.row_step = step * r.width;
  const std::size_t n = static_cast<std::size_t>(c.width) * c.height;
  r.data.assign(n * step, 0);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* src = c.data.data() + i * c.point_step;
    std::uint8_t* dst = r.data.data() + i * step;
    for (const Part& p : parts) {
      std::uint8_t* d = dst + p.f.offset;
      if (p.shift >= 0) {
        std::uint32_t bits = 0;
        std::memcpy(&bits, src + in[static_cast<std::size_t>(p.src)].offset, 4);
        *d = static_cast<std::uint8_t>((bits >> p.shift) & 0xFFu);
      } else if (p.unit_colour) {
        const double v = readValue(c, i, in[static_cast<std::size_t>(p.src)]);
        *d = std::isnan(v) ? std::uint8_t{0}
                           : static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0, 1.0) * 255.0));
      } else if (p.narrow) {
        double v;
        std::memcpy(&v, src + in[static_cast<std::size_t>(p.src)].offset, 8);
        const auto f = static_cast<float>(v);
        std::memcpy(d, &f, 4);
      } else if (p.src >= 0) {
        const Field& f = in[static_cast<std::size_t>(p.src)];
        std::memcpy(d, src + f.offset, datatypeSize(f.datatype) * fieldCount(f));
      } else {
        const auto byte = [&](int j) -> std::uint32_t {
          return p.rgba[j] < 0 ? 255u : src[in[static_cast<std::size_t>(p.rgba[j])].offset];
        };
        const std::uint32_t bits = byte(3) << 24 | byte(0) << 16 | byte(1) << 8 | byte(2);
        std::memcpy(d, &bits, 4);
      }
    }
  }
  *out = std::move(r);
  return true;
}

bool computeDense(const pcl::PCLPointCloud2& cloud) {
  const XyzFields xyz = findXyzFields(cloud);
  if (!xyz.hasXyz()) return true;
  const std::size_t n = static_cast<std::size_t>(cloud.width) * cloud.height;
  // One pass over the records, on every thread (three passes of a value decoder per field cost
  // 45 ms of a 4M-point read).
  std::vector<const Field*> fields;
  for (const int idx : {xyz.x, xyz.y, xyz.z}) {
    const Field& f = cloud.fields[static_cast<std::size_t>(idx)];
    if (f.datatype == Field::FLOAT32 || f.datatype == Field::FLOAT64) fields.push_back(&f);
  }
  if (fields.empty() || n == 0) return true;
  const std::uint8_t* data = cloud.data.data();
  const std::size_t step = cloud.point_step;
  const int blocks = blockCount(static_cast<long long>(n));
  std::vector<char> finite(static_cast<std::size_t>(blocks), 1);
  // (Block bounds in 64 bits: a PLY may hold up to 2^32 - 1 vertices.)
#pragma omp parallel for schedule(static, 1) num_threads(blocks) if (blocks > 1)
  for (int b = 0; b < blocks; ++b) {
    const auto begin = static_cast<std::size_t>(blockStart(static_cast<long long>(n), blocks, b));
    const auto end = static_cast<std::size_t>(blockStart(static_cast<long long>(n), blocks, b + 1));
    for (std::size_t i = begin; i < end && finite[static_cast<std::size_t>(b)]; ++i)
      for (const Field* f : fields) {
        const std::uint8_t* p = data + i * step + f->offset;
        bool ok;
        if (f->datatype == Field::FLOAT32) {
          float v;
          std::memcpy(&v, p, sizeof v);
          ok = std::isfinite(v);
        } else {
          double v;
          std::memcpy(&v, p, sizeof v);
          ok = std::isfinite(v);
        }
        if (!ok) {
          finite[static_cast<std::size_t>(b)] = 0;
          break;
        }
      }
  }
  return std::find(finite.begin(), finite.end(), 0) == finite.end();
}

pcl::PCLPointCloud2 makeCloud(std::size_t n, const std::vector<std::pair<std::string, std::uint8_t>>& fields,
                              const std::vector<double>& values) {
  pcl::PCLPointCloud2 cloud;
  std::uint32_t step = 0;
  for (const auto& [name, type] : fields) {
    Field f;
    f.name = name;
    f.offset = step;
    f.datatype = type;
    f.count = 1;
    step += static_cast<std::uint32_t>(datatypeSize(type));
    cloud.fields.push_back(f);
  }
  cloud.width = static_cast<std::uint32_t>(n);
  cloud.height = 1;
  cloud.point_step = step;
  cloud.row_step = step * cloud.width;
  cloud.is_bigendian = false;
  cloud.data.resize(n * step);
  const std::size_t nf = fields.size();
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t k = 0; k < nf; ++k)
      encodeValue(cloud.data.data() + i * step + cloud.fields[k].offset, cloud.fields[k].datatype,
                  values[i * nf + k]);
  cloud.is_dense = computeDense(cloud);
  return cloud;
}

}  // namespace hgd::io_internal
