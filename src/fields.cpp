#include "hgdeform/fields.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

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

}  // namespace hgd
