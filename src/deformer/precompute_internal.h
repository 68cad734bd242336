// The build's internal steps that the Deformer and the runner share (not part of the API).
#pragma once

#include <vector>

#include "hgdeform/deformer/precompute.h"

namespace hgd {

/// The graph's input at full resolution: every point of `geometry`, its file's normals (else
/// none: estimated, or a mesh's) and its faces.
void setGraphInput(SurfaceGraph& graph, const Geometry& geometry);

/// The solver's view of the clusters: members and barycentres through `normalise` (the
/// deformer's frame), handles constant or free, and each cluster's Rot(A) weight (w_MHC on the
/// manipulated cluster, bone_rigidity x w_MHC on bones).
std::vector<SolverCluster> solverClusters(const Clustering& clustering,
                                          const pcl::PointCloud<pcl::PointXYZ>& points,
                                          const DeformOptions& options, const Eigen::Vector3d& centre,
                                          double scale);

}  // namespace hgd
