// Parts of a shape that the harmonic field cannot reach, and what becomes of them.
//
// A connected piece of the neighbour graph that holds no handle gets no harmonic value. As a
// space deformation should, a piece that lies against or inside the reached surface (eyes,
// teeth, clothing modelled apart, a scan fragment) follows it: each of its points takes the
// blended transform of the nearest reached point. A piece apart from everything reached
// (another object on a scanned table) stays where it is. A piece that holds the manipulated
// handle but no fixed one has the harmonic value 1 throughout and moves rigidly with the
// handle. Each case is counted, so that the front ends can say which happened.
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "hgdeform/cluster/handles.h"
#include "hgdeform/graph/neighbor_graph.h"

namespace hgd {

struct PieceReport {
  std::size_t followed_points = 0, followed_pieces = 0;  ///< no handle, near the reached surface
  std::size_t stayed_points = 0, stayed_pieces = 0;      ///< no handle, apart from it: unmoved
  std::size_t rigid_points = 0, rigid_pieces = 0;        ///< the manipulated handle, no fixed one
  double reach = 0;  ///< a piece follows when one of its points is this close to a reached point

  /// The warnings a front end prints (empty when every piece holds a fixed handle).
  std::vector<std::string> warnings() const;
};

struct PieceAnalysis {
  PieceReport report;
  /// Per point: the reached point whose transform it takes, or -1 (reached points, and
  /// points of pieces that stay). Empty on a multi-resolution build (Deformer::pieces()): there
  /// the coarse points follow, and every point takes its anchor's clusters.
  std::vector<int> follow;
};

/// Classifies the pieces of `graph` (`piece_label`: each point's connected piece, as
/// HarmonicField::pieceLabels() gives it) by the handles they hold. The reach is
/// `reach_spacings` times the spacing of the surface sample `sample` (point indices, as
/// sampleSurface() picks them), so that it does not depend on the density of the cloud.
/// `weight` (per point, may be null): how many points each stands for in the report's counts
/// (a coarse level's cells).
PieceAnalysis analysePieces(const pcl::PointCloud<pcl::PointXYZ>& points, const NeighborGraph& graph,
                            const std::vector<int>& piece_label, const Handles& handles,
                            const std::vector<int>& sample, double reach_spacings = 2.0,
                            const std::vector<std::uint32_t>* weight = nullptr);

}  // namespace hgd
