// The normal filter (docs/scans.md): kNN pairs across a thin gap left out of the neighbour graph.
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>
#include <utility>
#include <vector>

#include "hgdeform/graph/knn.h"
#include "hgdeform/graph/neighbor_graph.h"

namespace hgd {

/// The normal filter's rule: the pair (i, j) lies across a thin gap (the two sides of a sheet,
/// lips, fingers touching): normals within 26 degrees of opposite, and the offset at least 6
/// degrees out of the tangent plane (0.10 of its length along the normals), one point above the
/// other. A ridge or a crease (normals
/// turning, offset tangential) never is. Normals need not be of unit length.
bool acrossThinGap(const Eigen::Vector3f& pi, const Eigen::Vector3f& ni, const Eigen::Vector3f& pj,
                   const Eigen::Vector3f& nj);

/// The symmetric kNN relation (i~j if either lists the other among its first `k`). With
/// `normals` (and then `points`), pairs across a thin gap (acrossThinGap) are dropped and,
/// when `dropped` is given, listed there (i < j, sorted).
NeighborGraph knnGraph(const KnnTable& knn, int k, const pcl::PointCloud<pcl::Normal>* normals,
                       const pcl::PointCloud<pcl::PointXYZ>* points = nullptr,
                       std::vector<std::pair<int, int>>* dropped = nullptr);

}  // namespace hgd
