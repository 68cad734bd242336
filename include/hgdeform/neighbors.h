// Normals and the neighbour graph of a point cloud (docs/scans.md: the graph and its normal filter).
#pragma once

#include <pcl/Vertices.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <cstddef>
#include <utility>
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

/// Orients `normals` consistently in place, as estimateNormals() does (minimum spanning tree
/// over the kNN graph, each piece seeded at its outermost point facing outwards). The normals
/// must be of unit length.
void orientNormals(const pcl::PointCloud<pcl::PointXYZ>& points, const KnnTable& knn, int k_normals,
                   pcl::PointCloud<pcl::Normal>& normals);

/// True when neighbours lying side by side (offsets within 17 degrees of both tangent planes)
/// have agreeing normals, all but 2% of them: the normals are consistently oriented.
bool consistentlyOriented(const pcl::PointCloud<pcl::PointXYZ>& points,
                          const pcl::PointCloud<pcl::Normal>& normals, const KnnTable& knn, int k);

/// The normal filter's rule: the pair (i, j) lies across a thin gap (the two sides of a sheet,
/// lips, fingers touching): normals within 26 degrees of opposite, and the offset at least 9
/// degrees out of the tangent plane, one point above the other. A ridge or a crease (normals
/// turning, offset tangential) never is. Normals need not be of unit length.
bool acrossThinGap(const Eigen::Vector3f& pi, const Eigen::Vector3f& ni, const Eigen::Vector3f& pj,
                   const Eigen::Vector3f& nj);

/// The symmetric kNN relation (i~j if either lists the other among its first `k`). With
/// `normals` (and then `points`), pairs across a thin gap (acrossThinGap) are dropped and,
/// when `dropped` is given, listed there (i < j, sorted).
NeighborGraph knnGraph(const KnnTable& knn, int k, const pcl::PointCloud<pcl::Normal>* normals,
                       const pcl::PointCloud<pcl::PointXYZ>* points = nullptr,
                       std::vector<std::pair<int, int>>* dropped = nullptr);

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

/// Every pair of either graph (same size; rows sorted, as every graph here has them).
NeighborGraph unionGraph(const NeighborGraph& a, const NeighborGraph& b);

/// `graph` with `edges` added (both directions; repeats and self-loops ignored).
NeighborGraph addEdges(const NeighborGraph& graph, const std::vector<std::pair<int, int>>& edges);

/// The 1-ring graph of a mesh (polygon edges).
NeighborGraph ringGraph(std::size_t n, const std::vector<pcl::Vertices>& faces);

/// Connected-component label of every vertex (0..count-1, numbered in the order of each
/// piece's smallest vertex), found in parallel; returns the count.
int connectedComponents(const NeighborGraph& graph, std::vector<int>& label);

}  // namespace hgd
