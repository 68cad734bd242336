// Stray points of a scan, found and made leaves of the neighbour graph (docs/scans.md).
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <vector>

#include "hgdeform/graph/knn.h"
#include "hgdeform/graph/neighbor_graph.h"

namespace hgd {

/// Stray points of a scan: those whose k-th neighbour (`knn`, sorted rows) is more than 3
/// times as far as the median point's, the sparsest 3% at most (noise on the surface is not
/// flagged; strays in clumps of fewer than k are). Empty when `knn` is (meshes on their 1-ring).
std::vector<char> findOutliers(const pcl::PointCloud<pcl::PointXYZ>& points, const KnnTable& knn);

/// `graph` with every stray point made a leaf: its pairs are dropped and it is joined to its
/// nearest neighbour that is no outlier (about the nearest, when its kNN are all strays). An
/// outlier between two parts of a surface (the prongs of a fork) lists points of both among its
/// kNN; as a leaf it cannot carry the field from one to the other, yet it is reached and moves
/// with the surface it hangs from.
NeighborGraph attachOutliers(const pcl::PointCloud<pcl::PointXYZ>& points, const NeighborGraph& graph,
                             const KnnTable& knn, const std::vector<char>& outlier);

}  // namespace hgd
