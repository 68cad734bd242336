// The harmonic field φ on a point cloud or mesh (docs/method.md): 1 on the manipulated handle, 0 on
// the fixed ones, harmonic for the uniform quasi-Laplacian of a SurfaceGraph elsewhere.
//
// A PCL-style stage on a SurfaceGraph (surface_graph.h), which it owns unless given one:
//   hgd::HarmonicField field;
//   field.setInputCloud(points);            // #P points (finite): its surface graph's input
//   field.setInputNormals(normals);         // optional: #P normals (else estimated)
//   field.setHandles(fixed, manipulated);   // indices into points
//   std::vector<float> phi;                 // out: #P values in [0, 1]
//   field.compute(phi);
// or, on a graph built apart (shared with the stages after it):
//   auto graph = std::make_shared<hgd::SurfaceGraph>(); ...; field.setSurfaceGraph(graph);
// The graph is built once for its inputs and options; new handles only join its pieces and
// re-solve.
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <memory>
#include <vector>

#include "hgdeform/graph/surface_graph.h"

namespace hgd {

enum class FieldSolver {
  Auto,        ///< exact up to FieldOptions::exact_limit free points, multilevel above
  Exact,       ///< sparse Cholesky (CHOLMOD supernodal) of the free block: the reference
  Multilevel,  ///< multigrid-preconditioned CG (Galerkin levels down to a small Cholesky solve)
};

/// The field's options, its graph's among them (a field is solved on a surface graph).
struct FieldOptions : GraphOptions {
  FieldSolver solver = FieldSolver::Auto;
  std::size_t exact_limit = 4000;
  double tolerance = 1e-3;   ///< multilevel: relative residual (tightened as 1/sqrt(n) above 1M unknowns)
  int max_iterations = 500;  ///< multilevel: CG cap
};

/// What compute() cost: its graph's build (0 when the graph was kept), the join, the solve.
struct FieldTimings {
  double normals_ms = 0, knn_ms = 0, graph_ms = 0, laplacian_ms = 0, solve_ms = 0;
  int iterations = 0;  ///< multilevel CG iterations (0 for exact)
  bool exact = true;
  double total() const { return normals_ms + knn_ms + graph_ms + laplacian_ms + solve_ms; }
};

class HarmonicField {
 public:
  HarmonicField() = default;
  HarmonicField(const HarmonicField&) = delete;
  HarmonicField& operator=(const HarmonicField&) = delete;
  HarmonicField(HarmonicField&&) = default;
  HarmonicField& operator=(HarmonicField&&) = default;

  /// The graph to solve on, built or not (compute() builds it when due); setOptions() sets its
  /// options too. Without one the field makes its own.
  void setSurfaceGraph(std::shared_ptr<SurfaceGraph> graph);
  /// The surface graph's input (shorthands for surfaceGraph().setInputCloud() etc.).
  void setInputCloud(const pcl::PointCloud<pcl::PointXYZ>::ConstPtr& cloud);
  void setInputNormals(const pcl::PointCloud<pcl::Normal>::ConstPtr& normals);
  void setPolygons(const std::vector<pcl::Vertices>& polygons);
  void setHandles(const std::vector<std::vector<int>>& fixed, const std::vector<int>& manipulated);
  void setOptions(const FieldOptions& options);
  const FieldOptions& options() const { return options_; }

  /// Computes φ for every input point. Throws std::invalid_argument on missing input or bad
  /// handle indices and std::runtime_error when the solver fails.
  void compute(std::vector<float>& phi);

  /// The graph stage: after compute(), its graph() is the one solved on (pieces joined back for
  /// these handles), with its normals, kNN, strays and the filter's pairs.
  const SurfaceGraph& surfaceGraph() const { return *graph_; }
  SurfaceGraph& surfaceGraph() { return *graph_; }
  /// Points in components that touch no handle (they get φ = 0).
  const std::vector<int>& unreachable() const { return unreachable_; }
  /// Connected-piece label of every point in surfaceGraph().graph() (0..count-1).
  const std::vector<int>& pieceLabels() const { return piece_; }
  const FieldTimings& timings() const { return timings_; }

 private:
  std::shared_ptr<SurfaceGraph> graph_ = std::make_shared<SurfaceGraph>();
  std::vector<std::vector<int>> fixed_;
  std::vector<int> manipulated_;
  FieldOptions options_;
  std::vector<int> unreachable_, piece_;
  FieldTimings timings_;
};

}  // namespace hgd
