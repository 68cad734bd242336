// The surface graph of a point cloud or mesh (docs/scans.md): the stage before the harmonic field.
// It owns the kNN table, the normals (the input's, the mesh's or estimated; re-oriented when their
// signs disagree), the neighbour graph with the normal filter's thin-gap pairs dropped (never mesh
// edges), the stray points made leaves, and the pieces the filter cut, joined back for a set of
// handles.
//
// A PCL-style stage:
//   hgd::SurfaceGraph graph;
//   graph.setInputCloud(points);        // #P points (finite)
//   graph.setInputNormals(normals);     // optional: #P normals (else estimated)
//   graph.setPolygons(faces);           // optional: a mesh's faces
//   graph.compute();                    // kNN, normals, the filtered graph, strays, pieces
//   graph.joinPieces(constrained);      // per handle set: pieces without a handle joined back
//   graph.graph();                      // what the harmonic field solves on
// compute() keeps its results as long as the cloud, normals, polygons and options stay the same.
#pragma once

#include <pcl/Vertices.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>
#include <utility>
#include <vector>

#include "hgdeform/graph/knn.h"
#include "hgdeform/graph/neighbor_graph.h"
#include "hgdeform/graph/strays.h"

namespace hgd {

struct GraphOptions {
  int k_neighbors = 10;              ///< kNN for the Laplacian
  int k_normals = 16;                ///< kNN for normal estimation (when normals are not given)
  bool mesh_ring = false;            ///< on meshes, use the 1-ring from faces instead of kNN
  bool normal_filter = true;         ///< drop kNN pairs across a thin gap (docs/scans.md); never mesh edges
  bool orient_to_viewpoint = false;  ///< orient estimated normals towards `viewpoint` (scans)
  Eigen::Vector3f viewpoint = Eigen::Vector3f::Zero();
};

struct GraphTimings {
  double knn_ms = 0, normals_ms = 0, graph_ms = 0;
};

class SurfaceGraph {
 public:
  SurfaceGraph() = default;
  SurfaceGraph(const SurfaceGraph&) = delete;  // large tables: moved, not copied
  SurfaceGraph& operator=(const SurfaceGraph&) = delete;
  SurfaceGraph(SurfaceGraph&&) = default;
  SurfaceGraph& operator=(SurfaceGraph&&) = default;

  void setInputCloud(const pcl::PointCloud<pcl::PointXYZ>::ConstPtr& cloud);
  void setInputNormals(const pcl::PointCloud<pcl::Normal>::ConstPtr& normals);
  void setPolygons(const std::vector<pcl::Vertices>& polygons);
  void setOptions(const GraphOptions& options);
  const GraphOptions& options() const { return options_; }
  const pcl::PointCloud<pcl::PointXYZ>::ConstPtr& inputCloud() const { return cloud_; }

  /// Builds kNN, normals, the filtered graph, strays and the filter's pieces, unless the inputs
  /// and options are those of the last build. Returns true when it built them (timings() then
  /// holds what this build cost). Throws std::invalid_argument without a cloud.
  bool compute();

  /// The pieces logic: the normal filter never splits the surface. A piece of the filtered graph
  /// that holds no point marked in `constrained` (#P), and that the filter alone cut off, is
  /// joined back through the dropped pairs that lead out of it; pieces that each hold a
  /// constrained point stay apart. graph() is the result until the next call or compute().
  void joinPieces(const std::vector<char>& constrained);

  /// The neighbour graph: the kNN graph less the pairs across a thin gap, except, on meshes,
  /// mesh edges; strays as leaves; joined back by the last joinPieces().
  const NeighborGraph& graph() const { return joined_.empty() ? graph_ : graph_joined_; }
  /// The normals the filter used: the input's (re-oriented when their signs were not
  /// consistent), the mesh's or estimated ones.
  const pcl::PointCloud<pcl::Normal>& normals() const { return *normals_; }
  /// The same, shared.
  const pcl::PointCloud<pcl::Normal>::ConstPtr& normalCloud() const { return normals_; }
  const KnnTable& knn() const { return knn_; }
  /// Pairs the normal filter dropped, and those of them put back to join pieces (i < j).
  const std::vector<std::pair<int, int>>& droppedPairs() const { return dropped_; }
  const std::vector<std::pair<int, int>>& rejoinedPairs() const { return joined_; }
  /// Per point: a stray point of a cloud (findOutliers), a leaf of graph(); empty when there is
  /// none.
  const std::vector<char>& outliers() const { return outliers_; }
  /// True when the input normals' signs were inconsistent and were re-oriented.
  bool normalsReoriented() const { return reoriented_; }
  /// What the last build cost.
  const GraphTimings& timings() const { return timings_; }

 private:
  void build();

  pcl::PointCloud<pcl::PointXYZ>::ConstPtr cloud_;
  pcl::PointCloud<pcl::Normal>::ConstPtr input_normals_;
  pcl::PointCloud<pcl::Normal>::ConstPtr normals_{new pcl::PointCloud<pcl::Normal>};
  std::vector<pcl::Vertices> polygons_;
  GraphOptions options_;
  bool valid_ = false;
  KnnTable knn_;
  NeighborGraph graph_, graph_joined_;
  std::vector<std::pair<int, int>> dropped_, joined_;
  std::vector<int> base_piece_;  ///< pieces of graph_ (when the filter dropped pairs)
  std::vector<char> outliers_;
  bool reoriented_ = false;
  GraphTimings timings_;
};

}  // namespace hgd
