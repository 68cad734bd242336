// The nearest of a set of points (internal).
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <vector>

namespace hgd {

/// For each of `queries` (point indices), the position in `targets` (point indices, not empty)
/// of the target nearest it, exactly (a k-d tree over the targets); -1 where there is none.
std::vector<int> nearestAmong(const pcl::PointCloud<pcl::PointXYZ>& points, const std::vector<int>& targets,
                              const std::vector<int>& queries);

}  // namespace hgd
