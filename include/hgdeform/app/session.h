// One shape, its handles and the deformer built for them: the session every front end holds.
//
//   hgd::Session s(shape, options);           // the geometry (normals, kNN later) of the shape
//   s.setFixedIndices({{0, 1, 2}});           // handles by point index (file order) ...
//   s.setManipulatedIndices({97, 98, 99});
//   s.setScenario(scenario);                  // ... or a scenario's regions (replaces them whole)
//   s.ensureBuilt();                          // the deformer, built when due
//   s.applyMove(move);                        // one move, solved as `hgdeform deform` solves it
//
// ScenarioRunner adds to it what the CLI and the viewer need (moves recorded for undo, live
// frames, the report, writing); the PCL stage (pcl.h) and the Python module are thin over it.
// Nothing is built until ensureBuilt(): the handles and options may change any number of times
// before, and each change is built once. What a change costs:
//   - new handles (or a scenario with other regions): the field, the clusters and the solver are
//     built again; normals, kNN and the graph are kept;
//   - another blend (setBlend(), or a scenario that differs in its blend alone): applied at
//     once, nothing built;
//   - another isovalue count, resolution (a scenario's `full_resolution`) or RunOptions, or another
//     shape: a new Deformer. A view of the old one (sharedDeformer()) keeps it alive.
#pragma once

#include <Eigen/Geometry>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "hgdeform/app/scenario.h"
#include "hgdeform/deformer/deformer.h"
#include "hgdeform/io/io.h"
#include "hgdeform/io/shape.h"

namespace hgd {

/// Options a front end sets beside a scenario. Where both say something, the front end wins:
/// `clusters` and `blend` override the scenario's values; unset, the scenario's, else the
/// defaults in `deform`.
struct RunOptions {
  DeformOptions deform;
  std::optional<int> clusters;  ///< isovalue count
  std::optional<Blend> blend;
};

/// What one move did.
struct MoveResult {
  int frames = 0;
  int iterations = 0;
  int max_frame_iterations = 0;
  bool reached = true;      ///< drags: the picked point reached its target
  double handle_error = 0;  ///< drags: final distance of the picked point from the target
  double solve_ms = 0, interpolation_ms = 0;
  std::string warning;  ///< empty, or why the move ended short
};

/// The motion of a frame move: the rotation about `centre` (the move's own centre when it has
/// one, else `handle_centre`), then the translation; world coordinates.
Eigen::Affine3d frameMotion(const FrameMove& move, const Eigen::Vector3d& handle_centre);

/// Applies one move to a deformer as every front end does (Session::applyMove; `number`: the
/// move's, for messages).
MoveResult applyMove(Deformer& deformer, const Move& move, int number = 1);

/// The deformation options of a run of `scenario`: the run's, its isovalue count and blend
/// winning over the scenario's, the scenario's "resolution" (Session::mergedOptions but for an
/// organized shape's viewpoint).
DeformOptions mergedOptions(const RunOptions& options, const Scenario& scenario);

class Session {
 public:
  /// A session without a shape yet (setShape()); handles and options may be set already.
  Session();
  explicit Session(Shape shape, const RunOptions& options = {});
  Session(Session&&) noexcept;
  Session& operator=(Session&&) noexcept;
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;
  ~Session();

  /// Another shape: the deformer is dropped; handles by scenario or index and the options are
  /// kept (resolved again on the new shape at the next build); handles given by setHandles()
  /// (indices into the old geometry) give way to the regions of setRegions(). If the shape has
  /// no point to deform (extractGeometry throws), the session is left as it was.
  void setShape(Shape shape);
  bool hasShape() const { return geometry_ != nullptr; }

  /// Other options: the next build makes a new deformer.
  void setOptions(const RunOptions& options);
  const RunOptions& options() const { return options_; }

  /// Handles (and clusters, blend, resolution) from a scenario's regions; its moves are kept
  /// (scenario().moves) for the caller to apply. Replaces handles set by index whole. With
  /// `resolve_now` (a shape is there) the regions are resolved at once: a region that does not
  /// fit throws ScenarioError here and the session is left as it was.
  void setScenario(const Scenario& scenario, bool resolve_now = false);
  /// Handles by point index (file order). Each replaces a scenario given before whole (its
  /// regions, moves and options); the other handles set by index stay.
  void setFixedIndices(const std::vector<std::vector<long long>>& handles);
  void setManipulatedIndices(std::vector<long long> handle);
  void setJointIndices(const std::vector<std::vector<long long>>& joints);
  /// Handles already resolved (indices into geometry()): the viewer's marking. An empty fixed or
  /// manipulated handle leaves the session without a deformer until both are there. The regions
  /// of the scenario() are left as they are (setRegions()).
  void setHandles(const Handles& handles);
  /// The regions scenario() holds for handles set with setHandles() (what replays them).
  void setRegions(std::vector<Region> fixed, Region manipulated, std::vector<Region> joints);
  /// Changes the blend at once (no re-solve, no rebuild).
  void setBlend(Blend blend);

  /// "fixed" or "manipulated" when that handle is not given yet (by scenario, index or
  /// setHandles), else empty: what ensureBuilt() would refuse.
  std::string missingHandle() const;

  /// Builds what is due (see the top of this file): the handles resolved on the shape, the
  /// options merged with the scenario's, the deformer built or rebuilt. The shape is then at
  /// rest; the scenario's moves are not applied (the caller's choice). True when it built;
  /// false when nothing was due, or when setHandles() left a handle empty. Throws
  /// std::logic_error without a shape, ScenarioError when a handle is missing (missingHandle())
  /// or a region does not fit the shape.
  bool ensureBuilt();
  /// A deformer for the current handles and options (ensureBuilt() has nothing to do).
  bool ready() const { return deformer_ != nullptr && built_; }

  /// One move from the deformer's current state, solved as `hgdeform deform` solves it: a drag
  /// replayed frame by frame until the picked point arrives (Deformer::dragTo), a drag that keeps
  /// orientation as one translation, a frame move as its frameMotion() about the handle's current
  /// centre. `number` (1, 2, ...) names the move in a warning. Requires ready().
  MoveResult applyMove(const Move& move, int number = 1);

  /// The deformer (ready() must be true).
  Deformer& deformer();
  const Deformer& deformer() const;
  /// The deformer, kept alive as long as the pointer is held (views of its buffers).
  std::shared_ptr<const Deformer> sharedDeformer() const;

  /// The options of the current build: RunOptions merged with the scenario's and the shape's
  /// (an organized scan's sensor viewpoint).
  DeformOptions mergedOptions() const;
  /// The same for another scenario (what the field alone of that scenario would use).
  DeformOptions mergedOptions(const Scenario& scenario) const;

  /// The regions (by scenario, index or setRegions()), clusters, blend and moves given.
  const Scenario& scenario() const { return scenario_; }
  const Handles& handles() const { return handles_; }
  const Shape& shape() const { return shape_; }
  /// The shape itself, for writing the deformed positions into it (Deformer::writeDeformed):
  /// nothing else of it may change while the session uses it.
  Shape& mutableShape() { return shape_; }
  const Geometry& geometry() const;
  const std::shared_ptr<const Geometry>& sharedGeometry() const { return geometry_; }
  /// The phases of the session's own work (the geometry, the handles), before the Deformer's.
  const std::vector<BuildPhase>& phases() const { return phases_; }
  /// What reading and extracting the geometry noted.
  const std::vector<std::string>& warnings() const { return warnings_; }

  /// Hands the shape over (as it is: the caller writes the deformed positions into it). The
  /// deformer and geometry stay for report()s; nothing else that needs the shape may be called.
  Shape releaseShape();

 private:
  void requireShape(const char* what) const;
  /// Handles by index replace a scenario given before (its regions, moves and options) whole.
  Scenario& indexHandles();

  Shape shape_;
  std::shared_ptr<const Geometry> geometry_;  // shared with the deformer
  RunOptions options_;
  Scenario scenario_;
  bool from_scenario_ = false;  // scenario_ was given whole (setScenario)
  bool direct_ = false;         // handles_ set by setHandles(), not resolved from scenario_
  bool resolved_ = false;       // handles_ resolved from scenario_ already (setScenario(.., true))
  Handles handles_;
  std::shared_ptr<Deformer> deformer_;
  std::optional<DeformOptions> built_options_;  // the options deformer_ was built with
  bool built_ = false;
  std::vector<BuildPhase> phases_;
  std::vector<std::string> warnings_;
};

}  // namespace hgd
