// Harmonic-guided clustering (docs/method.md; why on a sample: docs/scans.md): a surface sample is cut
// into handle clusters and isoclusters by the harmonic field, every cluster split into connected pieces of
// the surface so that two branches at the same harmonic value get separate transforms.
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>
#include <string>
#include <vector>

#include "hgdeform/cluster/handles.h"
#include "hgdeform/graph/neighbor_graph.h"

namespace hgd {

enum class ClusterKind {
  Manipulated,  ///< MC: sample points of the manipulated handle
  Fixed,        ///< FC: sample points of one fixed handle (constant, identity)
  Iso,          ///< IC: sample points near one isovalue, on one connected piece
  Range,        ///< RC: the points of one connected piece with phi in an interval: a rigid bone
  Static,       ///< points in parts that touch no handle: they stay where they are
};

struct Cluster {
  int id = 0;
  ClusterKind kind = ClusterKind::Iso;
  int level = 0;              ///< 0 for fixed/static, 1..n for isoclusters, n+1 for the manipulated one
  double harmonic_value = 0;  ///< harmonic value the cluster stands for (0, the isovalue, or 1)
  int handle = -1;            ///< fixed handle index for Fixed clusters
  std::vector<int> members;   ///< indices into the shape's points (sample points of this cluster)
  Eigen::Vector3d barycentre = Eigen::Vector3d::Zero();  ///< of the members, shape's local frame
};

struct ClusterOptions {
  int isovalues = 16;       ///< n isovalues, evenly spaced in (0, 1) (without joints)
  int samples = 4000;       ///< target sample size
  int min_contour = 3;      ///< contours with fewer sample points (a tip just crossing) are not clusters
  int joint_isovalues = 3;  ///< skeletal mode: isovalues inside each joint's phi range
};

/// A band of harmonic values: an isovalue (`lo == hi`, traced as contours) or an interval
/// (the fixed side [0, 0], the manipulated side [1, 1], a bone's open interval) whose connected
/// pieces are clusters. Bands are sorted and disjoint; between two bands lies a gap, where
/// points blend the clusters of the bands on either side.
struct Band {
  enum class Kind { Fixed, Iso, Range, Manipulated };
  Kind kind = Kind::Iso;
  double lo = 0, hi = 0;
};

/// The clusters and, for every point of the shape, the two clusters that bracket its harmonic
/// value on its own branch: what interpolation needs.
///
/// Isolines are traced on the surface sample, not on every point, so that the clusters do not
/// depend on the density or the noise of the cloud (docs/scans.md): every sample point owns the
/// points nearest it along the neighbour graph, two sample points are adjacent when those cells
/// touch, and an isoline at v is the sample points at either end of an adjacent pair that
/// straddles v. Each connected piece of it (a contour) is one isocluster, so two branches at
/// the same harmonic value (two legs) get separate clusters. Interval bands (handles, bones)
/// give a cluster per connected piece. A point in a gap between two bands takes, as `lower`, the
/// cluster of the lower band nearest to it within the gap along the surface, and as `upper`
/// the nearest of the upper band; a point in an interval band takes its own cluster for both.
struct Clustering {
  std::vector<int> sample;  ///< sample point -> shape point index
  std::vector<Cluster> clusters;
  std::vector<std::pair<int, int>> adjacency;  ///< E_C: pairs of cluster ids, first < second
  std::vector<Band> bands;                     ///< fixed side, isovalues (and bones), manipulated side
  std::vector<std::string> notes;              ///< what was merged or adjusted (e.g. overlapping joints)
  std::vector<int> lower, upper;  ///< per shape point: bracketing clusters below / above its harmonic value
  std::vector<float> alpha;       ///< per shape point: blend factor between lower (0) and upper (1)
  std::vector<int> nearest;       ///< per shape point: the nearer of the two (for display)
  int manipulated = -1;           ///< id of the MC cluster

  /// The bands of a deformation: without joints, n evenly spaced isovalues; with joints, a few
  /// isovalues inside each joint's phi range and a bone (range) band between joints. Joints
  /// whose phi ranges overlap are merged (and said so in `notes`).
  static std::vector<Band> makeBands(const std::vector<float>& phi,
                                     const std::vector<std::vector<int>>& joints,
                                     const ClusterOptions& options,
                                     std::vector<std::string>* notes = nullptr);
};

/// The clusters, bands and sample of `clustering` without its per-point labels (lower, upper,
/// alpha, nearest): what a deformer keeps once an interpolation table holds the brackets.
Clustering withoutPointLabels(Clustering clustering);

/// Picks a roughly uniform sample of the points: a voxel grid whose cell size is tuned to the
/// target count, one point per cell, taken separately inside each handle and outside them so
/// that every handle is represented. Points marked in `exclude` (outliers) are never picked.
std::vector<int> sampleSurface(const pcl::PointCloud<pcl::PointXYZ>& points, const Handles& handles,
                               int target, const std::vector<char>* exclude = nullptr);

/// Builds the clusters. `graph` is the shape's neighbour graph (the harmonic field's), `phi`
/// the field, `unreachable` the points in parts that touch no handle, `sample` a surface sample.
/// `follow` (per point, may be empty): the reached point whose clusters and blend factor an
/// unreachable point takes (see pieces.h), or -1 for a static cluster. `outliers` (per point,
/// may be empty): points that pass no cluster on.
Clustering buildClusters(const pcl::PointCloud<pcl::PointXYZ>& points, const NeighborGraph& graph,
                         const std::vector<float>& phi, const Handles& handles,
                         const std::vector<int>& unreachable, const std::vector<int>& sample,
                         const ClusterOptions& options, const std::vector<int>& follow = {},
                         const std::vector<char>& outliers = {});

}  // namespace hgd
