// The scenario runner: the one place where a scenario is applied to a shape. Every front end
// (`hgdeform deform`, `hgdeform batch`, the viewer, the PCL entry in pcl.h) is a client:
//
//   hgd::ScenarioRunner run = hgd::ScenarioRunner::read("scan.pcd", options);  // read time kept
//   run.setScenario(scenario);     // handles resolved, options merged, deformer built
//   run.applyMoves();              // every move of the scenario, recorded for undo
//   run.write("out.pcd");          // refuses to replace an input; write time kept
//   hgd::writeReportJson("r.json", run.report());
//
// Interactive clients set handles directly (setHandles), apply moves one at a time (apply),
// show live frames between them (liveDrag) and step through undo()/redo(). The shape, the
// handles and the deformer's build are its Session's (session.h), which the PCL stage and the
// Python module hold as well.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "hgdeform/app/scenario.h"
#include "hgdeform/app/session.h"
#include "hgdeform/deformer/deformer.h"
#include "hgdeform/io/io.h"
#include "hgdeform/io/shape.h"

namespace hgd {

/// What `hgdeform deform` reports (see report.h for the JSON).
struct DeformReport {
  std::size_t points = 0;
  std::size_t sample = 0;
  std::size_t clusters = 0;
  int isovalues = 0;  ///< the isovalue count asked for
  std::size_t unreachable = 0;
  int iterations = 0;
  int frames = 0;
  int max_frame_iterations = 0;
  bool reached = true;
  double handle_error = 0;            ///< world units; drags only
  std::vector<std::string> notes;     ///< what clustering merged or adjusted (overlapping joints)
  std::vector<std::string> warnings;  ///< a move that ended short, pieces no handle reached, splits
  PieceReport pieces;                 ///< parts that touch no fixed handle (see pieces.h)
  SurfaceStretch surface;             ///< after the moves (see stretch.h)
  Energies energy;
  double read_ms = 0, build_ms = 0, field_ms = 0, sampling_ms = 0, clusters_ms = 0, solve_ms = 0,
         solve_per_iteration_ms = 0, interpolation_ms = 0, write_ms = 0, total_ms = 0;
  BuildTimings build;
  /// The program's peak resident memory in MB when the report was made (Linux's VmHWM: this
  /// process image only, not the parent it was forked from). `hgdeform deform` sets it; 0 (left
  /// out of the JSON) elsewhere: a library call shares its process with whatever else runs there.
  double peak_rss_mb = 0;
  /// Whether the program ran with glibc's huge-page malloc (GLIBC_TUNABLES glibc.malloc.hugetlb,
  /// which `hgdeform deform` turns on for large inputs): the timings depend on it. Set by the
  /// program, as peak_rss_mb; false (left out of the JSON) elsewhere.
  bool huge_page_malloc = false;
};

/// The harmonic field of a scenario's handles over every point (`hgdeform field`).
struct FieldResult {
  std::vector<float> values;  ///< one per point of the geometry: 1 on the manipulated handle, 0 on the fixed
  FieldTimings timings;       ///< the field stage's
  std::size_t unreachable = 0;  ///< points in parts that touch no handle (their value is 0)
  Handles handles;              ///< the scenario's, resolved on the shape
};

class ScenarioRunner {
 public:
  /// Reads `path` (any format readShape() takes); the time goes into the report.
  static ScenarioRunner read(const std::string& path, const RunOptions& options = {});
  explicit ScenarioRunner(Shape shape, const RunOptions& options = {});
  /// A runner without a shape yet (setShape()): handles and options may be set on session().
  ScenarioRunner();
  /// Another shape (the PCL stage's new input): the deformer and the history go; handles and
  /// options stay, built on the new shape at the next ensureBuilt().
  void setShape(Shape shape);
  ScenarioRunner(ScenarioRunner&&) noexcept;
  ScenarioRunner& operator=(ScenarioRunner&&) noexcept;
  ScenarioRunner(const ScenarioRunner&) = delete;
  ScenarioRunner& operator=(const ScenarioRunner&) = delete;
  ~ScenarioRunner();

  /// Resolves the scenario's handles, merges its clusters/blend with the options and builds
  /// the deformer (normals and kNN are kept from an earlier build). Its moves are not applied
  /// yet (applyMoves()). Throws ScenarioError when a region does not fit the shape.
  void setScenario(const Scenario& scenario);

  /// The harmonic field alone for the scenario's handles: at full resolution, over every point,
  /// with the options' field settings and the sensor viewpoint of mergedOptions(). Nothing of the
  /// runner changes (no deformer is built, its handles stay). Throws ScenarioError when a region
  /// does not fit the shape.
  FieldResult field(const Scenario& scenario) const;

  /// Handles chosen directly (indices into geometry()); an empty fixed or manipulated handle
  /// leaves the runner without a deformer (ready() is false) until both are there. The
  /// recorded moves and undo history are cleared; the shape returns to rest.
  void setHandles(const Handles& handles);

  /// The regions a saved scenario holds for the current handles (set by setScenario, or
  /// index regions for handles set directly).
  void setRegions(std::vector<Region> fixed, Region manipulated, std::vector<Region> joints);

  bool ready() const { return session_.ready(); }

  /// Builds the deformer if the session has something due (handles or options changed through
  /// session()); the history is cleared when it builds. True when it built: the caller then
  /// applies the scenario's moves (applyMoves()) if it wants them.
  bool ensureBuilt();

  /// Applies every move of the scenario given to setScenario(), in order.
  void applyMoves();

  /// Applies one move (from the last applied state: live frames since are dropped) and
  /// records it; the redo list is cleared. A frame move without a centre turns about the
  /// handle's current barycentre.
  MoveResult apply(const Move& move);

  /// One interactive frame of a drag, shown but not recorded: the next apply(), undo() or
  /// dropLive() returns to the last applied state first. `keep_orientation`: the handle
  /// translates without turning (Deformer::translateHandle). `preview` (a level of detail for
  /// large shapes: Deformer::setPreview): only those points are interpolated in live frames;
  /// leaving the live frames interpolates every point again.
  SolveStats liveDrag(const Eigen::Vector3d& from, const Eigen::Vector3d& to, bool keep_orientation = false,
                      const std::vector<int>* preview = nullptr);
  /// Back to the last applied state, if live frames moved the shape.
  void dropLive();

  /// A live frame that is the move's own result: from the last applied state (each call starts
  /// there again), `move` solved exactly as apply() solves it, shown but not recorded. With
  /// `preview` (as liveDrag's) only those points are interpolated. commitLive() then keeps it:
  /// what was shown is what is applied, point for point, and `hgdeform deform` replays it.
  MoveResult previewMove(const Move& move, const std::vector<int>* preview = nullptr);
  /// Records the move of the last previewMove() as apply() would, without solving again (the
  /// preview's level of detail is left: every point interpolated with the same transforms).
  /// Nothing (std::nullopt) when the live frames are not a previewMove().
  std::optional<MoveResult> commitLive();

  bool undo();  ///< false when there is nothing to undo
  bool redo();  ///< false when there is nothing to redo
  /// Back to the rest shape; the recorded moves and history are cleared.
  void reset();

  /// Changes the blend at once (no re-solve).
  void setBlend(Blend blend);

  /// The moves applied so far (after undo: without the undone ones).
  const std::vector<Move>& moves() const { return moves_; }
  /// The current handles' regions, the options' clusters/blend and the applied moves: what
  /// replays this state with `hgdeform deform`.
  Scenario scenario() const;

  /// The report of everything so far: build, every applied move, the surface stretch now,
  /// read and write times.
  DeformReport report() const;

  /// The rest shape as read.
  const Shape& shape() const { return session_.shape(); }
  /// A copy of the shape with the deformed positions (and rotated normals).
  Shape deformedShape() const;
  /// Writes the deformed shape to `path`: refuses to replace any of `inputs` (the shape's own
  /// path is always one); notes in the report what the format cannot hold; time into the
  /// report. A failed write leaves no file.
  void write(const std::string& path, const WriteOptions& options = {},
             const std::vector<std::string>& inputs = {});
  /// write() for a run that ends with it: the deformed positions go into the runner's own shape
  /// instead of a copy, so the shape is held once (what a one-shot command wants). Once the
  /// write has begun (the output path was accepted), the runner holds no shape, written or not:
  /// only report() may still be called; anything else that needs the shape throws
  /// std::logic_error.
  void writeAndRelease(const std::string& path, const WriteOptions& options = {},
                       const std::vector<std::string>& inputs = {});
  /// Hands the shape over without a copy: deformed (positions and normals written into it) or
  /// at rest. The runner holds no shape afterwards; only report() may still be called (as after
  /// writeAndRelease()).
  Shape release(bool deformed = true);

  const Geometry& geometry() const { return session_.geometry(); }
  const Handles& handles() const { return session_.handles(); }
  /// The deformer (ready() must be true).
  const Deformer& deformer() const { return session_.deformer(); }
  /// The deformer for direct frames (Deformer::drag, setHandleTransform): those are not
  /// recorded as moves, and undo() does not see them.
  Deformer& deformer() { return session_.deformer(); }
  /// The deformer, alive as long as the pointer is held (a view of its buffers outlives a rebuild).
  std::shared_ptr<const Deformer> sharedDeformer() const { return session_.sharedDeformer(); }
  const RunOptions& options() const { return session_.options(); }
  /// The session (shape, handles, options, deformer). Changes go through the runner, which keeps
  /// its history and live frames consistent with them:
  const Session& session() const { return session_; }
  /// Handles by point index (file order), built at the next ensureBuilt(); each replaces a
  /// scenario given before whole (Session::setFixedIndices).
  void setFixedIndices(const std::vector<std::vector<long long>>& handles);
  void setManipulatedIndices(std::vector<long long> handle);
  void setJointIndices(const std::vector<std::vector<long long>>& joints);
  /// A scenario's handles and options, built at the next ensureBuilt() (setScenario() builds at
  /// once): what a front end that receives its input later (the PCL stage) gives.
  void setScenarioLater(const Scenario& scenario);
  /// Other options: the deformer, the live frames and the history go; the next ensureBuilt()
  /// builds a new deformer.
  void setOptions(const RunOptions& options);

 private:
  /// Builds what the session has due; the history goes when it builds (the shape is at rest).
  void build();
  /// Throws std::logic_error naming `what` once the shape was handed over.
  void requireShape(const char* what) const;
  void writeOut(const std::string& path, const WriteOptions& options, const std::vector<std::string>& inputs,
                bool release_shape);
  void noteWriteWarnings(const std::vector<std::string>& warnings);
  void clearHistory();
  /// Enters live frames (the last applied state kept for dropLive(), `preview` set); false
  /// when already in them.
  bool beginLive(const std::vector<int>* preview);
  /// Records an applied move and its result; the redo list is cleared.
  void record(const Move& move, const MoveResult& result);

  Session session_;
  std::vector<Move> moves_;
  std::vector<std::pair<Move, MoveResult>> undone_;
  std::vector<DeformerState> history_, redo_states_;
  std::vector<MoveResult> results_;  // one per applied move
  std::vector<std::string> write_warnings_;
  bool live_ = false;
  std::optional<Move> live_move_;  // the move the live frame shows (previewMove), if any
  std::optional<MoveResult> live_result_;
  bool released_ = false;  // the shape was handed over (release, writeAndRelease)
  double read_ms_ = 0, build_ms_ = 0, write_ms_ = 0;
};

/// The whole of `hgdeform deform` on a shape already read: the scenario applied by a
/// ScenarioRunner, positions (and normals) stored back into `shape`.
DeformReport deformShape(Shape& shape, const Scenario& scenario, const DeformOptions& options = {});

}  // namespace hgd
