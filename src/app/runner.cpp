#include "hgdeform/app/runner.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <utility>

#include "deformer/precompute_internal.h"
#include "hgdeform/app/regions.h"
#include "hgdeform/app/report.h"
#include "util/phases.h"
#include "util/timer.h"

namespace hgd {

ScenarioRunner ScenarioRunner::read(const std::string& path, const RunOptions& options) {
  Stopwatch t;
  Shape shape = readShape(path);
  const double read_ms = t.ms();
  ScenarioRunner run(std::move(shape), options);
  run.read_ms_ = read_ms;
  return run;
}

ScenarioRunner::ScenarioRunner() = default;

ScenarioRunner::ScenarioRunner(Shape shape, const RunOptions& options) {
  session_.setOptions(options);
  setShape(std::move(shape));
}

void ScenarioRunner::setShape(Shape shape) {
  Stopwatch t;
  dropLive();
  session_.setShape(std::move(shape));  // (throws with nothing changed)
  clearHistory();
  released_ = false;
  write_warnings_.clear();
  read_ms_ = write_ms_ = 0;
  build_ms_ = t.ms();
}

ScenarioRunner::ScenarioRunner(ScenarioRunner&&) noexcept = default;
ScenarioRunner& ScenarioRunner::operator=(ScenarioRunner&&) noexcept = default;
ScenarioRunner::~ScenarioRunner() = default;

void ScenarioRunner::setScenario(const Scenario& scenario) {
  requireShape("setScenario");
  Stopwatch t;
  session_.setScenario(scenario, true);  // a region that does not fit throws here: nothing lost
  build();
  build_ms_ += t.ms();
}

FieldResult ScenarioRunner::field(const Scenario& scenario) const {
  requireShape("field");
  FieldResult r;
  const Geometry& geometry = session_.geometry();
  r.handles = resolveHandles(scenario, geometry, session_.shape());
  const Handles& handles = r.handles;
  HarmonicField field;  // at full resolution, as Deformer's on a shape below multires_above
  setGraphInput(field.surfaceGraph(), geometry);
  field.setOptions(session_.mergedOptions(scenario).field);
  field.setHandles(handles.fixed, handles.manipulated);
  field.compute(r.values);
  r.timings = field.timings();
  r.unreachable = field.unreachable().size();
  return r;
}

void ScenarioRunner::setHandles(const Handles& handles) {
  requireShape("setHandles");
  dropLive();  // a live frame's level of detail goes with it (before the deformer may go)
  clearHistory();
  session_.setHandles(handles);
  build();
}

void ScenarioRunner::setRegions(std::vector<Region> fixed, Region manipulated, std::vector<Region> joints) {
  session_.setRegions(std::move(fixed), std::move(manipulated), std::move(joints));
}

void ScenarioRunner::build() {
  if (session_.ready()) return;
  dropLive();  // a live frame's level of detail goes with it
  clearHistory();
  session_.ensureBuilt();
}

void ScenarioRunner::setFixedIndices(const std::vector<std::vector<long long>>& handles) {
  session_.setFixedIndices(handles);
}

void ScenarioRunner::setManipulatedIndices(std::vector<long long> handle) {
  session_.setManipulatedIndices(std::move(handle));
}

void ScenarioRunner::setJointIndices(const std::vector<std::vector<long long>>& joints) {
  session_.setJointIndices(joints);
}

void ScenarioRunner::setScenarioLater(const Scenario& scenario) {
  session_.setScenario(scenario);
}

void ScenarioRunner::setOptions(const RunOptions& options) {
  dropLive();
  clearHistory();
  session_.setOptions(options);
}

bool ScenarioRunner::ensureBuilt() {
  requireShape("ensureBuilt");
  if (session_.ready()) return false;
  Stopwatch t;
  build();
  build_ms_ += t.ms();
  return session_.ready();
}

void ScenarioRunner::clearHistory() {
  moves_.clear();
  undone_.clear();
  history_.clear();
  redo_states_.clear();
  results_.clear();
  live_ = false;
  live_move_.reset();
  live_result_.reset();
}

void ScenarioRunner::applyMoves() {
  const std::vector<Move> moves = session_.scenario().moves;  // apply() may not change them, but be safe
  for (const Move& m : moves) apply(m);
}

MoveResult ScenarioRunner::apply(const Move& move) {
  requireShape("apply");
  if (!ready()) throw std::logic_error("ScenarioRunner::apply: no handles yet");
  dropLive();
  history_.push_back(deformer().state());
  const MoveResult r = session_.applyMove(move, static_cast<int>(moves_.size()) + 1);
  record(move, r);
  return r;
}

void ScenarioRunner::record(const Move& move, const MoveResult& result) {
  moves_.push_back(move);
  results_.push_back(result);
  undone_.clear();
  redo_states_.clear();
}

MoveResult ScenarioRunner::previewMove(const Move& move, const std::vector<int>* preview) {
  requireShape("previewMove");
  if (!ready()) throw std::logic_error("ScenarioRunner::previewMove: no handles yet");
  if (!beginLive(preview)) deformer().restore(history_.back());  // each preview starts where apply() would
  live_move_ = move;
  live_result_ = session_.applyMove(move, static_cast<int>(moves_.size()) + 1);
  return *live_result_;
}

std::optional<MoveResult> ScenarioRunner::commitLive() {
  if (!live_ || !live_move_ || !live_result_) return std::nullopt;
  live_ = false;  // the state before the gesture stays in history_, as apply() leaves it
  if (!deformer().preview().empty()) deformer().setPreview({});  // every point, same transforms
  const Move move = *live_move_;
  const MoveResult r = *live_result_;
  live_move_.reset();
  live_result_.reset();
  record(move, r);
  return r;
}

SolveStats ScenarioRunner::liveDrag(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                                    bool keep_orientation, const std::vector<int>* preview) {
  requireShape("liveDrag");
  if (!ready()) throw std::logic_error("ScenarioRunner::liveDrag: no handles yet");
  beginLive(preview);
  live_move_.reset();  // incremental frames: no move to commit as shown
  live_result_.reset();
  return keep_orientation ? deformer().translateHandle(from, to) : deformer().drag(from, to);
}

bool ScenarioRunner::beginLive(const std::vector<int>* preview) {
  if (live_) return false;
  history_.push_back(deformer().state());  // the last applied state, taken back by dropLive()
  live_ = true;
  if (preview) deformer().setPreview(*preview);
  return true;
}

void ScenarioRunner::dropLive() {
  if (!live_) return;
  live_ = false;
  live_move_.reset();
  live_result_.reset();
  deformer().restore(history_.back());  // with a preview, its points only
  history_.pop_back();
  if (!deformer().preview().empty()) deformer().setPreview({});  // then every point
}

bool ScenarioRunner::undo() {
  dropLive();
  if (history_.empty()) return false;
  redo_states_.push_back(deformer().state());
  undone_.emplace_back(moves_.back(), results_.back());
  moves_.pop_back();
  results_.pop_back();
  deformer().restore(history_.back());
  history_.pop_back();
  return true;
}

bool ScenarioRunner::redo() {
  dropLive();
  if (undone_.empty()) return false;
  history_.push_back(deformer().state());
  moves_.push_back(undone_.back().first);
  results_.push_back(undone_.back().second);
  undone_.pop_back();
  deformer().restore(redo_states_.back());
  redo_states_.pop_back();
  return true;
}

void ScenarioRunner::reset() {
  dropLive();  // a live frame's level of detail goes with it (else only its points would reset)
  if (session_.sharedDeformer()) deformer().reset();
  clearHistory();
}

void ScenarioRunner::setBlend(Blend blend) {
  session_.setBlend(blend);
}

Scenario ScenarioRunner::scenario() const {
  Scenario s = session_.scenario();
  s.moves = moves_;
  const RunOptions& options = session_.options();
  if (options.clusters) s.clusters = options.clusters;
  if (options.blend) s.blend = options.blend;
  return s;
}

DeformReport ScenarioRunner::report() const {
  DeformReport rep;
  rep.read_ms = read_ms_;
  rep.build_ms = read_ms_ + build_ms_;  // everything before the first solve
  rep.points = session_.sharedGeometry() ? session_.sharedGeometry()->size() : 0;
  rep.write_ms = write_ms_;
  if (const std::shared_ptr<const Deformer> shared = session_.sharedDeformer()) {
    const Deformer& d = *shared;
    describeRun(d, moves_, results_, session_.mergedOptions().clusters.isovalues, rep);
    // The runner's own phases (the geometry, the handles) before the Deformer's.
    rep.build.phases.insert(rep.build.phases.begin(), session_.phases().begin(), session_.phases().end());
    rep.surface = d.surfaceStretch();
    if (const std::string w = stretchWarning(rep.surface); !w.empty()) rep.warnings.push_back(w);
  }
  rep.warnings.insert(rep.warnings.begin(), session_.warnings().begin(), session_.warnings().end());
  rep.warnings.insert(rep.warnings.end(), write_warnings_.begin(), write_warnings_.end());
  rep.total_ms = rep.build_ms + rep.solve_ms + rep.interpolation_ms + rep.write_ms;
  return rep;
}

Shape ScenarioRunner::deformedShape() const {
  requireShape("deformedShape");
  Shape out = session_.shape();
  if (ready()) deformer().writeDeformed(out);
  return out;
}

void ScenarioRunner::noteWriteWarnings(const std::vector<std::string>& warnings) {
  for (const std::string& w : warnings)
    if (std::find(write_warnings_.begin(), write_warnings_.end(), w) == write_warnings_.end())
      write_warnings_.push_back(w);
}

void ScenarioRunner::write(const std::string& path, const WriteOptions& options,
                           const std::vector<std::string>& inputs) {
  writeOut(path, options, inputs, false);
}

void ScenarioRunner::writeAndRelease(const std::string& path, const WriteOptions& options,
                                     const std::vector<std::string>& inputs) {
  writeOut(path, options, inputs, true);
}

void ScenarioRunner::writeOut(const std::string& path, const WriteOptions& options,
                              const std::vector<std::string>& inputs, bool release_shape) {
  requireShape("write");
  std::vector<std::string> all = inputs;
  if (!session_.shape().path.empty()) all.push_back(session_.shape().path);
  refuseInputs(path, all);
  const FileFormat format = formatFromPath(path);
  Stopwatch t;
  // Released: the deformed positions go into the runner's own shape, held once.
  Shape out = release_shape ? release(false) : session_.shape();
  if (ready()) noteWriteWarnings(deformer().writeDeformed(out));
  writeShape(path, out, options);
  write_ms_ = t.ms();
  if (const std::string lost = extrasLost(out, format); !lost.empty())
    noteWriteWarnings({path + ": " + lost});
}

Shape ScenarioRunner::release(bool deformed) {
  requireShape("release");
  if (deformed && ready()) noteWriteWarnings(deformer().writeDeformed(session_.mutableShape()));
  released_ = true;
  return session_.releaseShape();
}

void ScenarioRunner::requireShape(const char* what) const {
  if (released_)
    throw std::logic_error(std::string("ScenarioRunner::") + what + ": the shape was handed over (release)");
}

DeformReport deformShape(Shape& shape, const Scenario& scenario, const DeformOptions& options) {
  RunOptions ro;
  ro.deform = options;
  ScenarioRunner run(std::move(shape), ro);
  try {
    run.setScenario(scenario);
    run.applyMoves();
  } catch (...) {
    shape = run.release(false);  // the caller's shape, unchanged
    throw;
  }
  try {
    shape = run.release(true);
  } catch (...) {
    shape = run.release(false);  // the caller's shape, unchanged
    throw;
  }
  return run.report();  // with what writing the shape said
}

void describeRun(const Deformer& d, const std::vector<Move>& moves, const std::vector<MoveResult>& results,
                 int isovalues, DeformReport& rep) {
  const BuildTimings& b = d.buildTimings();
  rep.build = b;
  rep.field_ms = b.field_ms;
  rep.sampling_ms = b.sampling_ms;
  rep.clusters_ms = b.clusters_ms;
  rep.sample = d.clustering().sample.size();
  rep.clusters = d.clustering().clusters.size();
  rep.isovalues = isovalues;
  rep.unreachable = d.unreachablePoints();
  rep.notes = d.clustering().notes;
  if (d.surfaceGraph().normalsReoriented())
    rep.notes.emplace_back(
        "the file's normals are not consistently oriented: the neighbour filter used re-oriented copies "
        "(the output keeps the file's signs)");
  if (!d.surfaceGraph().rejoinedPairs().empty())
    rep.notes.push_back("the normal filter would have cut pieces without a handle off the surface: " +
                        std::to_string(d.surfaceGraph().rejoinedPairs().size()) +
                        " neighbour pairs across thin gaps were kept to join them back");
  rep.pieces = d.pieces().report;
  rep.warnings = rep.pieces.warnings();
  for (std::size_t i = 0; i < results.size(); ++i) {
    const MoveResult& r = results[i];
    if (!r.warning.empty()) rep.warnings.push_back(r.warning);
    rep.frames += r.frames;
    rep.iterations += r.iterations;
    rep.max_frame_iterations = std::max(rep.max_frame_iterations, r.max_frame_iterations);
    rep.solve_ms += r.solve_ms;
    rep.interpolation_ms += r.interpolation_ms;
    if (moves[i].kind == Move::Kind::Drag) {
      rep.handle_error = r.handle_error;
      rep.reached = rep.reached && r.reached;
    }
  }
  rep.energy = d.energies();
  rep.solve_per_iteration_ms = rep.iterations > 0 ? rep.solve_ms / rep.iterations : 0;
}

}  // namespace hgd
