// Is the deformed surface still in one piece? Surface neighbour pairs (mesh edges; on clouds,
// the neighbour graph) measured before and after a deformation.
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>
#include <cstddef>
#include <string>
#include <vector>

#include "hgdeform/graph/neighbor_graph.h"
#include "hgdeform/graph/surface_graph.h"
#include "hgdeform/io/geometry.h"
#include "hgdeform/multires/multires.h"

namespace hgd {

struct SurfaceStretch {
  /// Points with a surface neighbour whose distance more than tripled and grew by more than
  /// 2% of the move distance: where the surface creases or opens.
  std::size_t split_points = 0;
  /// The largest ratio deformed / rest length over all pairs (1 for a rigid motion).
  double max_stretch = 1;
  std::size_t pairs = 0;  ///< pairs measured
};

/// Measures every pair (i, j) of `pairs` (a symmetric graph; pairs of coincident rest points
/// are skipped). `move_distance`: how far the manipulated handle travelled (its largest point
/// displacement), the scale of "grew by more than 2%". Points marked in `skip` (a cloud's
/// strays) and their pairs are not measured.
SurfaceStretch measureStretch(const pcl::PointCloud<pcl::PointXYZ>& rest,
                              const std::vector<Eigen::Vector3f>& deformed, const NeighborGraph& pairs,
                              double move_distance, const std::vector<char>* skip = nullptr);

/// The surface of a deformed shape measured: its mesh edges where it has faces, else the pairs
/// of its surface graph (on a multi-resolution build, `graph` is the coarse level's and its pairs
/// join the points that stand for their cells), the graph's strays left out; the move distance
/// is the largest point displacement, at least `min_move`.
SurfaceStretch measureSurfaceStretch(const Geometry& geometry, const std::vector<Eigen::Vector3f>& deformed,
                                     const SurfaceGraph& graph, const CoarseLevel& coarse, double min_move);

/// The warning a front end prints when points are split ("" when none is).
std::string stretchWarning(const SurfaceStretch& stretch);

}  // namespace hgd
