// The harmonic field φ on a point cloud or mesh (docs/method.md; its graph: docs/scans.md): 1 on the
// manipulated handle, 0 on the fixed ones, harmonic for the uniform quasi-Laplacian elsewhere.
//
// A PCL-style stage:
//   hgd::HarmonicField field;
//   field.setInputCloud(points);            // #P points (finite)
//   field.setInputNormals(normals);         // optional: #P normals (else estimated)
//   field.setHandles(fixed, manipulated);   // indices into points
//   std::vector<float> phi;                 // out: #P values in [0, 1]
//   field.compute(phi);
// Normals, kNN and the neighbour graph are cached across compute() calls as long as the input
// cloud, normals, polygons and neighbour options stay the same; new handles only re-solve.
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <vector>

#include "hgdeform/neighbors.h"

namespace hgd {

enum class FieldSolver {
  Auto,        ///< exact up to FieldOptions::exact_limit free points, multilevel above
  Exact,       ///< sparse Cholesky (CHOLMOD supernodal) of the free block: the reference
  Multilevel,  ///< multigrid-preconditioned CG (Galerkin levels down to a small Cholesky solve)
};

struct FieldOptions {
  int k_neighbors = 10;       ///< kNN for the Laplacian
  int k_normals = 16;         ///< kNN for normal estimation (when normals are not given)
  bool mesh_ring = false;     ///< on meshes, use the 1-ring from faces instead of kNN
  bool normal_filter = true;  ///< drop kNN pairs across a thin gap (docs/scans.md); never mesh edges
  FieldSolver solver = FieldSolver::Auto;
  std::size_t exact_limit = 4000;
  double tolerance = 1e-3;   ///< multilevel: relative residual (tightened as 1/sqrt(n) above 1M unknowns)
  int max_iterations = 500;  ///< multilevel: CG cap
  bool orient_to_viewpoint = false;  ///< orient estimated normals towards `viewpoint` (scans)
  Eigen::Vector3f viewpoint = Eigen::Vector3f::Zero();
};

struct FieldTimings {
  double normals_ms = 0, knn_ms = 0, graph_ms = 0, laplacian_ms = 0, solve_ms = 0;
  int iterations = 0;  ///< multilevel CG iterations (0 for exact)
  bool exact = true;
  double total() const { return normals_ms + knn_ms + graph_ms + laplacian_ms + solve_ms; }
};

class HarmonicField {
 public:
  HarmonicField() = default;
  HarmonicField(const HarmonicField&) = delete;  // owns its graph and caches: moved, not copied
  HarmonicField& operator=(const HarmonicField&) = delete;
  HarmonicField(HarmonicField&&) = default;
  HarmonicField& operator=(HarmonicField&&) = default;

  void setInputCloud(const pcl::PointCloud<pcl::PointXYZ>::ConstPtr& cloud);
  void setInputNormals(const pcl::PointCloud<pcl::Normal>::ConstPtr& normals);
  void setPolygons(const std::vector<pcl::Vertices>& polygons);
  void setHandles(const std::vector<std::vector<int>>& fixed, const std::vector<int>& manipulated);
  void setOptions(const FieldOptions& options);
  const FieldOptions& options() const { return options_; }

  /// Computes φ for every input point. Throws std::invalid_argument on missing input or bad
  /// handle indices and std::runtime_error when the solver fails.
  void compute(std::vector<float>& phi);

  /// The neighbour graph used (valid after compute()): the kNN graph less the pairs across a
  /// thin gap (the normal filter), except, on meshes, mesh edges; then joined back through
  /// the dropped pairs wherever the filter alone would cut a piece without a handle off.
  const NeighborGraph& graph() const { return joined_.empty() ? graph_ : graph_joined_; }
  /// The normals the filter used: the input's (re-oriented when their signs were not
  /// consistent), the mesh's or estimated ones.
  const pcl::PointCloud<pcl::Normal>& normals() const { return *normals_; }
  const KnnTable& knn() const { return knn_; }
  /// Points in components that touch no handle (they get φ = 0).
  const std::vector<int>& unreachable() const { return unreachable_; }
  /// Connected-piece label of every point in graph() (0..count-1).
  const std::vector<int>& pieceLabels() const { return piece_; }
  /// Pairs the normal filter dropped, and those of them put back to join pieces (i < j).
  const std::vector<std::pair<int, int>>& droppedPairs() const { return dropped_; }
  const std::vector<std::pair<int, int>>& rejoinedPairs() const { return joined_; }
  /// Per point: a stray point of a cloud (findOutliers), a leaf of graph(); empty when there is
  /// none.
  const std::vector<char>& outliers() const { return outliers_; }
  /// True when the input normals' signs were inconsistent and were re-oriented.
  bool normalsReoriented() const { return reoriented_; }
  const FieldTimings& timings() const { return timings_; }

 private:
  void buildGraph();
  void joinPieces(const std::vector<char>& constrained);

  pcl::PointCloud<pcl::PointXYZ>::ConstPtr cloud_;
  pcl::PointCloud<pcl::Normal>::ConstPtr input_normals_;
  pcl::PointCloud<pcl::Normal>::ConstPtr normals_{new pcl::PointCloud<pcl::Normal>};
  std::vector<pcl::Vertices> polygons_;
  std::vector<std::vector<int>> fixed_;
  std::vector<int> manipulated_;
  FieldOptions options_;
  bool graph_valid_ = false;
  KnnTable knn_;
  NeighborGraph graph_, graph_joined_;
  std::vector<std::pair<int, int>> dropped_, joined_;
  std::vector<int> base_piece_;  ///< pieces of graph_ (when the filter dropped pairs)
  std::vector<char> outliers_;
  bool reoriented_ = false;
  std::vector<int> unreachable_, piece_;
  FieldTimings timings_;
};

/// Solves the Dirichlet problem on a graph: value[i] given for constrained points (mask[i] =
/// true), harmonic (uniform weights) elsewhere. Points in components without a constraint are
/// set to 0 and listed in `unreachable`. `piece`, when given, receives every point's connected
/// piece label. Exposed for tests and the multilevel comparison.
void solveDirichlet(const NeighborGraph& graph, const std::vector<char>& constrained,
                    std::vector<double>& value, const FieldOptions& options, std::vector<int>& unreachable,
                    FieldTimings& timings, std::vector<int>* piece = nullptr);

}  // namespace hgd
