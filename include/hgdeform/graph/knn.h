// k nearest neighbours of a point cloud (the graph stage; docs/scans.md).
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <vector>

namespace hgd {

/// k nearest neighbours of every point (the point itself excluded), row-major n x k.
struct KnnTable {
  int k = 0;
  std::size_t n = 0;  ///< points (rows), also when k is 0
  std::vector<int> index;
  const int* row(std::size_t i) const { return index.data() + i * static_cast<std::size_t>(k); }
  std::size_t size() const { return n; }
};

/// Exact kNN, in parallel: on a uniform grid for surface-like clouds, else through FLANN
/// (a k-d tree). k is clamped to n - 1.
KnnTable computeKnn(const pcl::PointCloud<pcl::PointXYZ>& points, int k);

}  // namespace hgd
