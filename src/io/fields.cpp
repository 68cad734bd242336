#include "hgdeform/io/fields.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "hgdeform/io/colormap.h"
#include "hgdeform/io/geometry.h"
#include "hgdeform/io/shape.h"
#include "io/field_codec.h"

namespace hgd {

// datatypeSize is defined with the rest of the datatype codec (io/field_codec.cpp).

int findField(const pcl::PCLPointCloud2& cloud, const std::string& name) {
  for (std::size_t i = 0; i < cloud.fields.size(); ++i)
    if (cloud.fields[i].name == name) return static_cast<int>(i);
  return -1;
}

double readValue(const pcl::PCLPointCloud2& cloud, std::size_t point, const pcl::PCLPointField& field,
                 std::size_t element) {
  const std::uint8_t* p =
      cloud.data.data() + point * cloud.point_step + field.offset + element * datatypeSize(field.datatype);
  return io_internal::decodeValue(p, field.datatype);
}

void writeValue(pcl::PCLPointCloud2& cloud, std::size_t point, const pcl::PCLPointField& field, double value,
                std::size_t element) {
  std::uint8_t* p =
      cloud.data.data() + point * cloud.point_step + field.offset + element * datatypeSize(field.datatype);
  io_internal::encodeValue(p, field.datatype, value);
}

int addFloatField(pcl::PCLPointCloud2& cloud, const std::string& name) {
  const int existing = findField(cloud, name);
  if (existing >= 0 && cloud.fields[existing].datatype == pcl::PCLPointField::FLOAT32 &&
      cloud.fields[existing].count == 1)
    return existing;
  if (existing >= 0) cloud.fields.erase(cloud.fields.begin() + existing);  // retyped below

  const std::size_t n = static_cast<std::size_t>(cloud.width) * cloud.height;
  const std::uint32_t old_step = cloud.point_step;
  // Repack without the dropped field's bytes only if one was removed; otherwise append.
  pcl::PCLPointCloud2 out = cloud;
  out.data.clear();
  std::uint32_t offset = 0;
  for (auto& f : out.fields) {
    f.offset = offset;
    offset += static_cast<std::uint32_t>(datatypeSize(f.datatype) * std::max<std::uint32_t>(f.count, 1));
  }
  pcl::PCLPointField nf;
  nf.name = name;
  nf.offset = offset;
  nf.datatype = pcl::PCLPointField::FLOAT32;
  nf.count = 1;
  out.fields.push_back(nf);
  out.point_step = offset + 4;
  out.row_step = out.point_step * out.width;
  out.data.assign(n * out.point_step, 0);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t k = 0; k + 1 < out.fields.size(); ++k) {
      const auto& nfield = out.fields[k];
      const auto& ofield = cloud.fields[k];
      const std::size_t bytes = datatypeSize(nfield.datatype) * std::max<std::uint32_t>(nfield.count, 1);
      std::memcpy(out.data.data() + i * out.point_step + nfield.offset,
                  cloud.data.data() + i * old_step + ofield.offset, bytes);
    }
  }
  cloud = std::move(out);
  return static_cast<int>(cloud.fields.size()) - 1;
}

void retypeFields(pcl::PCLPointCloud2& cloud, const std::vector<int>& fields, std::uint8_t datatype) {
  const std::size_t n = static_cast<std::size_t>(cloud.width) * cloud.height;
  // The header alone: the data is repacked, not copied first.
  std::vector<std::uint8_t> data = std::move(cloud.data);
  pcl::PCLPointCloud2 out = cloud;
  cloud.data = std::move(data);
  std::uint32_t offset = 0;  // repacked in field order, each field at its (new) size
  for (std::size_t k = 0; k < out.fields.size(); ++k) {
    auto& f = out.fields[k];
    if (std::find(fields.begin(), fields.end(), static_cast<int>(k)) != fields.end()) f.datatype = datatype;
    f.offset = offset;
    offset += static_cast<std::uint32_t>(datatypeSize(f.datatype) * std::max<std::uint32_t>(f.count, 1));
  }
  out.point_step = offset;
  out.row_step = out.point_step * out.width;
  out.data.assign(n * out.point_step, 0);
  for (std::size_t k = 0; k < out.fields.size(); ++k) {
    const auto& nf = out.fields[k];
    const auto& of = cloud.fields[k];
    const std::size_t count = std::max<std::uint32_t>(nf.count, 1);
    if (nf.datatype == of.datatype) {
      const std::size_t bytes = datatypeSize(nf.datatype) * count;
      for (std::size_t i = 0; i < n; ++i)
        std::memcpy(out.data.data() + i * out.point_step + nf.offset,
                    cloud.data.data() + i * cloud.point_step + of.offset, bytes);
    } else {
      for (std::size_t i = 0; i < n; ++i)
        for (std::size_t e = 0; e < count; ++e) writeValue(out, i, nf, readValue(cloud, i, of, e), e);
    }
  }
  cloud = std::move(out);
}

XyzFields findXyzFields(const pcl::PCLPointCloud2& cloud) {
  XyzFields f;
  f.x = findField(cloud, "x");
  f.y = findField(cloud, "y");
  f.z = findField(cloud, "z");
  f.nx = findField(cloud, "normal_x");
  f.ny = findField(cloud, "normal_y");
  f.nz = findField(cloud, "normal_z");
  if (f.nx < 0 || f.ny < 0 || f.nz < 0) {
    f.nx = findField(cloud, "nx");
    f.ny = findField(cloud, "ny");
    f.nz = findField(cloud, "nz");
  }
  return f;
}

ColourFields findColourFields(const pcl::PCLPointCloud2& cloud) {
  ColourFields c;
  const auto scalar = [&](const char* name) {
    const int k = findField(cloud, name);
    return k >= 0 && datatypeSize(cloud.fields[static_cast<std::size_t>(k)].datatype) > 0 ? k : -1;
  };
  c.red = scalar("red");
  c.green = scalar("green");
  c.blue = scalar("blue");
  if (c.red >= 0 && c.green >= 0 && c.blue >= 0) {
    const auto& r = cloud.fields[static_cast<std::size_t>(c.red)];
    const std::size_t size = datatypeSize(r.datatype);
    const bool integer =
        r.datatype != pcl::PCLPointField::FLOAT32 && r.datatype != pcl::PCLPointField::FLOAT64;
    if (integer && size == 1) {
      c.scale = 255;
    } else if (integer && size == 2) {
      c.scale = 65535;
    } else {
      double top = 0;
      const std::size_t n = static_cast<std::size_t>(cloud.width) * cloud.height;
      for (const int k : {c.red, c.green, c.blue})
        for (std::size_t i = 0; i < n && top <= 1; ++i) {
          const double v = readValue(cloud, i, cloud.fields[static_cast<std::size_t>(k)]);
          if (std::isfinite(v)) top = std::max(top, v);
        }
      c.scale = top > 1 ? 255 : 1;
    }
    return c;
  }
  c.red = c.green = c.blue = -1;
  for (const char* name : {"rgb", "rgba"}) {
    const int k = findField(cloud, name);
    if (k >= 0 && datatypeSize(cloud.fields[static_cast<std::size_t>(k)].datatype) == 4) {
      c.packed = k;
      break;
    }
  }
  return c;
}

Eigen::Vector3f readColour(const pcl::PCLPointCloud2& cloud, std::size_t point, const ColourFields& fields) {
  if (fields.red >= 0 && fields.green >= 0 && fields.blue >= 0) {
    Eigen::Vector3f c;
    const int k[3] = {fields.red, fields.green, fields.blue};
    for (int i = 0; i < 3; ++i) {
      const double v = readValue(cloud, point, cloud.fields[static_cast<std::size_t>(k[i])]) / fields.scale;
      c[i] = std::isfinite(v) ? static_cast<float>(std::clamp(v, 0.0, 1.0)) : 0.0f;
    }
    return c;
  }
  if (fields.packed >= 0) {
    std::uint32_t v;
    std::memcpy(&v,
                cloud.data.data() + point * cloud.point_step +
                    cloud.fields[static_cast<std::size_t>(fields.packed)].offset,
                4);
    return Eigen::Vector3f(static_cast<float>((v >> 16) & 255u), static_cast<float>((v >> 8) & 255u),
                           static_cast<float>(v & 255u)) /
           255.0f;
  }
  return Eigen::Vector3f(0.75f, 0.75f, 0.72f);
}

void storeField(Shape& shape, const Geometry& geometry, const std::vector<float>& values,
                const std::string& name, bool colour) {
  const int fi = addFloatField(shape.cloud, name);
  const std::size_t n = shape.size();
  for (std::size_t i = 0; i < n; ++i) {
    const int k = geometry.finite_index[i];
    writeValue(shape.cloud, i, shape.cloud.fields[static_cast<std::size_t>(fi)],
               k >= 0 ? values[static_cast<std::size_t>(k)] : std::numeric_limits<float>::quiet_NaN());
  }
  if (!colour) return;
  if (shape.format == FileFormat::Pcd || findField(shape.cloud, "rgb") >= 0) {
    const int ci = addFloatField(shape.cloud, "rgb");
    for (std::size_t i = 0; i < n; ++i) {
      const int k = geometry.finite_index[i];
      const Eigen::Vector3f c = colourMap(k >= 0 ? values[static_cast<std::size_t>(k)] : 0.0f) * 255.0f;
      const std::uint32_t packed = (static_cast<std::uint32_t>(c.x()) << 16) |
                                   (static_cast<std::uint32_t>(c.y()) << 8) |
                                   static_cast<std::uint32_t>(c.z());
      std::memcpy(shape.cloud.data.data() + i * shape.cloud.point_step +
                      shape.cloud.fields[static_cast<std::size_t>(ci)].offset,
                  &packed, 4);
    }
    return;
  }
  // PLY/OBJ: red/green/blue as uchar (reusing existing fields of those names, whatever their type).
  const char* names[3] = {"red", "green", "blue"};
  int idx[3];
  for (int c = 0; c < 3; ++c) {
    idx[c] = findField(shape.cloud, names[c]);
    if (idx[c] < 0) {
      idx[c] = addFloatField(shape.cloud, names[c]);
      shape.cloud.fields[static_cast<std::size_t>(idx[c])].datatype =
          pcl::PCLPointField::UINT8;  // first byte used
    }
  }
  const bool float_colour =
      shape.cloud.fields[static_cast<std::size_t>(idx[0])].datatype == pcl::PCLPointField::FLOAT32;
  for (std::size_t i = 0; i < n; ++i) {
    const int k = geometry.finite_index[i];
    const Eigen::Vector3f c = colourMap(k >= 0 ? values[static_cast<std::size_t>(k)] : 0.0f);
    for (int ch = 0; ch < 3; ++ch)
      writeValue(shape.cloud, i, shape.cloud.fields[static_cast<std::size_t>(idx[ch])],
                 float_colour ? c[ch] : c[ch] * 255.0f);
  }
}

}  // namespace hgd
