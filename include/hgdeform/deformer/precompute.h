// The deformer's build stage, in libigl's precompute / solve style: the surface graph, the field,
// the pieces, the clusters and the interpolation table for a set of handles, at full resolution or
// on a coarse level prolonged to every point (docs/method.md §7). Deformer keeps a
// DeformationData and solves and interpolates with it.
//
//   hgd::DeformationData data;
//   hgd::precompute(geometry, handles, options, data);   // again for new handles: the graph is kept
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

#include "hgdeform/cluster/clustering.h"
#include "hgdeform/cluster/pieces.h"
#include "hgdeform/field/harmonic_field.h"
#include "hgdeform/interp/blend.h"
#include "hgdeform/interp/interpolation.h"
#include "hgdeform/io/geometry.h"
#include "hgdeform/multires/multires.h"
#include "hgdeform/solve/solver.h"
#include "hgdeform/util/phase.h"

namespace hgd {

struct DeformOptions {
  FieldOptions field;
  ClusterOptions clusters;
  SolverWeights weights;
  GaussNewtonOptions gauss_newton;
  double drag_tolerance = 1e-4;   ///< dragTo(): stop when the picked point is this close (× diagonal)
  double max_drag_step = 0.02;    ///< dragTo(): the cursor moves at most this much per frame (× diagonal)
  int max_drag_frames = 3000;     ///< dragTo(): frames at most
  Blend blend = Blend::Rotation;  ///< how points blend their two clusters' transforms
  /// Rot(A) weight of range clusters (bones), times w_MHC: bones are meant to stay rigid (their
  /// transforms are also projected onto the nearest rotation when applied).
  double bone_rigidity = 10;
  /// Rot(A) weight of isoclusters (the paper's 1, the default). Points between isoclusters
  /// blend their rotations only, so an isocluster's stretch, which its own ring of points hardly
  /// constrains along the field, reaches the shape as slip between clusters: 2 lowers the bench
  /// shapes' distortion by about 3%, at the cost of a Gauss–Newton iteration now and then
  /// (docs/method.md, "Shape quality").
  double iso_rigidity = 1;
  /// Multi-resolution build (docs/method.md §7): a shape with more points than this gets its
  /// field, pieces and clusters on a voxel subsample, prolonged to every point: of about
  /// `coarse_points` points, or one for every `points_per_coarse` points where that is fewer
  /// (a mid-sized shape's coarse level grows with it, and so does its build time). 0: always at
  /// full resolution (every point in the neighbour graph).
  std::size_t multires_above = 131072;
  std::size_t coarse_points = 65536;
  std::size_t points_per_coarse = 10;
};

struct BuildTimings {
  double field_ms = 0, sampling_ms = 0, clusters_ms = 0, setup_ms = 0;
  double coarse_ms = 0;  ///< of field_ms: the coarse level and the prolongation (multi-resolution)
  FieldTimings field;
  /// Every phase of the last build in order, finer than the above (a phase run twice is listed
  /// twice): the kNN, normals and graph, the field's Laplacian and solve, the multi-resolution
  /// steps, the clusters, the table, the solver's set-up, the first shape.
  std::vector<BuildPhase> phases;
  double total() const { return field_ms + sampling_ms + clusters_ms + setup_ms; }
};

/// A coarse level built elsewhere (streamCoarseLevel: a scan streamed from its file) for a
/// geometry that holds only some of the shape's points (the coarse points): `level` maps those
/// points (its anchors are theirs; its weights count every point of the shape), `handles` are
/// the whole shape's handles on the coarse level.
struct PrebuiltLevel {
  CoarseLevel level;
  Handles handles;
  std::size_t shape_points = 0;  ///< the whole shape's (for what the build says of itself)
  /// The manipulated handle's points when the geometry does not hold them all (a streamed
  /// shape's: only its coarse points): their local rest positions in Geometry's order, and each
  /// one's index in the geometry (-1: not held). The Deformer picks among them and takes their
  /// centre; each follows the manipulated cluster's transform (a handle's points are pinned).
  /// Empty: the handle's points are the geometry's (`handles.manipulated` of the Deformer).
  std::vector<Eigen::Vector3f> manipulated_rest;
  std::vector<int> manipulated_held;
};

/// What precompute() builds, for the resolution it chose.
struct DeformationData {
  /// Set before the first precompute(): the coarse level to build on, not coarsened here.
  std::shared_ptr<const PrebuiltLevel> prebuilt;
  /// The graph stage and the field on it: over every point, or over coarse.points' positions
  /// on a multi-resolution build. Kept across precompute() calls on the same geometry (new
  /// handles at full resolution only re-solve).
  std::shared_ptr<SurfaceGraph> graph;
  HarmonicField field;
  bool multires = false;
  CoarseLevel coarse;                  ///< empty at full resolution
  std::vector<float> phi;              ///< φ at every point of the shape
  std::size_t unreachable_points = 0;  ///< points in parts that touch no handle (all resolutions)
  PieceAnalysis pieces;
  /// The clusters, bands and sample, without per-point labels: a point's two clusters and blend
  /// factor are table.bracket(i).
  Clustering clustering;
  InterpolationTable table;
  /// On a prebuilt level: what the table of any of the shape's points needs (the points the
  /// geometry does not hold are tabled block by block as they stream by).
  std::shared_ptr<const BlockProlongation> blocks;
  BuildTimings timings;  ///< field_ms, sampling_ms, coarse_ms, field; clusters_ms so far
};

/// Builds `data` for `handles` (valid indices, checked: std::invalid_argument) on `geometry`,
/// whose clouds must stay as they are while `data` lives. The resolution is chosen on the first
/// call (options.multires_above, coarse_points) and kept.
void precompute(const Geometry& geometry, const Handles& handles, const DeformOptions& options,
                DeformationData& data);

}  // namespace hgd
