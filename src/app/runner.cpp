#include "hgdeform/app/runner.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <utility>

#include "hgdeform/app/regions.h"
#include "util/phases.h"
#include "util/timer.h"

namespace hgd {

DeformOptions mergedOptions(const RunOptions& options, const Scenario& scenario, const Shape& shape,
                            const Geometry& geometry) {
  DeformOptions opt = options.deform;
  if (options.clusters)
    opt.clusters.isovalues = *options.clusters;
  else if (scenario.clusters)
    opt.clusters.isovalues = *scenario.clusters;
  if (options.blend)
    opt.blend = *options.blend;
  else if (scenario.blend)
    opt.blend = *scenario.blend;
  if (scenario.full_resolution && *scenario.full_resolution) opt.multires_above = 0;
  if (shape.isOrganized()) {
    opt.field.orient_to_viewpoint = true;
    opt.field.viewpoint = (shape.sensor_origin.head<3>().cast<double>() - geometry.origin).cast<float>();
  }
  return opt;
}

ScenarioRunner ScenarioRunner::read(const std::string& path, const RunOptions& options) {
  Stopwatch t;
  Shape shape = readShape(path);
  const double read_ms = t.ms();
  ScenarioRunner run(std::move(shape), options);
  run.read_ms_ = read_ms;
  return run;
}

ScenarioRunner::ScenarioRunner(Shape shape, const RunOptions& options)
    : shape_(std::move(shape)), options_(options) {
  Stopwatch t;
  PhaseRecording recording(&phases_);
  read_warnings_ = shape_.warnings;  // what reading noted (a format told by content, ...)
  geometry_ = std::make_shared<const Geometry>(extractGeometry(shape_));
  read_warnings_.insert(read_warnings_.end(), geometry_->warnings.begin(), geometry_->warnings.end());
  build_ms_ = t.ms();
}

ScenarioRunner::ScenarioRunner(ScenarioRunner&&) noexcept = default;
ScenarioRunner& ScenarioRunner::operator=(ScenarioRunner&&) noexcept = default;
ScenarioRunner::~ScenarioRunner() = default;

void ScenarioRunner::setScenario(const Scenario& scenario) {
  requireShape("setScenario");
  Stopwatch t;
  scenario_ = scenario;
  PhaseClock clock;
  {
    PhaseRecording recording(&phases_);
    handles_ = resolveHandles(scenario_, *geometry_, shape_);
    clock.lap("runner.handles");
  }
  dropLive();  // a live frame's level of detail goes with it
  clearHistory();
  build(mergedOptions(options_, scenario_, shape_, *geometry_));
  build_ms_ += t.ms();
}

FieldResult ScenarioRunner::field(const Scenario& scenario) const {
  requireShape("field");
  FieldResult r;
  r.handles = resolveHandles(scenario, *geometry_, shape_);
  const Handles& handles = r.handles;
  HarmonicField field;  // at full resolution, as Deformer's on a shape below multires_above
  setGraphInput(field.surfaceGraph(), *geometry_);
  field.setOptions(mergedOptions(options_, scenario, shape_, *geometry_).field);
  field.setHandles(handles.fixed, handles.manipulated);
  field.compute(r.values);
  r.timings = field.timings();
  r.unreachable = field.unreachable().size();
  return r;
}

void ScenarioRunner::setHandles(const Handles& handles) {
  requireShape("setHandles");
  handles_ = handles;
  dropLive();  // a live frame's level of detail goes with it
  clearHistory();
  if (handles_.fixed.empty() || handles_.manipulated.empty()) {
    deformer_.reset();
    return;
  }
  build(mergedOptions(options_, scenario_, shape_, *geometry_));
}

void ScenarioRunner::setRegions(std::vector<Region> fixed, Region manipulated, std::vector<Region> joints) {
  scenario_.fixed = std::move(fixed);
  scenario_.manipulated = std::move(manipulated);
  scenario_.joints = std::move(joints);
}

void ScenarioRunner::build(const DeformOptions& options) {
  if (deformer_)
    deformer_->setHandles(handles_);  // normals and kNN are kept
  else
    deformer_ = std::make_unique<Deformer>(geometry_, handles_, options);
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
  for (const Move& m : scenario_.moves) apply(m);
}

MoveResult ScenarioRunner::apply(const Move& move) {
  requireShape("apply");
  if (!deformer_) throw std::logic_error("ScenarioRunner::apply: no handles yet");
  dropLive();
  history_.push_back(deformer_->state());
  const MoveResult r = solveMove(move);
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
  if (!deformer_) throw std::logic_error("ScenarioRunner::previewMove: no handles yet");
  if (!beginLive(preview)) deformer_->restore(history_.back());  // each preview starts where apply() would
  live_move_ = move;
  live_result_ = solveMove(move);
  return *live_result_;
}

std::optional<MoveResult> ScenarioRunner::commitLive() {
  if (!live_ || !live_move_ || !live_result_) return std::nullopt;
  live_ = false;  // the state before the gesture stays in history_, as apply() leaves it
  if (!deformer_->preview().empty()) deformer_->setPreview({});  // every point, same transforms
  const Move move = *live_move_;
  const MoveResult r = *live_result_;
  live_move_.reset();
  live_result_.reset();
  record(move, r);
  return r;
}

MoveResult ScenarioRunner::solveMove(const Move& move) {
  Deformer& d = *deformer_;
  const int number = static_cast<int>(moves_.size()) + 1;
  MoveResult r;
  if (move.kind == Move::Kind::Drag && !move.drag.keep_orientation) {
    const DragResult dr = d.dragTo(move.drag.from, move.drag.to);
    r = MoveResult{dr.frames, dr.iterations, dr.max_frame_iterations, dr.reached,
                   dr.error,  dr.solve_ms,   dr.interpolation_ms,     {}};
    if (!dr.reached) {
      char buf[320];
      std::snprintf(buf, sizeof buf,
                    "move %d (drag): the picked point stopped %.6g (%.3g of the diagonal) from its "
                    "target after %d frames%s",
                    number, dr.error, dr.error / d.diagonal(), dr.frames,
                    dr.last.decreased ? "" : "; Gauss-Newton could not decrease the energy further");
      r.warning = buf;
    }
  } else {
    // One rigid motion of the handle, given exactly: a frame move, or a drag that keeps the
    // handle's orientation (a translation that lands the picked point on the target).
    const bool translate = move.kind == Move::Kind::Drag;
    SolveStats st;
    if (translate) {
      st = d.translateHandle(move.drag.from, move.drag.to);  // reached: the point lands exactly
    } else {
      const FrameMove& f = move.frame;
      const Eigen::Vector3d centre = f.centre ? *f.centre : d.handleCentre();
      Eigen::Affine3d motion = Eigen::Affine3d::Identity();
      motion.translate(centre + f.translate);
      motion.rotate(Eigen::AngleAxisd(f.degrees * M_PI / 180.0, f.axis.normalized()));
      motion.translate(-centre);
      st = d.moveHandle(motion);
    }
    if (!st.decreased)
      r.warning = "move " + std::to_string(number) +
                  (translate ? " (drag, keeping orientation)" : " (frame)") +
                  ": Gauss-Newton could not decrease the energy; the shape may not follow the handle exactly";
    r.frames = 1;
    r.iterations = st.iterations;
    r.max_frame_iterations = st.iterations;
    r.solve_ms = st.ms;
    r.interpolation_ms = d.lastInterpolationMs();
  }
  return r;
}

SolveStats ScenarioRunner::liveDrag(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                                    bool keep_orientation, const std::vector<int>* preview) {
  requireShape("liveDrag");
  if (!deformer_) throw std::logic_error("ScenarioRunner::liveDrag: no handles yet");
  beginLive(preview);
  live_move_.reset();  // incremental frames: no move to commit as shown
  live_result_.reset();
  return keep_orientation ? deformer_->translateHandle(from, to) : deformer_->drag(from, to);
}

bool ScenarioRunner::beginLive(const std::vector<int>* preview) {
  if (live_) return false;
  history_.push_back(deformer_->state());  // the last applied state, taken back by dropLive()
  live_ = true;
  if (preview) deformer_->setPreview(*preview);
  return true;
}

void ScenarioRunner::dropLive() {
  if (!live_) return;
  live_ = false;
  live_move_.reset();
  live_result_.reset();
  deformer_->restore(history_.back());  // with a preview, its points only
  history_.pop_back();
  if (!deformer_->preview().empty()) deformer_->setPreview({});  // then every point
}

bool ScenarioRunner::undo() {
  dropLive();
  if (history_.empty()) return false;
  redo_states_.push_back(deformer_->state());
  undone_.emplace_back(moves_.back(), results_.back());
  moves_.pop_back();
  results_.pop_back();
  deformer_->restore(history_.back());
  history_.pop_back();
  return true;
}

bool ScenarioRunner::redo() {
  dropLive();
  if (undone_.empty()) return false;
  history_.push_back(deformer_->state());
  moves_.push_back(undone_.back().first);
  results_.push_back(undone_.back().second);
  undone_.pop_back();
  deformer_->restore(redo_states_.back());
  redo_states_.pop_back();
  return true;
}

void ScenarioRunner::reset() {
  dropLive();  // a live frame's level of detail goes with it (else only its points would reset)
  if (deformer_) deformer_->reset();
  clearHistory();
}

void ScenarioRunner::setBlend(Blend blend) {
  options_.blend = blend;
  if (deformer_) deformer_->setBlend(blend);
}

Scenario ScenarioRunner::scenario() const {
  Scenario s = scenario_;
  s.moves = moves_;
  if (options_.clusters) s.clusters = options_.clusters;
  if (options_.blend) s.blend = options_.blend;
  return s;
}

DeformReport ScenarioRunner::report() const {
  DeformReport rep;
  rep.read_ms = read_ms_;
  rep.build_ms = read_ms_ + build_ms_;  // everything before the first solve
  rep.points = geometry_->size();
  rep.write_ms = write_ms_;
  if (deformer_) {
    const Deformer& d = *deformer_;
    const BuildTimings& b = d.buildTimings();
    rep.build = b;
    // The runner's own phases (the geometry, the handles) before the Deformer's.
    rep.build.phases.insert(rep.build.phases.begin(), phases_.begin(), phases_.end());
    rep.field_ms = b.field_ms;
    rep.sampling_ms = b.sampling_ms;
    rep.clusters_ms = b.clusters_ms;
    rep.sample = d.clustering().sample.size();
    rep.clusters = d.clustering().clusters.size();
    rep.isovalues = mergedOptions(options_, scenario_, shape_, *geometry_).clusters.isovalues;
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
    for (std::size_t i = 0; i < results_.size(); ++i) {
      const MoveResult& r = results_[i];
      if (!r.warning.empty()) rep.warnings.push_back(r.warning);
      rep.frames += r.frames;
      rep.iterations += r.iterations;
      rep.max_frame_iterations = std::max(rep.max_frame_iterations, r.max_frame_iterations);
      rep.solve_ms += r.solve_ms;
      rep.interpolation_ms += r.interpolation_ms;
      if (moves_[i].kind == Move::Kind::Drag) {
        rep.handle_error = r.handle_error;
        rep.reached = rep.reached && r.reached;
      }
    }
    rep.energy = d.energies();
    rep.solve_per_iteration_ms = rep.iterations > 0 ? rep.solve_ms / rep.iterations : 0;
    rep.surface = d.surfaceStretch();
    if (const std::string w = stretchWarning(rep.surface); !w.empty()) rep.warnings.push_back(w);
  }
  rep.warnings.insert(rep.warnings.begin(), read_warnings_.begin(), read_warnings_.end());
  rep.warnings.insert(rep.warnings.end(), write_warnings_.begin(), write_warnings_.end());
  rep.total_ms = rep.build_ms + rep.solve_ms + rep.interpolation_ms + rep.write_ms;
  return rep;
}

Shape ScenarioRunner::deformedShape() const {
  requireShape("deformedShape");
  Shape out = shape_;
  if (deformer_) deformer_->writeDeformed(out);
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
  if (!shape_.path.empty()) all.push_back(shape_.path);
  refuseInputs(path, all);
  const FileFormat format = formatFromPath(path);
  Stopwatch t;
  // Released: the deformed positions go into the runner's own shape, held once.
  Shape out = release_shape ? release(false) : shape_;
  if (deformer_) noteWriteWarnings(deformer_->writeDeformed(out));
  writeShape(path, out, options);
  write_ms_ = t.ms();
  if (const std::string lost = extrasLost(out, format); !lost.empty())
    noteWriteWarnings({path + ": " + lost});
}

Shape ScenarioRunner::release(bool deformed) {
  requireShape("release");
  if (deformed && deformer_) noteWriteWarnings(deformer_->writeDeformed(shape_));
  released_ = true;
  Shape out = std::move(shape_);
  shape_ = Shape{};
  return out;
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

}  // namespace hgd
