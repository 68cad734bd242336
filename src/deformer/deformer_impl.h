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
  // The Deformer's API, each the implementation of the call of that name (deformer.h documents
  // them).
  Impl(std::shared_ptr<const Geometry> geometry, const Handles& handles, const DeformOptions& options,
       std::shared_ptr<const PrebuiltLevel> level = nullptr);
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;
  SolveStats drag(const Eigen::Vector3d& from, const Eigen::Vector3d& to);
  DragResult dragTo(const Eigen::Vector3d& from, const Eigen::Vector3d& to);
  SolveStats translateHandle(const Eigen::Vector3d& from, const Eigen::Vector3d& to);
  SolveStats setHandleTransform(const Eigen::Affine3d& transform);
  SolveStats moveHandle(const Eigen::Affine3d& motion);
  Eigen::Vector3d handleCentre() const;
  Eigen::Affine3d handleTransform() const;
  void reset();
  void setHandles(const Handles& handles);
  DeformerState state() const;
  void restore(const DeformerState& state);
  void setBlend(Blend blend);
  void setPreview(std::vector<int> points);
  const std::vector<int>& preview() const { return preview_; }
  const std::vector<Eigen::Vector3f>& deformedPoints() const {
    ensureFirstShape();
    return positions_;
  }
  const std::vector<Eigen::Vector3f>& deformedNormals() const;
  Eigen::Vector3d deformedWorld(std::size_t i) const {
    ensureFirstShape();
    return positions_[i].cast<double>() + geometry_->origin;
  }
  std::vector<std::string> writeDeformed(Shape& shape) const;
  ExactInterpolation exactInterpolation() const { return exactInterpolation(data_.table); }
  ExactInterpolation exactInterpolation(const InterpolationTable& table) const;
  std::shared_ptr<const BlockProlongation> blockProlongation() const { return data_.blocks; }
  std::vector<Eigen::Affine3d> worldTransforms() const;
  const Geometry& geometry() const { return *geometry_; }
  const Handles& handles() const { return handles_; }
  const std::vector<float>& field() const { return data_.phi; }
  const SurfaceGraph& surfaceGraph() const { return *data_.graph; }
  const HarmonicField& harmonicField() const { return data_.field; }
  const CoarseLevel& coarseLevel() const { return data_.coarse; }
  std::size_t unreachablePoints() const { return data_.unreachable_points; }
  const Clustering& clustering() const { return data_.clustering; }
  const InterpolationTable& interpolationTable() const { return data_.table; }
  const PieceAnalysis& pieces() const { return data_.pieces; }
  SurfaceStretch surfaceStretch() const;
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
  // The picked point: its geometry index (-1: none picked, or one the geometry does not hold),
  // its index among the level's manipulated_rest (a streamed shape's; else -1), its rest local
  // position.
  int picked_ = -1;
  int picked_external_ = -1;
  Eigen::Vector3f picked_rest_ = Eigen::Vector3f::Zero();
  bool hasPick() const { return picked_ >= 0 || picked_external_ >= 0; }
  void unpick() { picked_ = picked_external_ = -1; }
  /// The picked point's deformed local position.
  Eigen::Vector3f pickedNow() const;
  /// The level's manipulated handle points when the geometry does not hold them (else null).
  const std::vector<Eigen::Vector3f>* externalHandle() const {
    return data_.prebuilt && !data_.prebuilt->manipulated_rest.empty() ? &data_.prebuilt->manipulated_rest
                                                                       : nullptr;
  }
  /// Calls fn(k, deformed local position) for the external handle points [first, first + count)
  /// of a block: what interpolatePositions gives their pinned rows, as for the points it holds.
  void externalPositions(std::size_t first, std::size_t count, std::vector<Eigen::Vector3f>& out) const;
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
