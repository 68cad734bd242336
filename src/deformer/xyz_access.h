// A cloud's x/y/z read and written as doubles (internal; the writers of deformed points:
// write_deformed.cpp, streamed_write.cpp).
#pragma once

#include <pcl/PCLPointCloud2.h>

#include <Eigen/Core>
#include <cstring>

#include "hgdeform/io/fields.h"

namespace hgd {

// A shape's x/y/z read and written as doubles: straight from the record when the three share a
// floating type (a file's usual case), else through readValue/writeValue.
class XyzAccess {
 public:
  XyzAccess(pcl::PCLPointCloud2& c, const XyzFields& f)
      : c_(c),
        fx_(c.fields[static_cast<std::size_t>(f.x)]),
        fy_(c.fields[static_cast<std::size_t>(f.y)]),
        fz_(c.fields[static_cast<std::size_t>(f.z)]) {
    const std::uint8_t t = fx_.datatype;
    const bool floating = t == pcl::PCLPointField::FLOAT32 || t == pcl::PCLPointField::FLOAT64;
    type_ = floating && fy_.datatype == t && fz_.datatype == t ? t : 0;
  }
  Eigen::Vector3d get(std::size_t i) const {
    const std::uint8_t* r = c_.data.data() + i * c_.point_step;
    if (type_ == pcl::PCLPointField::FLOAT32)
      return {load<float>(r + fx_.offset), load<float>(r + fy_.offset), load<float>(r + fz_.offset)};
    if (type_ == pcl::PCLPointField::FLOAT64)
      return {load<double>(r + fx_.offset), load<double>(r + fy_.offset), load<double>(r + fz_.offset)};
    return {readValue(c_, i, fx_), readValue(c_, i, fy_), readValue(c_, i, fz_)};
  }
  void set(std::size_t i, const Eigen::Vector3d& p) {
    std::uint8_t* r = c_.data.data() + i * c_.point_step;
    if (type_ == pcl::PCLPointField::FLOAT32) {
      store(r + fx_.offset, static_cast<float>(p.x()));
      store(r + fy_.offset, static_cast<float>(p.y()));
      store(r + fz_.offset, static_cast<float>(p.z()));
    } else if (type_ == pcl::PCLPointField::FLOAT64) {
      store(r + fx_.offset, p.x());
      store(r + fy_.offset, p.y());
      store(r + fz_.offset, p.z());
    } else {
      writeValue(c_, i, fx_, p.x());
      writeValue(c_, i, fy_, p.y());
      writeValue(c_, i, fz_, p.z());
    }
  }

 private:
  template <typename T>
  static double load(const std::uint8_t* p) {
    T v;
    std::memcpy(&v, p, sizeof v);
    return static_cast<double>(v);
  }
  template <typename T>
  static void store(std::uint8_t* p, T v) {
    std::memcpy(p, &v, sizeof v);
  }
  pcl::PCLPointCloud2& c_;
  const pcl::PCLPointField &fx_, &fy_, &fz_;
  std::uint8_t type_ = 0;
};

}  // namespace hgd
