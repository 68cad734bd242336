// Normals and the neighbour graph of a point cloud (ALGORITHM.md §1, steps 1-2).
#pragma once

#include <pcl/Vertices.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <cstddef>
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

/// A symmetric graph in compressed rows (CSR): neighbours of i are adj[offsets[i] .. offsets[i+1]).
struct NeighborGraph {
  std::vector<int> offsets{0};
  std::vector<int> adj;
  std::size_t size() const { return offsets.size() - 1; }
  int degree(std::size_t i) const { return offsets[i + 1] - offsets[i]; }
  const int* begin(std::size_t i) const { return adj.data() + offsets[i]; }
  const int* end(std::size_t i) const { return adj.data() + offsets[i + 1]; }
};

/// Exact kNN, in parallel: on a uniform grid for surface-like clouds, else through FLANN
/// (a k-d tree). k is clamped to n - 1.
KnnTable computeKnn(const pcl::PointCloud<pcl::PointXYZ>& points, int k);

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

/// The symmetric kNN relation (i~j if either lists the other among its first `k`), dropping
/// pairs whose normals point opposite ways (n_i . n_j < 0). `normals` may be null (no filter).
NeighborGraph knnGraph(const KnnTable& knn, int k, const pcl::PointCloud<pcl::Normal>* normals);

/// The 1-ring graph of a mesh (polygon edges).
NeighborGraph ringGraph(std::size_t n, const std::vector<pcl::Vertices>& faces);

/// Connected-component label of every vertex (0..count-1, numbered in the order of each
/// piece's smallest vertex), found in parallel; returns the count.
int connectedComponents(const NeighborGraph& graph, std::vector<int>& label);

}  // namespace hgd
