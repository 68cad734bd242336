// Blocks of a file's records decoded as extractGeometry reads them (internal; the streamed
// build's passes).
#pragma once

#include <pcl/PCLPointCloud2.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "hgdeform/io/fields.h"
#include "hgdeform/io/io.h"
#include "hgdeform/io/records.h"

namespace hgd::stream {

/// The records of a layout in blocks, each decoded as a one-row cloud of the file's fields.
class Blocks {
 public:
  Blocks(const RecordLayout& layout, std::size_t block)
      : reader_(layout), block_(std::max<std::size_t>(1, block)), share_{0, layout.count} {
    cloud_.fields = layout.shape.cloud.fields;
    cloud_.point_step = layout.bytes;
    cloud_.height = 1;
    cloud_.is_bigendian = false;
    xyz_ = findXyzFields(cloud_);
    if (!xyz_.hasXyz()) throw IoError(layout.shape.path + ": no x/y/z fields");
  }
  /// Reads only records [first, last) in each() and strided() (a rank's share).
  void share(const RecordShare& s) { share_ = s; }
  /// Calls fn(record, k) for every record of the share, cloud() holding its block (k its row
  /// there).
  template <typename Fn>
  void each(Fn&& fn) {
    const std::uint64_t n = share_.last;
    for (std::uint64_t first = share_.first; first < n; first += block_) {
      const auto count = static_cast<std::size_t>(std::min<std::uint64_t>(block_, n - first));
      load(first, count);
      for (std::size_t k = 0; k < count; ++k) fn(first + k, k);
    }
  }
  /// Calls fn(record, k) for the share's records at multiples of `stride` (read alone when far
  /// apart).
  template <typename Fn>
  void strided(std::uint64_t stride, Fn&& fn) {
    if (stride <= 16) {
      each([&](std::uint64_t i, std::size_t k) {
        if (i % stride == 0) fn(i, k);
      });
      return;
    }
    for (std::uint64_t i = (share_.first + stride - 1) / stride * stride; i < share_.last; i += stride) {
      load(i, 1);
      fn(i, std::size_t{0});
    }
  }
  /// Loads `count` records from `first` as the cloud.
  void load(std::uint64_t first, std::size_t count) {
    cloud_.width = static_cast<std::uint32_t>(count);
    cloud_.row_step = cloud_.point_step * cloud_.width;
    cloud_.data.resize(count * cloud_.point_step);
    reader_.read(first, count, cloud_.data.data());
  }
  /// Row k's x, y, z as extractGeometry reads them (double).
  Eigen::Vector3d world(std::size_t k) const {
    const std::uint8_t* r = cloud_.data.data() + k * cloud_.point_step;
    return {value(r, xyz_.x), value(r, xyz_.y), value(r, xyz_.z)};
  }
  /// Row k's normal as extractGeometry reads it: unit, or false when missing (not finite, zero).
  bool normal(std::size_t k, Eigen::Vector3f& out) const {
    if (!xyz_.hasNormals()) return false;
    const std::uint8_t* r = cloud_.data.data() + k * cloud_.point_step;
    const Eigen::Vector3f nv(static_cast<float>(value(r, xyz_.nx)), static_cast<float>(value(r, xyz_.ny)),
                             static_cast<float>(value(r, xyz_.nz)));
    const float len = nv.norm();
    if (!std::isfinite(len) || len < 1e-12f) return false;
    out = nv / len;
    return true;
  }
  bool hasNormals() const { return xyz_.hasNormals(); }
  /// The block last loaded, as a cloud of the file's fields.
  const pcl::PCLPointCloud2& cloud() const { return cloud_; }

 private:
  /// A field's value in a record, as readValue reads it (float and double without its switch).
  double value(const std::uint8_t* record, int field) const {
    const pcl::PCLPointField& f = cloud_.fields[static_cast<std::size_t>(field)];
    if (f.datatype == pcl::PCLPointField::FLOAT32) {
      float v;
      std::memcpy(&v, record + f.offset, sizeof v);
      return v;
    }
    if (f.datatype == pcl::PCLPointField::FLOAT64) {
      double v;
      std::memcpy(&v, record + f.offset, sizeof v);
      return v;
    }
    return readValue(cloud_, static_cast<std::size_t>(record - cloud_.data.data()) / cloud_.point_step, f);
  }
  RecordReader reader_;
  std::size_t block_;
  RecordShare share_;
  pcl::PCLPointCloud2 cloud_;
  XyzFields xyz_;
};

}  // namespace hgd::stream
