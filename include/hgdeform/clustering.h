// Harmonic-guided clustering (ALGORITHM.md §2): a surface sample is cut into handle clusters
// and isoclusters by the harmonic field, every cluster split into connected pieces of the
// surface so that two branches at the same harmonic value get separate transforms.
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>
#include <vector>

#include "hgdeform/neighbors.h"
#include "hgdeform/regions.h"

namespace hgd {

enum class ClusterKind {
  Manipulated,  ///< MC: sample points of the manipulated handle
  Fixed,        ///< FC: sample points of one fixed handle (constant, identity)
  Iso,          ///< IC: sample points near one isovalue, on one connected piece
  Static,       ///< points in parts that touch no handle: they stay where they are
};

struct Cluster {
  int id = 0;
  ClusterKind kind = ClusterKind::Iso;
  int level = 0;             ///< 0 for fixed/static, 1..n for isoclusters, n+1 for the manipulated one
  double phi = 0;            ///< harmonic value the cluster stands for (0, the isovalue, or 1)
  int handle = -1;           ///< fixed handle index for Fixed clusters
  std::vector<int> members;  ///< indices into the shape's points (sample points of this cluster)
  Eigen::Vector3d barycenter = Eigen::Vector3d::Zero();  ///< of the members, shape's local frame
};

struct ClusterOptions {
  int isoclusters = 16;  ///< n isovalues, evenly spaced in (0, 1)
  int samples = 4000;    ///< target sample size
  int min_contour = 8;   ///< contours with fewer points (sampling noise) are not clusters
};

/// The clusters and, for every point of the shape, the two clusters that bracket its harmonic
/// value on its own branch: what interpolation needs.
///
/// Isovalues v_l = l / (n + 1), l = 1..n; v_0 = 0 is the fixed side, v_{n+1} = 1 the
/// manipulated side. An isoline at v_l is traced on the neighbour graph as the points incident
/// to an edge that crosses v_l; each connected piece of it (a contour) is one isocluster, whose
/// members are the sample points on it. So two branches at the same harmonic value (two legs)
/// get separate clusters. A point between v_l and v_l+1 takes, as `down`, the contour at v_l
/// nearest to it within that slab along the surface, and as `up` the nearest at v_l+1.
struct Clustering {
  std::vector<int> sample;  ///< sample point -> shape point index
  std::vector<Cluster> clusters;
  std::vector<std::pair<int, int>> adjacency;  ///< E_C: pairs of cluster ids, first < second
  std::vector<double> levels;                  ///< v_0 = 0, v_1..v_n isovalues, v_{n+1} = 1
  std::vector<int> down, up;                   ///< per shape point: bracketing clusters below / above
  std::vector<int> piece;                      ///< per shape point: the nearer of the two (for display)
  int manipulated = -1;                        ///< id of the MC cluster

  int isoclusters() const { return static_cast<int>(levels.size()) - 2; }
};

/// Picks a roughly uniform sample of the points: a voxel grid whose cell size is tuned to the
/// target count, one point per cell, taken separately inside each handle and outside them so
/// that every handle is represented.
std::vector<int> sampleSurface(const pcl::PointCloud<pcl::PointXYZ>& points, const Handles& handles,
                               int target);

/// Builds the clusters. `graph` is the shape's neighbour graph (the harmonic field's), `phi`
/// the field, `unreachable` the points in parts that touch no handle, `sample` a surface sample.
Clustering buildClusters(const pcl::PointCloud<pcl::PointXYZ>& points, const NeighborGraph& graph,
                         const std::vector<float>& phi, const Handles& handles,
                         const std::vector<int>& unreachable, const std::vector<int>& sample,
                         const ClusterOptions& options);

}  // namespace hgd
