// The Deformer's state and its implementation (internal): what deformer.h keeps behind its
// pointer, so that the public header holds no mutex, atomic or build data.
#pragma once

#include <atomic>
#include <limits>
#include <mutex>

#include "hgdeform/deformer/deformer.h"

namespace hgd {

class Deformer::Impl {
 public:
  /// normal clouds shared, so those clouds must not change while the Deformer lives.
  /// The geometry shared, nothing of it copied (what ScenarioRunner does: the shape's index maps
  /// held once). Neither it nor its clouds may change while the Deformer lives.
  Impl(std::shared_ptr<const Geometry> geometry, const Handles& handles, const DeformOptions& options);
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

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
  const std::vector<int>& preview() const { return preview_; }

  const std::vector<Eigen::Vector3f>& deformedPoints() const {
    ensureFirstShape();
    return positions_;
  }
  /// The normals of deformedPoints() (the rest normals turned as their points' transforms
  /// turn). A move transforms positions only; the normals are derived on the first call after
  /// it (safe from concurrent const calls), so a reference kept from an earlier call shows
  /// normals as of that call until this is called again.
  const std::vector<Eigen::Vector3f>& deformedNormals() const;
  Eigen::Vector3d deformedWorld(std::size_t i) const {
    ensureFirstShape();
    return positions_[i].cast<double>() + geometry_->origin;
  }
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
  /// Each cluster's current transform in world coordinates, x -> A x + b, in double: what
  /// writeDeformed() blends (bones already projected onto rotations).
  std::vector<Eigen::Affine3d> worldTransforms() const;

  const Geometry& geometry() const { return *geometry_; }
  const Handles& handles() const { return handles_; }
  const std::vector<float>& field() const { return data_.phi; }
  /// The graph and field stages: at full resolution over every point; on a multi-resolution
  /// build over the coarse points (their indices are coarseLevel().points' positions).
  const SurfaceGraph& surfaceGraph() const { return *data_.graph; }
  const HarmonicField& harmonicField() const { return data_.field; }
  /// The coarse level of a multi-resolution build; empty at full resolution.
  const CoarseLevel& coarseLevel() const { return data_.coarse; }
  /// Points in parts that touch no handle (at any resolution, counted over every point).
  std::size_t unreachablePoints() const { return data_.unreachable_points; }
  /// The clusters, bands and sample. Its per-point labels (lower, upper, alpha, nearest) are
  /// empty: a point's two clusters and blend factor are interpolationTable().bracket(i).
  const Clustering& clustering() const { return data_.clustering; }
  const InterpolationTable& interpolationTable() const { return data_.table; }
  /// The pieces the field did not reach, and what became of them (see pieces.h).
  const PieceAnalysis& pieces() const { return data_.pieces; }
  /// Surface neighbour pairs (mesh edges, else the neighbour graph) measured on the current
  /// deformed shape, against the largest point displacement (at least 1e-4 of the diagonal).
  SurfaceStretch surfaceStretch() const;
  /// Cluster transforms in the solver's normalised frame (about each rest barycentre).
  const std::vector<NormalisedTransform>& clusterTransforms() const { return solver_.transforms(); }
  Energies energies() const { return solver_.energies(); }
  const BuildTimings& buildTimings() const { return data_.timings; }
  double lastInterpolationMs() const { return interp_ms_; }
  int picked() const { return picked_; }
  double diagonal() const { return 1.0 / scale_; }

  // What was private when these were the Deformer's own members.
  /// A drag after frame moves: the manipulated cluster is freed for shape matching.
  void leaveFrameMode();
  /// precompute(), then the preview table and the solver's set-up; the shape at rest.
  void rebuild();
  SolveStats dragFrame(const Eigen::Vector3d& to);
  SolveStats solveHandle(const Eigen::Affine3d& transform);
  Eigen::Vector3d pickedWorld() const;
  void updateShape(bool lazy = false);  ///< lazy: the build's first shape (first_shape_)
  /// Brings out_normals_ up to the last move.
  void updateNormals() const;
  void buildPreviewTable();
  Eigen::Vector3d normalise(const Eigen::Vector3d& local) const { return (local - centre_) * scale_; }
  Eigen::Vector3d currentNormalised(int cluster, const Eigen::Vector3d& rest) const;
  void pick(const Eigen::Vector3d& world);

  std::shared_ptr<const Geometry> geometry_;
  Handles handles_;
  DeformOptions options_;
  DeformationData data_;
  std::vector<int> preview_request_;  ///< setPreview's points (empty: all)
  std::vector<int> preview_;          ///< with the manipulated handle's, sorted
  InterpolationTable preview_table_;  ///< table_'s rows for them
  std::vector<Eigen::Vector3f> preview_points_;
  mutable std::vector<Eigen::Vector3f> preview_normals_;
  ClusterSolver solver_;
  bool frame_mode_ = false;
  Eigen::Vector3d centre_ = Eigen::Vector3d::Zero();
  double scale_ = 1;
  // Shape matching of the manipulated handle.
  std::vector<Eigen::Vector3d> manip_rest_, manip_target_;
  std::vector<double> manip_weight_;
  int picked_ = -1;
  Eigen::Vector3d last_to_ = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  // Per-frame buffers.
  std::vector<LocalTransform> local_;
  std::vector<ExactTransform> exact_;  ///< the same transforms in double, for writing
  // The shape a (re)build starts from is interpolated when it is first read, and only the
  // manipulated handle's points when a move reads just those (pick, handleCentre): a program
  // that moves at once and writes in double (`hgdeform deform`) never reads the rest.
  mutable std::vector<Eigen::Vector3f> positions_;
  struct DueShape {
    std::mutex mutex;               // const readers may settle it concurrently
    std::atomic<bool> due{false};   // positions_ do not hold the build's first shape yet
    bool handle_done = false;       // ... except the manipulated handle's points
    Blend blend = Blend::Rotation;  // the build's (setBlend changes options_ first)
  };
  mutable DueShape first_shape_;
  /// Settles the first shape (a lock only while it is due: readers call this for every point).
  void ensureFirstShape() const {
    if (first_shape_.due.load(std::memory_order_acquire)) settleFirstShape();
  }
  void settleFirstShape() const;
  /// Calls read(positions_) for reading the manipulated handle's points only, with only those
  /// settled, under the first shape's lock (a concurrent settle rewrites them).
  template <typename Read>
  void readHandlePositions(Read&& read) const;
  /// The rows of data_.table for `points` (ascending), as one table.
  InterpolationTable subTable(const std::vector<int>& points) const;
  // Normals are derived when asked for, each point's from the transforms its position came
  // from: the last full frame's (kept here) and, for the preview's points, the current ones.
  mutable std::vector<Eigen::Vector3f> out_normals_;
  struct DueNormals {
    std::mutex mutex;  // const readers may derive them concurrently
    bool all_due = false, preview_due = false;
    std::vector<LocalTransform> all_transforms;
    Blend all_blend = Blend::Rotation;
  };
  mutable DueNormals normals_;
  double interp_ms_ = 0;
};

}  // namespace hgd
