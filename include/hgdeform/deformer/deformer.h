// The deformer façade, in libigl's precompute / solve style:
//
//   hgd::Deformer d(geometry, handles, options);   // precompute() (precompute.h), solver set-up
//   d.drag(from, to);                              // one interactive frame (direct manipulation)
//   d.setHandleTransform(T);                       // or: frame metaphor, T given exactly
//   d.deformedPoints();                            // #P deformed positions (geometry's local frame)
//   d.writeDeformed(shape);                        // into the shape's x/y/z (+ normals)
//
// A frame (drag / setHandleTransform) allocates nothing proportional to the shape's size.
#pragma once

#include <Eigen/Geometry>
#include <memory>
#include <string>
#include <vector>

#include "hgdeform/deformer/precompute.h"
#include "hgdeform/deformer/stretch.h"

namespace hgd {

/// A snapshot of the deformation (see Deformer::state()).
struct DeformerState {
  std::vector<NormalisedTransform> transforms;
  bool frame_mode = false;
};

/// What a replayed drag did.
struct DragResult {
  int frames = 0;
  int iterations = 0;            ///< Gauss–Newton iterations over all frames
  int max_frame_iterations = 0;  ///< the most any one frame took
  double error = 0;              ///< final distance of the picked point from the target (world units)
  bool reached = false;
  double solve_ms = 0, interpolation_ms = 0;
  SolveStats last;
};

class Deformer {
 public:
  /// The Deformer keeps a copy of `geometry`: its index maps and faces are copied, its point and
  /// normal clouds shared, so those clouds must not change while the Deformer lives.
  Deformer(const Geometry& geometry, const Handles& handles, const DeformOptions& options = {});
  /// The geometry shared, nothing of it copied (what ScenarioRunner does: the shape's index maps
  /// held once). Neither it nor its clouds may change while the Deformer lives.
  Deformer(std::shared_ptr<const Geometry> geometry, const Handles& handles,
           const DeformOptions& options = {});
  /// On a coarse level built elsewhere (a scan streamed from its file: streamedDeformer() in
  /// <hgdeform/multires/streamed.h> makes both): `geometry` holds the shape's coarse points,
  /// `handles` index it, and `level` maps it and lists the manipulated handle's points (the
  /// Deformer picks among them and takes their centre).
  Deformer(std::shared_ptr<const Geometry> geometry, const Handles& handles, const DeformOptions& options,
           std::shared_ptr<const PrebuiltLevel> level);
  Deformer(const Deformer&) = delete;
  Deformer& operator=(const Deformer&) = delete;
  ~Deformer();

  /// One interactive frame of direct manipulation: the manipulated handle's point nearest
  /// `from` (world coordinates, deformed shape) is pulled towards `to`. Continuing a drag
  /// (`from` equal to the previous `to`) keeps the picked point.
  SolveStats drag(const Eigen::Vector3d& from, const Eigen::Vector3d& to);

  /// A whole drag replayed (a scenario's "drag" move, docs/scenario.md): frames with the cursor
  /// moving from the picked point to `to`, then held there, until the picked point is within
  /// tolerance.
  DragResult dragTo(const Eigen::Vector3d& from, const Eigen::Vector3d& to);

  /// A drag that keeps the handle's orientation (a scenario's "keep_orientation", the viewer's
  /// `l`): the manipulated handle translates rigidly, without turning, so that its point nearest
  /// `from` (deformed shape) lands on `to` exactly, as ARAP tools and proportional editing drag.
  /// Continuing a drag (`from` equal to the previous `to`) keeps the picked point. Travelled in
  /// steps like moveHandle().
  SolveStats translateHandle(const Eigen::Vector3d& from, const Eigen::Vector3d& to);

  /// Frame metaphor: the manipulated handle gets the rigid (or affine) transform T, world
  /// coordinates, relative to the rest shape, exactly. A large change is travelled in steps
  /// (at most 20 degrees, a tenth of the diagonal each), as a user would turn the handle.
  SolveStats setHandleTransform(const Eigen::Affine3d& transform);

  /// Frame metaphor, relative: the manipulated handle moves by `motion` (world coordinates)
  /// from where it is now; travelled in steps like setHandleTransform().
  SolveStats moveHandle(const Eigen::Affine3d& motion);

  /// The manipulated handle's current barycentre (world coordinates).
  Eigen::Vector3d handleCentre() const;

  /// The manipulated handle's current transform (world coordinates, relative to rest).
  Eigen::Affine3d handleTransform() const;

  /// Back to the rest shape.
  void reset();

  /// New handles: the field is re-solved (normals, kNN and the graph are kept; on a
  /// multi-resolution build the coarse level, which depends on the handles, is built again), the
  /// clusters and the solver rebuilt; the shape returns to rest.
  void setHandles(const Handles& handles);

  /// The deformation state (cluster transforms): cheap to keep for undo/redo.
  DeformerState state() const;
  void restore(const DeformerState& state);

  /// Changes the blend (takes effect at once; no re-solve needed).
  void setBlend(Blend blend);

  /// Level of detail for live frames on large shapes: while `points` is not empty, every move
  /// interpolates only those points and the manipulated handle's (which picking reads); their
  /// entries of deformedPoints() and deformedNormals() are what a full interpolation gives, to
  /// the bit, and the others keep their last values. An empty list interpolates every point
  /// again, at once.
  void setPreview(std::vector<int> points);
  /// The points interpolated (setPreview's and the handle's, ascending), or empty: all.
  const std::vector<int>& preview() const;

  const std::vector<Eigen::Vector3f>& deformedPoints() const;
  /// The normals of deformedPoints() (the rest normals turned as their points' transforms
  /// turn). A move transforms positions only; the normals are derived on the first call after
  /// it (safe from concurrent const calls), so a reference kept from an earlier call shows
  /// normals as of that call until this is called again.
  const std::vector<Eigen::Vector3f>& deformedNormals() const;
  Eigen::Vector3d deformedWorld(std::size_t i) const;
  /// Writes the deformed shape into `shape`, which must hold the rest shape this deformer was
  /// built on (its geometry's source; std::logic_error otherwise, so a shape is never moved
  /// twice). Positions (and normals, where the shape has normal fields) are computed in double
  /// from the shape's own values with the current transforms (ExactInterpolation), so moved
  /// points keep the input's precision; points that do not move are not written at all and stay
  /// as the file had them, to the bit. Returns what it had to change that a front end should say
  /// (integer x/y/z widened to float or double).
  std::vector<std::string> writeDeformed(Shape& shape) const;
  /// The current deformation evaluated in double (see writeDeformed()).
  ExactInterpolation exactInterpolation() const;
  /// The same on another table of the shape's points (a block of a streamed shape's:
  /// blockProlongation()), which must outlive it.
  ExactInterpolation exactInterpolation(const InterpolationTable& table) const;
  /// On a coarse level built elsewhere (the constructor with a PrebuiltLevel): what the table of
  /// any of the shape's points needs; else null.
  std::shared_ptr<const BlockProlongation> blockProlongation() const;
  /// Each cluster's current transform in world coordinates, x -> A x + b, in double: what
  /// writeDeformed() blends (bones already projected onto rotations).
  std::vector<Eigen::Affine3d> worldTransforms() const;

  const Geometry& geometry() const;
  const Handles& handles() const;
  const std::vector<float>& field() const;
  /// The graph and field stages: at full resolution over every point; on a multi-resolution
  /// build over the coarse points (their indices are coarseLevel().points' positions).
  const SurfaceGraph& surfaceGraph() const;
  const HarmonicField& harmonicField() const;
  /// The coarse level of a multi-resolution build; empty at full resolution.
  const CoarseLevel& coarseLevel() const;
  /// Points in parts that touch no handle (at any resolution, counted over every point).
  std::size_t unreachablePoints() const;
  /// The clusters, bands and sample. Its per-point labels (lower, upper, alpha, nearest) are
  /// empty: a point's two clusters and blend factor are interpolationTable().bracket(i).
  const Clustering& clustering() const;
  const InterpolationTable& interpolationTable() const;
  /// The pieces the field did not reach, and what became of them (see pieces.h).
  const PieceAnalysis& pieces() const;
  /// Surface neighbour pairs (mesh edges, else the neighbour graph) measured on the current
  /// deformed shape, against the largest point displacement (at least 1e-4 of the diagonal).
  SurfaceStretch surfaceStretch() const;
  /// Cluster transforms in the solver's normalised frame (about each rest barycentre).
  const std::vector<NormalisedTransform>& clusterTransforms() const;
  Energies energies() const;
  const BuildTimings& buildTimings() const;
  double lastInterpolationMs() const;
  /// The picked point's index in geometry(); -1 when none is, or when it is one of a streamed
  /// shape's manipulated points the geometry does not hold.
  int picked() const;
  double diagonal() const;

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hgd
