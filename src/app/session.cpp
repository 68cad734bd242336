#include "hgdeform/app/session.h"

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <utility>

#include "hgdeform/app/regions.h"
#include "util/phases.h"

namespace hgd {

Eigen::Affine3d frameMotion(const FrameMove& move, const Eigen::Vector3d& handle_centre) {
  const Eigen::Vector3d centre = move.centre ? *move.centre : handle_centre;
  Eigen::Affine3d motion = Eigen::Affine3d::Identity();
  motion.translate(centre + move.translate);
  motion.rotate(Eigen::AngleAxisd(move.degrees * M_PI / 180.0, move.axis.normalized()));
  motion.translate(-centre);
  return motion;
}

Session::Session() = default;
Session::Session(Session&&) noexcept = default;
Session& Session::operator=(Session&&) noexcept = default;
Session::~Session() = default;

Session::Session(Shape shape, const RunOptions& options) : options_(options) {
  setShape(std::move(shape));
}

void Session::setShape(Shape shape) {
  std::vector<BuildPhase> phases;
  std::shared_ptr<const Geometry> geometry;
  {
    PhaseRecording recording(&phases);
    geometry = std::make_shared<const Geometry>(extractGeometry(shape));  // may throw: nothing changed
  }
  deformer_.reset();
  built_ = false;
  built_options_.reset();
  resolved_ = false;
  if (direct_) {  // indices into the old geometry: the regions saved for them stand in
    handles_ = {};
    direct_ = false;
  }
  phases_ = std::move(phases);
  shape_ = std::move(shape);
  geometry_ = std::move(geometry);
  warnings_ = shape_.warnings;  // what reading noted (a format told by content, ...)
  warnings_.insert(warnings_.end(), geometry_->warnings.begin(), geometry_->warnings.end());
}

void Session::setOptions(const RunOptions& options) {
  options_ = options;
  deformer_.reset();
  built_ = false;
  built_options_.reset();
}

void Session::setScenario(const Scenario& scenario, bool resolve_now) {
  Handles resolved;
  if (resolve_now) {  // before anything changes: a region that does not fit leaves all as it was
    requireShape("setScenario");
    PhaseRecording recording(&phases_);
    PhaseClock clock;
    resolved = resolveHandles(scenario, *geometry_, shape_);
    clock.lap("runner.handles");
  }
  scenario_ = scenario;
  from_scenario_ = true;
  direct_ = false;
  built_ = false;
  resolved_ = resolve_now;
  if (resolve_now) handles_ = std::move(resolved);
}

Scenario& Session::indexHandles() {
  if (from_scenario_) scenario_ = Scenario{};
  from_scenario_ = false;
  direct_ = false;
  built_ = false;
  resolved_ = false;
  return scenario_;
}

void Session::setFixedIndices(const std::vector<std::vector<long long>>& handles) {
  Scenario& s = indexHandles();
  s.fixed.clear();
  for (const auto& h : handles) s.fix(Region::fromIndices(h));
}

void Session::setManipulatedIndices(std::vector<long long> handle) {
  indexHandles().manipulate(Region::fromIndices(std::move(handle)));
}

void Session::setJointIndices(const std::vector<std::vector<long long>>& joints) {
  Scenario& s = indexHandles();
  s.joints.clear();
  for (const auto& j : joints) s.joint(Region::fromIndices(j));
}

void Session::setHandles(const Handles& handles) {
  handles_ = handles;
  direct_ = true;
  built_ = false;
  resolved_ = false;
  if (handles_.fixed.empty() || handles_.manipulated.empty()) deformer_.reset();  // until both are there
}

void Session::setRegions(std::vector<Region> fixed, Region manipulated, std::vector<Region> joints) {
  scenario_.fixed = std::move(fixed);
  scenario_.manipulated = std::move(manipulated);
  scenario_.joints = std::move(joints);
}

void Session::setBlend(Blend blend) {
  options_.blend = blend;
  if (deformer_) deformer_->setBlend(blend);
  if (built_options_) built_options_->blend = blend;
}

std::string Session::missingHandle() const {
  if (direct_) {
    if (handles_.fixed.empty()) return "fixed";
    if (handles_.manipulated.empty()) return "manipulated";
    return {};
  }
  if (scenario_.fixed.empty()) return "fixed";
  // A scenario always names its manipulated region; handles by index need the list.
  if (!from_scenario_ && scenario_.manipulated.kind == Region::Kind::Indices &&
      scenario_.manipulated.indices.empty())
    return "manipulated";
  return {};
}

DeformOptions mergedOptions(const RunOptions& options, const Scenario& scenario) {
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
  return opt;
}

DeformOptions Session::mergedOptions(const Scenario& scenario) const {
  DeformOptions opt = hgd::mergedOptions(options_, scenario);
  if (shape_.isOrganized() && geometry_) {
    opt.field.orient_to_viewpoint = true;
    opt.field.viewpoint = (shape_.sensor_origin.head<3>().cast<double>() - geometry_->origin).cast<float>();
  }
  return opt;
}

DeformOptions Session::mergedOptions() const {
  return mergedOptions(scenario_);
}

bool Session::ensureBuilt() {
  requireShape("ensureBuilt");
  if (built_ && deformer_) return false;
  if (direct_) {
    if (handles_.fixed.empty() || handles_.manipulated.empty()) return false;  // marking goes on
  } else if (!resolved_) {
    if (const std::string missing = missingHandle(); !missing.empty())
      throw ScenarioError("no " + missing + " handle");
    PhaseRecording recording(&phases_);
    PhaseClock clock;
    handles_ = resolveHandles(scenario_, *geometry_, shape_);
    clock.lap("runner.handles");
  }
  const DeformOptions opt = mergedOptions();
  // What mergedOptions() takes from a scenario is built into a Deformer (the isovalue count,
  // the resolution) but the blend, which it applies at once.
  if (!deformer_ || !built_options_ || opt.clusters.isovalues != built_options_->clusters.isovalues ||
      opt.multires_above != built_options_->multires_above) {
    deformer_.reset();  // its memory back before the new one is built
    deformer_ = std::make_shared<Deformer>(geometry_, handles_, opt);
  } else {
    const Handles& old = deformer_->handles();
    if (handles_.fixed == old.fixed && handles_.manipulated == old.manipulated &&
        handles_.joints == old.joints)
      deformer_->reset();  // the same handles (another blend, or the scenario again): at rest
    else
      deformer_->setHandles(handles_);  // normals, kNN and the graph are kept
    deformer_->setBlend(opt.blend);
  }
  built_options_ = opt;
  built_ = true;
  return true;
}

MoveResult Session::applyMove(const Move& move, int number) {
  return hgd::applyMove(deformer(), move, number);
}

MoveResult applyMove(Deformer& d, const Move& move, int number) {
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
    return r;
  }
  // One rigid motion of the handle, given exactly: a frame move, or a drag that keeps the
  // handle's orientation (a translation that lands the picked point on the target).
  const bool translate = move.kind == Move::Kind::Drag;
  const SolveStats st = translate ? d.translateHandle(move.drag.from, move.drag.to)  // lands exactly
                                  : d.moveHandle(frameMotion(move.frame, d.handleCentre()));
  if (!st.decreased)
    r.warning = "move " + std::to_string(number) + (translate ? " (drag, keeping orientation)" : " (frame)") +
                ": Gauss-Newton could not decrease the energy; the shape may not follow the handle exactly";
  r.frames = 1;
  r.iterations = st.iterations;
  r.max_frame_iterations = st.iterations;
  r.solve_ms = st.ms;
  r.interpolation_ms = d.lastInterpolationMs();
  return r;
}

Deformer& Session::deformer() {
  if (!deformer_) throw std::logic_error("hgd::Session: no deformer yet (no handles, or not built)");
  return *deformer_;
}

const Deformer& Session::deformer() const {
  if (!deformer_) throw std::logic_error("hgd::Session: no deformer yet (no handles, or not built)");
  return *deformer_;
}

std::shared_ptr<const Deformer> Session::sharedDeformer() const {
  return deformer_;
}

const Geometry& Session::geometry() const {
  requireShape("geometry");
  return *geometry_;
}

Shape Session::releaseShape() {
  Shape out = std::move(shape_);
  shape_ = Shape{};
  return out;
}

void Session::requireShape(const char* what) const {
  if (!geometry_) throw std::logic_error(std::string("hgd::Session::") + what + ": no shape (setShape)");
}

}  // namespace hgd
