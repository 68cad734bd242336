// What a streamed level answers of any record (hgdeform/multires/streamed.h): kept or set
// apart, its class, its anchor, its place in Geometry's order.
#include <algorithm>

#include "hgdeform/multires/streamed.h"
#include "io/frame.h"
#include "multires/coarse_grid.h"

namespace hgd {

std::uint32_t StreamedLevel::mortonKey(const Eigen::Vector3d& w) const {
  return frame::mortonKey(w, morton_lo, morton_scale);  // Geometry's
}

int StreamedLevel::classOf(std::uint64_t record) const {
  const auto it = std::lower_bound(record_class.begin(), record_class.end(), record << 16);
  return it != record_class.end() && (*it >> 16) == record ? static_cast<int>(*it & 0xFFFFu) : 0;
}

bool StreamedLevel::kept(std::uint64_t record, const Eigen::Vector3d& world) const {
  if (zeros_apart && world.x() == 0 && world.y() == 0 && world.z() == 0) return false;
  const double d = (world - frame_centre).cwiseAbs().maxCoeff();
  if (d > far) return false;
  return !(d > stray_distance && std::binary_search(far_strays.begin(), far_strays.end(), record));
}

std::uint32_t StreamedLevel::anchorOf(std::uint64_t record, const Eigen::Vector3f& p, int cls) const {
  const auto s = std::lower_bound(strays.begin(), strays.end(), record);
  if (s != strays.end() && *s == record) return stray_anchor[static_cast<std::size_t>(s - strays.begin())];
  return cellAnchor(p, cls);
}

std::uint32_t StreamedLevel::cellAnchor(const Eigen::Vector3f& p, int cls) const {
  coarse::Grid grid;
  grid.lo = grid_lo;
  grid.h = cell;
  grid.axis_bits = axis_bits;
  const std::uint64_t key = grid.key(p, cls);
  const auto it = std::lower_bound(cell_key.begin(), cell_key.end(), key);
  if (it == cell_key.end() || *it != key) return 0;  // (not a kept point of the file)
  return cell_id[static_cast<std::size_t>(it - cell_key.begin())];
}

}  // namespace hgd
