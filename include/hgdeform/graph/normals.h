// Normals of a point cloud or mesh: estimated, oriented, checked (the graph stage; docs/scans.md).
#pragma once

#include <pcl/Vertices.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <vector>

#include "hgdeform/graph/knn.h"

namespace hgd {

/// PCA normals over each point's k nearest neighbours (PCL's computePointNormal), oriented
/// consistently: by propagation along a minimum spanning tree of the kNN graph (Hoppe et al.),
/// starting in each connected piece from its outermost point facing outwards; or towards
/// `viewpoint` when `use_viewpoint` (organized scans).
pcl::PointCloud<pcl::Normal>::Ptr estimateNormals(const pcl::PointCloud<pcl::PointXYZ>& points,
                                                  const KnnTable& knn, int k_normals,
                                                  bool use_viewpoint = false,
                                                  const Eigen::Vector3f& viewpoint = Eigen::Vector3f::Zero());

/// Area-weighted vertex normals of a mesh (consistently oriented by the face winding).
/// Vertices on no face get no normal (NaN).
pcl::PointCloud<pcl::Normal>::Ptr meshNormals(const pcl::PointCloud<pcl::PointXYZ>& points,
                                              const std::vector<pcl::Vertices>& faces);

/// Orients `normals` consistently in place, as estimateNormals() does (minimum spanning tree
/// over the kNN graph, each piece seeded at its outermost point facing outwards). The normals
/// must be of unit length.
void orientNormals(const pcl::PointCloud<pcl::PointXYZ>& points, const KnnTable& knn, int k_normals,
                   pcl::PointCloud<pcl::Normal>& normals);

/// True when neighbours lying side by side (offsets within 17 degrees of both tangent planes)
/// have agreeing normals, all but 2% of them: the normals are consistently oriented.
bool consistentlyOriented(const pcl::PointCloud<pcl::PointXYZ>& points,
                          const pcl::PointCloud<pcl::Normal>& normals, const KnnTable& knn, int k);

}  // namespace hgd
