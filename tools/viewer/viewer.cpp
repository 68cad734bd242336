// The viewer's state: the shape and its selection, the handles marked from it, the moves made
// through the runner (as `hgdeform deform` replays them, with undo and redo), and what is saved.
#include "viewer.h"

#include <omp.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iterator>
#include <sstream>
#include <thread>

#include "hgdeform/deformer/deformer.h"
#include "hgdeform/io/geometry.h"
#include "hgdeform/io/io.h"

namespace hgdview {

Viewer::Viewer(const std::string& input, int width, int height, const hgd::RunOptions& options)
    : input_(input), width_(width), height_(height), run_(hgd::ScenarioRunner::read(input, options)) {
  diagonal_ = hgd::boundingBoxDiagonal(run_.geometry());
  for (const std::string& w : run_.shape().warnings)
    std::fprintf(stderr, "hgdeform-view: warning: %s\n", w.c_str());
  radius_ = 0.03 * diagonal_;
  display_.reset(new pcl::PointCloud<pcl::PointXYZRGB>);
  display_->resize(run_.geometry().size());
  rest_.reset(new pcl::PointCloud<pcl::PointXYZRGB>);
  rest_->resize(run_.geometry().size());
  for (std::size_t i = 0; i < run_.geometry().size(); ++i) {
    (*rest_)[i].getVector3fMap() = run_.geometry().world(i).cast<float>();
    (*rest_)[i].r = (*rest_)[i].g = (*rest_)[i].b = 170;
  }
  role_.assign(run_.geometry().size(), 0);
  selected_.assign(run_.geometry().size(), 0);
  fileColours();
}

void Viewer::loadScenario(const std::string& path) {
  const hgd::Scenario scenario = hgd::readScenario(path);
  cleared_.reset();
  run_.setScenario(scenario);
  fixed_regions_ = scenario.fixed;
  manipulated_region_ = scenario.manipulated;
  joint_regions_ = scenario.joints;
  handles_ = run_.handles();
  refreshRoles();
  run_.applyMoves();
  updateAlerts();
}

void Viewer::printStats() const {
  auto median = [](std::vector<double> v) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  if (stats_.solve.empty()) {  // (a rate of nothing over no time is no figure: it printed 1e12 frames/s)
    std::printf("frames 0: no drag or frame key was timed\n");
    return;
  }
  const double s = median(stats_.solve), i = median(stats_.interpolate), r = median(stats_.render);
  std::printf(
      "frames %zu: solve %.2f ms, interpolate %.2f ms, render %.2f ms (medians); %.1f frames/s, %.0f "
      "updates/s without rendering; %zu of %zu points drawn while dragging\n",
      stats_.solve.size(), s, i, r, 1000.0 / std::max(1e-9, s + i + r), 1000.0 / std::max(1e-9, s + i),
      stats_.drawn, run_.geometry().size());
}

void Viewer::markSelection(int role) {
  std::vector<int> idx;
  for (std::size_t i = 0; i < selected_.size(); ++i)
    if (selected_[i]) idx.push_back(static_cast<int>(i));
  if (idx.empty()) return message("nothing selected (x: area, shift+click: point)");
  cleared_.reset();  // new handles: what C or n threw away is no longer one undo away
  std::vector<long long> raw;
  for (int i : idx) raw.push_back(run_.geometry().raw_index[static_cast<std::size_t>(i)]);
  hgd::Region region = hgd::Region::fromIndices(raw);
  hgd::Handles h = handles_;
  auto remove = [&](std::vector<int>& from) {
    std::vector<int> keep;
    std::set_difference(from.begin(), from.end(), idx.begin(), idx.end(), std::back_inserter(keep));
    from = keep;
  };
  // A point has one role: marking takes the points away from other handles.
  for (auto& f : h.fixed) remove(f);
  remove(h.manipulated);
  for (auto& jt : h.joints) remove(jt);
  if (role == 1) {
    h.fixed.push_back(idx);
    fixed_regions_.push_back(region);
  } else if (role == 2) {
    h.manipulated = idx;
    manipulated_region_ = region;
  } else {
    h.joints.push_back(idx);
    joint_regions_.push_back(region);
  }
  // Regions keep in step with the handles they describe.
  h.fixed.erase(std::remove_if(h.fixed.begin(), h.fixed.end(), [](const auto& v) { return v.empty(); }),
                h.fixed.end());
  h.joints.erase(std::remove_if(h.joints.begin(), h.joints.end(), [](const auto& v) { return v.empty(); }),
                 h.joints.end());
  handles_ = h;
  markUnsaved(/*shape_moved=*/false);
  syncRegions();
  clearSelection(false);
  refreshRoles();
  buildDeformer();
}

// New handles: the deformer is built for them (the field, the clusters). In the interactive
// window that happens off the GUI thread: the view still turns, the status line counts the
// seconds, and keys that need the deformer wait (see key()); pollBuild() finishes it.
void Viewer::buildDeformer() {
  const bool complete = !handles_.fixed.empty() && !handles_.manipulated.empty();
  if (!async_builds_ || !complete || !vis_) {
    run_.setHandles(handles_);
    finishHandles();
    return;
  }
  building_ = true;
  build_done_ = false;
  build_error_.clear();
  build_start_ = Clock::now();
  build_thread_ = std::thread([this, h = handles_] {
    // One core less than there are for the build: the GUI thread keeps one to draw and answer
    // the mouse (on a single core the two share it). At the process's own priority: at nice 10,
    // beside four busy processes, a 1M-point build took 60 s instead of 9 s.
    omp_set_num_threads(std::max(1, omp_get_num_procs() - 1));
    try {
      run_.setHandles(h);
    } catch (const std::exception& e) {
      build_error_ = e.what();
    }
    build_done_ = true;
  });
  last_progress_ = Clock::now();
  message_ = "building the deformer for " + std::to_string(run_.geometry().size()) +
             " points... (the view turns meanwhile)";
  if (verbose_) std::fprintf(stderr, "hgdeform-view: %s\n", message_.c_str());
  fillDisplay();
  showLod(true);  // a large cloud turns at its level of detail while the cores build
  refresh();
}

void Viewer::pollBuild() {
  if (!building_) return;
  if (!build_done_) {
    if (msSince(last_progress_) > 1000) {  // on the status line only (not stderr), once a second
      last_progress_ = Clock::now();
      message_ = "building the deformer for " + std::to_string(run_.geometry().size()) + " points... " +
                 num(msSince(build_start_) / 1000.0) + " s (the view turns meanwhile)";
      render();
    }
    return;
  }
  build_thread_.join();
  building_ = false;
  showLod(false);
  if (!build_error_.empty()) {
    restoring_.reset();  // an undo of C whose build failed: nothing to apply
    handles_ = hgd::Handles{};
    run_.setHandles(handles_);
    refreshRoles();
    message("cannot build the deformer: " + build_error_ +
            (waiting_keys_.empty()
                 ? std::string()
                 : "; the " + std::to_string(waiting_keys_.size()) + " keys pressed meanwhile were dropped"));
    waiting_keys_.clear();
    refresh();
    return;
  }
  if (verbose_)
    std::fprintf(stderr, "hgdeform-view: deformer built in %.2f s\n", msSince(build_start_) / 1000.0);
  finishHandles();
  // The keys pressed while it was built, in order (one that starts another build makes the
  // rest wait again).
  const std::vector<std::pair<std::string, char>> keys = std::move(waiting_keys_);
  waiting_keys_.clear();
  for (const auto& [sym, code] : keys) key(sym, code);
}

void Viewer::waitForBuild() {
  if (build_thread_.joinable()) build_thread_.join();
  building_ = false;
}

Viewer::~Viewer() {
  waitForBuild();
}

void Viewer::finishHandles() {
  if (restoring_) return applyRestored();  // an undo of C: its moves again
  updateAlerts();
  if (run_.ready()) {
    message("handles: " + std::to_string(handles_.fixed.size()) + " fixed, manipulated " +
            std::to_string(handles_.manipulated.size()) + " points, " +
            std::to_string(handles_.joints.size()) + " joints; " +
            std::to_string(run_.deformer().clustering().clusters.size()) + " clusters");
  } else {
    message(std::string("marked; still needed: ") + (handles_.fixed.empty() ? "a fixed handle " : "") +
            (handles_.manipulated.empty() ? "the manipulated handle" : ""));
  }
  refresh();
}

// The regions written to a saved scenario: the points each handle holds now, as indices.
void Viewer::syncRegions() {
  auto asRegion = [&](const std::vector<int>& idx) {
    std::vector<long long> raw;
    for (int i : idx) raw.push_back(run_.geometry().raw_index[static_cast<std::size_t>(i)]);
    return hgd::Region::fromIndices(raw);
  };
  fixed_regions_.clear();
  for (const auto& f : handles_.fixed) fixed_regions_.push_back(asRegion(f));
  if (!handles_.manipulated.empty()) manipulated_region_ = asRegion(handles_.manipulated);
  joint_regions_.clear();
  for (const auto& jt : handles_.joints) joint_regions_.push_back(asRegion(jt));
  run_.setRegions(fixed_regions_, manipulated_region_, joint_regions_);
}

void Viewer::clearSelection(bool redraw) {
  std::fill(selected_.begin(), selected_.end(), 0);
  if (redraw) refresh();
}

void Viewer::clearHandles() {
  const bool any = !handles_.fixed.empty() || !handles_.manipulated.empty() || !handles_.joints.empty();
  if (!any) return message("no handles to clear");
  keepForUndo("handles and moves");
  handles_ = hgd::Handles{};
  markUnsaved(/*shape_moved=*/!run_.moves().empty());
  fixed_regions_.clear();
  joint_regions_.clear();
  run_.setHandles(handles_);
  run_.setRegions(fixed_regions_, manipulated_region_, joint_regions_);
  updateAlerts();
  refreshRoles();
  message(std::string("handles cleared (z brings them back)") +
          (caps_lock_ ? "; Caps Lock is on: c clears the selection" : ""));
  refresh();
}

// C and n throw away handles or moves the runner's undo does not hold: kept here for one undo.
void Viewer::keepForUndo(const std::string& what) {
  cleared_ = Cleared{handles_, fixed_regions_, manipulated_region_, joint_regions_, run_.moves(), what};
}

// Undo after C or n: the handles as they were, the deformer built for them as any handles are
// (off the window's thread in the window), then every move applied again in order, each solved
// as it was the first time: the same shape, point for point.
void Viewer::restoreCleared() {
  Cleared c = std::move(*cleared_);
  cleared_.reset();
  const bool same = ready() && c.handles.fixed == handles_.fixed &&
                    c.handles.manipulated == handles_.manipulated && c.handles.joints == handles_.joints;
  handles_ = c.handles;
  fixed_regions_ = c.fixed;
  manipulated_region_ = c.manipulated;
  joint_regions_ = c.joints;
  run_.setRegions(fixed_regions_, manipulated_region_, joint_regions_);
  refreshRoles();
  restoring_ = std::move(c);
  if (same)
    applyRestored();
  else
    buildDeformer();  // finishHandles applies them
}

void Viewer::applyRestored() {
  if (!restoring_) return;
  const Cleared c = std::move(*restoring_);
  restoring_.reset();
  if (run_.ready())
    for (const hgd::Move& m : c.moves) run_.apply(m);
  shapeChanged(c.what + " back (undone)");
}

// What the deformation cannot do for this shape, on the status line and stderr: pieces that
// no handle reaches (followed or left), a piece moved rigidly, a surface pulled apart.
// `live`: a drag's live frame, which is the move it will commit (the stretch is measured on it).
void Viewer::updateAlerts(bool live) {
  alert_.clear();
  if (!ready()) return;
  const hgd::PieceReport& p = run_.deformer().pieces().report;
  std::vector<std::string> full = p.warnings();
  std::ostringstream s;
  if (p.followed_points) s << " | " << p.followed_points << " points without a handle follow";
  if (p.stayed_points) s << " | " << p.stayed_points << " points without a handle stay";
  if (p.rigid_points) s << " | " << p.rigid_points << " points move rigidly with the handle";
  if (!run_.moves().empty() || live) {
    const hgd::SurfaceStretch st = run_.deformer().surfaceStretch();
    if (st.split_points) s << " | SURFACE PULLED APART at " << st.split_points << " points";
    if (const std::string w = hgd::stretchWarning(st); !w.empty()) full.push_back(w);
  }
  alert_ = s.str();
  for (const auto& w : full)
    if (std::find(reported_.begin(), reported_.end(), w) == reported_.end()) {
      std::fprintf(stderr, "hgdeform-view: warning: %s\n", w.c_str());
      reported_.push_back(w);
    }
}

// Applies a move through the runner (as `hgdeform deform` does), recorded for undo and the
// saved scenario.
void Viewer::commit(const hgd::Move& m) {
  if (!ready()) return;
  run_.apply(m);
  markUnsaved();
  updateAlerts();
}

void Viewer::frameMove(const Eigen::Vector3d& translate, const Eigen::Vector3d& axis, double degrees) {
  if (!ready()) return message("mark a fixed and a manipulated handle first");
  hgd::Move m;
  m.kind = hgd::Move::Kind::Frame;
  m.frame.translate = translate;
  if (degrees != 0) {
    m.frame.axis = axis;
    m.frame.degrees = degrees;
    m.frame.centre = handleCentre();  // explicit, so that the scenario replays it exactly
  }
  const auto t0 = Clock::now();
  commit(m);
  stats_.solve.push_back(msSince(t0));
  // Said on the status line of the frame drawn next (refresh, below).
  message(degrees != 0 ? "turned the handle " + num(degrees) + " degrees"
                       : "moved the handle by (" + num(translate.x()) + ", " + num(translate.y()) + ", " +
                             num(translate.z()) + ")",
          /*draw=*/false);
  stats_.interpolate.push_back(run_.deformer().lastInterpolationMs());
  timing_frame_ = true;  // the frame's render counts (--stats)
  refresh();
  timing_frame_ = false;
}

void Viewer::undo() {
  if (ready() && run_.undo()) return shapeChanged("undone");
  if (cleared_) return restoreCleared();
  message("nothing to undo");
}

void Viewer::redo() {
  if (!ready() || !run_.redo()) return message("nothing to redo");
  shapeChanged("redone");
}

void Viewer::resetShape() {
  if (!ready() || run_.moves().empty()) return message("the shape is at rest already");
  keepForUndo("moves");
  run_.reset();
  shapeChanged("rest shape (z brings the moves back)");
}

// After undo, redo or a reset: the shape moved without a gesture.
void Viewer::shapeChanged(const std::string& what) {
  markUnsaved();
  updateAlerts();
  message(what);
  refresh();
}

void Viewer::saveShape(const std::string& path) {
  run_.write(path, {}, inputs_);
  unsaved_ = shape_unsaved_ = false;
  message("saved " + path);
}

void Viewer::saveScenario(const std::string& path) {
  hgd::refuseInputs(path, inputs_);
  if (handles_.fixed.empty() || handles_.manipulated.empty())
    return message("a scenario needs a fixed and a manipulated handle");
  hgd::writeFileAtomically(path, hgd::scenarioToJson(run_.scenario()));
  unsaved_ = shape_unsaved_ = false;  // the session replays from it
  message("saved " + path);
}

Eigen::Vector3d Viewer::deformed(std::size_t i) const {
  return ready() ? run_.deformer().deformedWorld(i) : run_.geometry().world(i);
}

Eigen::Vector3d Viewer::centre() const {
  const Eigen::AlignedBox3f box = hgd::boundingBox(*run_.geometry().points);
  return run_.geometry().origin + 0.5 * (box.min() + box.max()).cast<double>();
}

Eigen::Vector3d Viewer::handleCentre() const {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (int i : handles_.manipulated) c += deformed(static_cast<std::size_t>(i));
  return c / std::max<double>(1.0, static_cast<double>(handles_.manipulated.size()));
}

std::string Viewer::defaultPath(const std::string& suffix, const std::string& ext) const {
  const std::filesystem::path p(input_);
  return (p.parent_path() / (p.stem().string() + suffix + ext)).string();
}

// Saving never replaces an earlier result: INPUT-deformed.ply, then INPUT-deformed-2.ply, ...
std::string Viewer::freshPath(const std::string& suffix, const std::string& ext) const {
  std::string path = defaultPath(suffix, ext);
  for (int n = 2; std::filesystem::exists(std::filesystem::symlink_status(path)); ++n)
    path = defaultPath(suffix + "-" + std::to_string(n), ext);
  return path;
}

std::string Viewer::extensionOf(const std::string& path) {
  const std::string e = std::filesystem::path(path).extension().string();
  return e.empty() ? ".ply" : e;
}

std::string Viewer::num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}

}  // namespace hgdview
