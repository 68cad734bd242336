// hgdeform-view: the interactive front end. Pick handles, drag, see it live.
//
//   hgdeform-view INPUT [--scenario S.json] [--replay EVENTS.json] [--screenshot OUT.png]
//                 [--size WxH] [--stats]
//
// Keys (also shown by 'h'):
//   x          area selection (rubber band) on/off; shift+click selects a point and its radius
//   + / -      selection radius up / down;  c  clear the selection
//   f / m / j  the selection becomes a fixed handle / the manipulated handle / a joint
//   C          clear all handles
//   d          drag mode on/off: left-drag on the manipulated handle moves it (else the camera)
//   t          frame mode on/off: arrows move the handle in the view plane, [ ] turn it about
//              the view direction, , . about the view's vertical
//   v          view: original colours / harmonic field / clusters;  o  rest shape overlay
//   z / y      undo / redo;  n  back to the rest shape
//   s / S      save the deformed shape / the session as a scenario (beside the input)
//   k          screenshot (PNG);  h  this help;  q  quit
//
// --replay plays a script of events (picks, keys, drags in screen or world coordinates) and
// exits; with --screenshot it saves a picture at the end. The replay format, checked as a whole
// before the first event runs (tools/replay.cpp), is in docs/replay.md. Every committed drag is
// applied the way `hgdeform deform` replays a scenario's drag, so a saved session replays to
// the same shape.
#include <pcl/conversions.h>
#include <pcl/visualization/interactor_style.h>
#include <pcl/visualization/pcl_visualizer.h>
#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkFloatArray.h>
#include <vtkLODActor.h>
#include <vtkLookupTable.h>
#include <vtkMapper.h>
#include <vtkObjectFactory.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkRenderWindow.h>
#include <vtkRenderWindowInteractor.h>
#include <vtkRenderer.h>
#include <vtkRendererCollection.h>
#include <vtkScalarBarActor.h>
#include <vtkSmartPointer.h>
#include <vtkTextProperty.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "blas_guard.h"
#include "cli_common.h"
#include "hgdeform/colormap.h"
#include "hgdeform/deformer.h"
#include "hgdeform/fields.h"
#include "hgdeform/io.h"
#include "hgdeform/regions.h"
#include "hgdeform/render.h"
#include "hgdeform/runner.h"
#include "hgdeform/scenario.h"
#include "replay.h"

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

const char* kHelp =
    "x  area select on/off   shift+click  select around a point   +/-  radius   c  clear selection\n"
    "f  fixed handle   m  manipulated handle   j  joint   C  clear all handles\n"
    "d  drag mode (left-drag the manipulated handle)   t  frame mode (arrows, [ ], , .)\n"
    "v  view: colours / field / clusters   o  rest overlay   z/y  undo/redo   n  rest shape\n"
    "s  save shape   S  save scenario   k  screenshot   h  help   q  quit";

class Viewer;

// The interactor style: our keys and the handle drag first, PCL's behaviour for the rest.
class Style : public pcl::visualization::PCLVisualizerInteractorStyle {
 public:
  static Style* New();
  vtkTypeMacro(Style, pcl::visualization::PCLVisualizerInteractorStyle) Viewer* viewer = nullptr;

  void OnKeyDown() override;
  void OnChar() override;
  void OnLeftButtonDown() override;
  void OnLeftButtonUp() override;
  void OnMouseMove() override;
  // vtkInteractorStyleRubberBandPick's modes: 0 orient (camera), 1 select (rubber band).
  bool selecting() const { return CurrentMode == 1; }
  void rubberBand(int& x0, int& y0, int& x1, int& y1) const {
    x0 = StartPosition[0];
    y0 = StartPosition[1];
    x1 = EndPosition[0];
    y1 = EndPosition[1];
  }
};
vtkStandardNewMacro(Style);

struct FrameStats {
  std::vector<double> solve, interpolate, render;
};

class Viewer {
 public:
  Viewer(const std::string& input, int width, int height)
      : input_(input), width_(width), height_(height), run_(hgd::ScenarioRunner::read(input)) {
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

  void loadScenario(const std::string& path) {
    const hgd::Scenario scenario = hgd::readScenario(path);
    run_.setScenario(scenario);
    fixed_regions_ = scenario.fixed;
    manipulated_region_ = scenario.manipulated;
    joint_regions_ = scenario.joints;
    handles_ = run_.handles();
    refreshRoles();
    run_.applyMoves();
    updateAlerts();
  }

  void open() {
    style_ = vtkSmartPointer<Style>::Take(Style::New());
    style_->viewer = this;
    int argc = 0;
    vis_ = std::make_unique<pcl::visualization::PCLVisualizer>(argc, nullptr, "hgdeform-view", style_.Get(),
                                                               true);
    vis_->setSize(width_, height_);
    vis_->setBackgroundColor(1, 1, 1);
    if (run_.geometry().faces.empty()) {
      const pcl::visualization::PointCloudColorHandlerRGBField<pcl::PointXYZRGB> rgb(display_);
      vis_->addPointCloud<pcl::PointXYZRGB>(display_, rgb, "shape");
      // Big points cost fill rate under software GL: dense clouds need no more than one pixel.
      const double size = run_.geometry().size() > 200000 ? 1 : run_.geometry().size() > 50000 ? 2 : 3;
      vis_->setPointCloudRenderingProperties(pcl::visualization::PCL_VISUALIZER_POINT_SIZE, size, "shape");
    } else {
      pcl::PolygonMesh mesh;
      pcl::toPCLPointCloud2(*display_, mesh.cloud);
      mesh.polygons = run_.geometry().faces;
      vis_->addPolygonMesh(mesh, "shape");
    }
    vis_->addText("", 10, 10, 13, 0.1, 0.1, 0.1, "status");
    vis_->addText(kHelp, 10, height_ - 110, 13, 0.1, 0.1, 0.1, "help");
    help_visible_ = true;
    // The field's colour scale, shown in field view.
    auto lut = vtkSmartPointer<vtkLookupTable>::New();
    lut->SetNumberOfTableValues(256);
    for (int k = 0; k < 256; ++k) {
      const Eigen::Vector3f c = hgd::colourMap(static_cast<float>(k) / 255.0f);
      lut->SetTableValue(k, c.x(), c.y(), c.z(), 1.0);
    }
    lut->SetRange(0, 1);
    lut->Build();
    scale_bar_ = vtkSmartPointer<vtkScalarBarActor>::New();
    scale_bar_->SetLookupTable(lut);
    scale_bar_->SetTitle("harmonic");
    scale_bar_->SetNumberOfLabels(3);
    scale_bar_->GetTitleTextProperty()->SetColor(0.1, 0.1, 0.1);
    scale_bar_->GetLabelTextProperty()->SetColor(0.1, 0.1, 0.1);
    scale_bar_->SetWidth(0.08);
    scale_bar_->SetHeight(0.45);
    scale_bar_->SetPosition(0.9, 0.3);
    scale_bar_->SetVisibility(false);
    renderer()->AddActor2D(scale_bar_);
    vis_->resetCamera();
    const Eigen::Vector3d c = centre();
    vis_->setCameraPosition(c.x(), c.y(), c.z() + 2.2 * diagonal_, c.x(), c.y(), c.z(), 0, 1, 0);
    vis_->setCameraClipDistances(0.01 * diagonal_, 10 * diagonal_);
    refresh();
  }

  void spin() {
    while (!vis_->wasStopped() && !quit_) vis_->spinOnce(30);
  }

  // --- events ---------------------------------------------------------------------------

  // Our keys; returns false for keys that PCL/VTK should handle.
  bool key(const std::string& sym, char code) {
    const char k = code != 0 ? code : (sym.size() == 1 ? sym[0] : 0);
    if (frame_mode_) {
      const double step = 0.02 * diagonal_, turn = 5.0;
      Eigen::Vector3d up, right, view;
      cameraAxes(up, right, view);
      const Eigen::Vector3d none = Eigen::Vector3d::Zero();
      if (sym == "Left") return frameMove(-step * right, none, 0), true;
      if (sym == "Right") return frameMove(step * right, none, 0), true;
      if (sym == "Up") return frameMove(step * up, none, 0), true;
      if (sym == "Down") return frameMove(-step * up, none, 0), true;
      if (k == '[') return frameMove(none, view, turn), true;
      if (k == ']') return frameMove(none, view, -turn), true;
      if (k == ',') return frameMove(none, up, turn), true;
      if (k == '.') return frameMove(none, up, -turn), true;
    }
    switch (k) {
      case 'f': markSelection(1); return true;
      case 'm': markSelection(2); return true;
      case 'j': markSelection(3); return true;
      case 'c': clearSelection(); return true;
      case 'C': clearHandles(); return true;
      case 'd':
        drag_mode_ = !drag_mode_;
        if (drag_mode_) frame_mode_ = false;
        message(drag_mode_ ? "drag mode: left-drag the manipulated handle" : "drag mode off");
        return true;
      case 't':
        frame_mode_ = !frame_mode_;
        if (frame_mode_) drag_mode_ = false;
        message(frame_mode_ ? "frame mode: arrows move, [ ] and , . turn the handle" : "frame mode off");
        return true;
      case 'v':
        view_ = (view_ + 1) % 3;
        refresh();
        return true;
      case 'o':
        overlay_ = !overlay_;
        refresh();
        return true;
      case 'z': undo(); return true;
      case 'y': redo(); return true;
      case 'n': resetShape(); return true;
      case 's': saveShape(defaultPath("-deformed", extensionOf(input_))); return true;
      case 'S': saveScenario(defaultPath("-scenario", ".json")); return true;
      case 'k': screenshot(defaultPath("-screenshot", ".png")); return true;
      case 'h':
        help_visible_ = !help_visible_;
        vis_->updateText(help_visible_ ? kHelp : "", 10, height_ - 110, 13, 0.1, 0.1, 0.1, "help");
        render();
        return true;
      case '+':
      case '=':
        radius_ *= 1.25;
        message("selection radius " + num(radius_));
        return true;
      case '-':
        radius_ /= 1.25;
        message("selection radius " + num(radius_));
        return true;
      case 'q': quit_ = true; return true;
      default: return false;
    }
  }

  // A click with shift: select the points within the radius of the point under the cursor.
  void pickAt(int x, int y) {
    const int hit = nearestOnScreen(x, y, 12.0);
    if (hit < 0) return message("nothing under the cursor");
    const Eigen::Vector3d p = deformed(static_cast<std::size_t>(hit));
    std::size_t count = 0;
    for (std::size_t i = 0; i < run_.geometry().size(); ++i)
      if ((deformed(i) - p).norm() <= radius_) {
        selected_[i] = 1;
        ++count;
      }
    message("selected " + std::to_string(count) + " points around point " +
            std::to_string(run_.geometry().raw_index[static_cast<std::size_t>(hit)]));
    refresh();
  }

  // The points whose projections fall inside a screen rectangle.
  void selectArea(int x0, int y0, int x1, int y1) {
    if (x0 > x1) std::swap(x0, x1);
    if (y0 > y1) std::swap(y0, y1);
    std::size_t count = 0;
    for (std::size_t i = 0; i < run_.geometry().size(); ++i) {
      const Eigen::Vector3d d = toDisplay(deformed(i));
      if (d.x() >= x0 && d.x() <= x1 && d.y() >= y0 && d.y() <= y1) {
        selected_[i] = 1;
        ++count;
      }
    }
    message("selected " + std::to_string(count) + " points");
    refresh();
  }

  // Direct manipulation: press on the manipulated handle, move, release.
  bool dragBegin(int x, int y) {
    if (!drag_mode_ || !run_.ready()) return false;
    const int hit = nearestOnScreen(x, y, 20.0, /*manipulated_only=*/true);
    if (hit < 0) {
      message("press on the manipulated handle (red) to drag it");
      return true;
    }
    dragging_ = true;
    drag_from_ = deformed(static_cast<std::size_t>(hit));
    drag_depth_ = toDisplay(drag_from_).z();
    drag_last_ = drag_from_;
    return true;
  }

  bool dragMove(int x, int y) {
    if (!dragging_) return false;
    const Eigen::Vector3d to = fromDisplay(x, y, drag_depth_);
    const auto t0 = Clock::now();
    run_.liveDrag(drag_last_, to);
    const double total = msSince(t0);
    stats_.interpolate.push_back(run_.deformer().lastInterpolationMs());
    stats_.solve.push_back(total - run_.deformer().lastInterpolationMs());
    drag_last_ = to;
    updatePositions();
    return true;
  }

  bool dragEnd(int x, int y) {
    if (!dragging_) return false;
    dragMove(x, y);
    dragging_ = false;
    // Commit as `hgdeform deform` would replay it: from the state before the gesture (the
    // runner drops the live frames), the picked point dragged from where it was to where the
    // cursor let go.
    hgd::Move m;
    m.kind = hgd::Move::Kind::Drag;
    m.drag.from = drag_from_;
    m.drag.to = drag_last_;
    commit(m);
    refresh();
    return true;
  }

  // --- replay -----------------------------------------------------------------------------

  // Plays events that hgdview::readReplay() has checked (all of them, before the first runs).
  void replay(const std::vector<hgdview::ReplayEvent>& events, const std::string& path,
              vtkRenderWindowInteractor* iren) {
    for (const hgdview::ReplayEvent& e : events) {
      try {
        replayEvent(e, iren);
      } catch (const std::exception& ex) {
        throw std::runtime_error(path + ": " + e.path + ": " + ex.what());
      }
    }
  }

  void printStats() const {
    auto median = [](std::vector<double> v) {
      if (v.empty()) return 0.0;
      std::sort(v.begin(), v.end());
      return v[v.size() / 2];
    };
    const double s = median(stats_.solve), i = median(stats_.interpolate), r = median(stats_.render);
    std::printf(
        "frames %zu: solve %.2f ms, interpolate %.2f ms, render %.2f ms (medians); %.1f frames/s, %.0f "
        "updates/s without rendering\n",
        stats_.solve.size(), s, i, r, 1000.0 / std::max(1e-9, s + i + r), 1000.0 / std::max(1e-9, s + i));
  }

  void screenshot(const std::string& path) {
    render();
    hgd::writeWindowPng(vis_->getRenderWindow(), path, inputs_, "screenshot");
    message("screenshot " + path);
  }

  Style* style() { return style_.Get(); }
  pcl::visualization::PCLVisualizer& vis() { return *vis_; }

 private:
  // --- state changes ----------------------------------------------------------------------

  void markSelection(int role) {
    std::vector<int> idx;
    for (std::size_t i = 0; i < selected_.size(); ++i)
      if (selected_[i]) idx.push_back(static_cast<int>(i));
    if (idx.empty()) return message("nothing selected (x: area, shift+click: point)");
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
    syncRegions();
    clearSelection(false);
    refreshRoles();
    run_.setHandles(handles_);
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
  void syncRegions() {
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

  void clearSelection(bool redraw = true) {
    std::fill(selected_.begin(), selected_.end(), 0);
    if (redraw) refresh();
  }

  void clearHandles() {
    handles_ = hgd::Handles{};
    fixed_regions_.clear();
    joint_regions_.clear();
    run_.setHandles(handles_);
    run_.setRegions(fixed_regions_, manipulated_region_, joint_regions_);
    updateAlerts();
    refreshRoles();
    message("handles cleared");
    refresh();
  }

  // What the deformation cannot do for this shape, on the status line and stderr: pieces that
  // no handle reaches (followed or left), a piece moved rigidly, a surface pulled apart.
  void updateAlerts() {
    alert_.clear();
    if (!run_.ready()) return;
    const hgd::PieceReport& p = run_.deformer().pieces().report;
    std::vector<std::string> full = p.warnings();
    std::ostringstream s;
    if (p.followed_points) s << " | " << p.followed_points << " points without a handle follow";
    if (p.stayed_points) s << " | " << p.stayed_points << " points without a handle stay";
    if (p.rigid_points) s << " | " << p.rigid_points << " points move rigidly with the handle";
    if (!run_.moves().empty()) {
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
  void commit(const hgd::Move& m) {
    if (!run_.ready()) return;
    run_.apply(m);
    updateAlerts();
  }

  void frameMove(const Eigen::Vector3d& translate, const Eigen::Vector3d& axis, double degrees) {
    if (!run_.ready()) return message("mark a fixed and a manipulated handle first");
    hgd::Move m;
    m.kind = hgd::Move::Kind::Frame;
    m.frame.translate = translate;
    if (degrees != 0) {
      m.frame.axis = axis;
      m.frame.degrees = degrees;
      m.frame.center = handleCentre();  // explicit, so that the scenario replays it exactly
    }
    const auto t0 = Clock::now();
    commit(m);
    stats_.solve.push_back(msSince(t0));
    stats_.interpolate.push_back(run_.deformer().lastInterpolationMs());
    refresh();
  }

  void undo() {
    if (!run_.ready() || !run_.undo()) return message("nothing to undo");
    updateAlerts();
    message("undone");
    refresh();
  }

  void redo() {
    if (!run_.ready() || !run_.redo()) return message("nothing to redo");
    updateAlerts();
    message("redone");
    refresh();
  }

  void resetShape() {
    if (!run_.ready()) return;
    run_.reset();
    updateAlerts();
    message("rest shape");
    refresh();
  }

  void saveShape(const std::string& path) {
    run_.write(path, {}, inputs_);
    message("saved " + path);
  }

  void saveScenario(const std::string& path) {
    hgd::refuseInputs(path, inputs_);
    if (handles_.fixed.empty() || handles_.manipulated.empty())
      return message("a scenario needs a fixed and a manipulated handle");
    hgd::writeFileAtomically(path, hgd::scenarioToJson(run_.scenario()));
    message("saved " + path);
  }

  // --- drawing ----------------------------------------------------------------------------

  void fileColours() {
    const hgd::ColourFields fields = hgd::findColourFields(run_.shape().cloud);
    colours_.resize(run_.geometry().size());
    for (std::size_t i = 0; i < run_.geometry().size(); ++i)
      colours_[i] =
          hgd::readColour(run_.shape().cloud, static_cast<std::size_t>(run_.geometry().raw_index[i]), fields);
  }

  void refreshRoles() {
    std::fill(role_.begin(), role_.end(), 0);
    for (const auto& f : handles_.fixed)
      for (int i : f) role_[static_cast<std::size_t>(i)] = 1;
    for (int i : handles_.manipulated) role_[static_cast<std::size_t>(i)] = 2;
    for (const auto& jt : handles_.joints)
      for (int i : jt) role_[static_cast<std::size_t>(i)] = 3;
  }

  void refresh() {
    if (!vis_) return;
    static const Eigen::Vector3f kRole[4] = {
        {0, 0, 0}, {0.15f, 0.35f, 0.95f}, {0.95f, 0.15f, 0.1f}, {0.2f, 0.75f, 0.2f}};
    const bool field_view = view_ == 1 && run_.ready();
    const bool cluster_view = view_ == 2 && run_.ready();
    for (std::size_t i = 0; i < run_.geometry().size(); ++i) {
      auto& p = (*display_)[i];
      p.getVector3fMap() = deformed(i).cast<float>();
      Eigen::Vector3f c = colours_[i];
      if (field_view) c = hgd::colourMap(run_.deformer().field()[i]);
      if (cluster_view) c = clusterColour(run_.deformer().clustering().piece[i]);
      if (!field_view && role_[i] != 0) c = 0.35f * c + 0.65f * kRole[static_cast<int>(role_[i])];
      if (selected_[i]) c = Eigen::Vector3f(1.0f, 0.85f, 0.1f);
      p.r = static_cast<std::uint8_t>(std::clamp(c.x(), 0.0f, 1.0f) * 255);
      p.g = static_cast<std::uint8_t>(std::clamp(c.y(), 0.0f, 1.0f) * 255);
      p.b = static_cast<std::uint8_t>(std::clamp(c.z(), 0.0f, 1.0f) * 255);
    }
    if (run_.geometry().faces.empty()) {
      // With an explicit colour handler: PCL's plain update paints the cloud white.
      const pcl::visualization::PointCloudColorHandlerRGBField<pcl::PointXYZRGB> rgb(display_);
      vis_->updatePointCloud<pcl::PointXYZRGB>(display_, rgb, "shape");
    } else {
      // PCL's updatePolygonMesh drops the colours (the mesh turns black): add it afresh.
      pcl::PolygonMesh mesh;
      pcl::toPCLPointCloud2(*display_, mesh.cloud);
      mesh.polygons = run_.geometry().faces;
      vis_->removePolygonMesh("shape");
      vis_->addPolygonMesh(mesh, "shape");
    }
    if (overlay_ && !overlay_shown_) {
      const pcl::visualization::PointCloudColorHandlerRGBField<pcl::PointXYZRGB> grey(rest_);
      vis_->addPointCloud<pcl::PointXYZRGB>(rest_, grey, "rest");
      vis_->setPointCloudRenderingProperties(pcl::visualization::PCL_VISUALIZER_OPACITY, 0.35, "rest");
      overlay_shown_ = true;
    } else if (!overlay_ && overlay_shown_) {
      vis_->removePointCloud("rest");
      overlay_shown_ = false;
    }
    scale_bar_->SetVisibility(field_view);
    render();
  }

  // During a drag only positions change: write them straight into the VTK points of the shape
  // (PCL's update would rebuild the whole poly data, colours included, on every mouse move).
  void updatePositions() {
    vtkPolyData* poly = shapePolyData();
    vtkPoints* pts = poly ? poly->GetPoints() : nullptr;
    if (!pts || pts->GetNumberOfPoints() != static_cast<vtkIdType>(run_.geometry().size()) ||
        pts->GetDataType() != VTK_FLOAT) {
      refresh();
      return;
    }
    float* raw = static_cast<vtkFloatArray*>(pts->GetData())->GetPointer(0);
    const long long n = static_cast<long long>(run_.geometry().size());
    const auto& local = run_.deformer().deformedPoints();
    const Eigen::Vector3f origin = run_.geometry().origin.cast<float>();
#pragma omp parallel for schedule(static)
    for (long long i = 0; i < n; ++i) {
      const Eigen::Vector3f p = local[static_cast<std::size_t>(i)] + origin;
      raw[3 * i] = p.x();
      raw[3 * i + 1] = p.y();
      raw[3 * i + 2] = p.z();
    }
    pts->Modified();
    poly->Modified();
    render();
  }

  vtkPolyData* shapePolyData() {
    vtkMapper* mapper = nullptr;
    if (run_.geometry().faces.empty()) {
      auto it = vis_->getCloudActorMap()->find("shape");
      if (it != vis_->getCloudActorMap()->end() && it->second.actor) mapper = it->second.actor->GetMapper();
    } else {
      auto it = vis_->getShapeActorMap()->find("shape");
      if (it != vis_->getShapeActorMap()->end())
        if (auto* actor = vtkActor::SafeDownCast(it->second)) mapper = actor->GetMapper();
    }
    return mapper ? vtkPolyData::SafeDownCast(mapper->GetInput()) : nullptr;
  }

  void render() {
    const auto t0 = Clock::now();
    updateStatus();
    vis_->getRenderWindow()->Render();
    if (dragging_) stats_.render.push_back(msSince(t0));
  }

  void updateStatus() {
    static const char* kViews[3] = {"colours", "field", "clusters"};
    std::ostringstream s;
    s << run_.geometry().size() << " points";
    if (run_.ready()) s << ", " << run_.deformer().clustering().clusters.size() << " clusters";
    s << " | view " << kViews[view_] << (drag_mode_ ? " | DRAG" : "") << (frame_mode_ ? " | FRAME" : "");
    if (!stats_.solve.empty())
      s << " | solve " << num(stats_.solve.back()) << " ms, interpolate " << num(stats_.interpolate.back())
        << " ms, render " << (stats_.render.empty() ? std::string("-") : num(stats_.render.back())) << " ms";
    s << alert_;
    if (!message_.empty()) s << " | " << message_;
    vis_->updateText(s.str(), 10, 10, 13, 0.1, 0.1, 0.1, "status");
  }

  void message(const std::string& m) {
    message_ = m;
    if (verbose_) std::fprintf(stderr, "hgdeform-view: %s\n", m.c_str());
    if (vis_) render();
  }

  static Eigen::Vector3f clusterColour(int id) {
    // Golden-ratio hues: neighbouring ids look different.
    const float h = std::fmod(static_cast<float>(id) * 0.618034f, 1.0f) * 6.0f;
    const float x = 1.0f - std::abs(std::fmod(h, 2.0f) - 1.0f);
    Eigen::Vector3f c;
    if (h < 1)
      c = {1, x, 0};
    else if (h < 2)
      c = {x, 1, 0};
    else if (h < 3)
      c = {0, 1, x};
    else if (h < 4)
      c = {0, x, 1};
    else if (h < 5)
      c = {x, 0, 1};
    else
      c = {1, 0, x};
    return 0.25f + 0.7f * c.array();
  }

  // --- geometry on screen -----------------------------------------------------------------

  vtkRenderer* renderer() {
    return vis_->getRenderWindow()->GetRenderers()->GetFirstRenderer();
  }

  Eigen::Vector3d deformed(std::size_t i) const {
    return run_.ready() ? run_.deformer().deformedWorld(i) : run_.geometry().world(i);
  }

  Eigen::Vector3d centre() const {
    const Eigen::AlignedBox3f box = hgd::boundingBox(*run_.geometry().points);
    return run_.geometry().origin + 0.5 * (box.min() + box.max()).cast<double>();
  }

  Eigen::Vector3d handleCentre() const {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int i : handles_.manipulated) c += deformed(static_cast<std::size_t>(i));
    return c / std::max<double>(1.0, static_cast<double>(handles_.manipulated.size()));
  }

  Eigen::Vector3d toDisplay(const Eigen::Vector3d& w) {
    vtkRenderer* r = renderer();
    r->SetWorldPoint(w.x(), w.y(), w.z(), 1.0);
    r->WorldToDisplay();
    double d[3];
    r->GetDisplayPoint(d);
    return {d[0], d[1], d[2]};
  }

  Eigen::Vector3d fromDisplay(double x, double y, double depth) {
    vtkRenderer* r = renderer();
    r->SetDisplayPoint(x, y, depth);
    r->DisplayToWorld();
    double w[4];
    r->GetWorldPoint(w);
    return Eigen::Vector3d(w[0], w[1], w[2]) / (w[3] != 0 ? w[3] : 1.0);
  }

  void cameraAxes(Eigen::Vector3d& up, Eigen::Vector3d& right, Eigen::Vector3d& view) {
    vtkCamera* cam = renderer()->GetActiveCamera();
    double u[3], p[3], f[3];
    cam->GetViewUp(u);
    cam->GetPosition(p);
    cam->GetFocalPoint(f);
    view = (Eigen::Vector3d(f[0], f[1], f[2]) - Eigen::Vector3d(p[0], p[1], p[2])).normalized();
    up = Eigen::Vector3d(u[0], u[1], u[2]).normalized();
    right = view.cross(up).normalized();
    up = right.cross(view).normalized();
  }

  // The point nearest to the cursor on screen (within `pixels`), front-most on ties.
  int nearestOnScreen(int x, int y, double pixels, bool manipulated_only = false) {
    int best = -1;
    double best_d = pixels * pixels, best_z = INFINITY;
    auto consider = [&](std::size_t i) {
      const Eigen::Vector3d d = toDisplay(deformed(i));
      const double dd = (d.x() - x) * (d.x() - x) + (d.y() - y) * (d.y() - y);
      if (dd < best_d - 1e-9 || (std::abs(dd - best_d) <= 1e-9 && d.z() < best_z)) {
        best_d = dd;
        best_z = d.z();
        best = static_cast<int>(i);
      }
    };
    if (manipulated_only) {
      for (int i : handles_.manipulated) consider(static_cast<std::size_t>(i));
    } else {
      for (std::size_t i = 0; i < run_.geometry().size(); ++i) consider(i);
    }
    return best;
  }

  // --- replay -----------------------------------------------------------------------------

  Eigen::Vector2d screenOf(const hgdview::ReplayPosition& p) {
    return p.world ? Eigen::Vector2d(toDisplay(p.at).head<2>()) : Eigen::Vector2d(p.at.head<2>());
  }

  // A window coordinate as an int. World points far off the screen (or at the eye) project to
  // huge or NaN display coordinates, which no int holds: they land far outside the window.
  static int pixel(double v) {
    if (std::isnan(v)) return -1000000;
    return static_cast<int>(std::clamp(v, -1e6, 1e6));
  }

  void sendKey(vtkRenderWindowInteractor* iren, const std::string& key) {
    // Named keys (Left, Right, Up, Down) go as key symbols; others as characters.
    const bool named = key.size() > 1;
    iren->SetKeyEventInformation(0, 0, named ? 0 : key[0], 1, key.c_str());
    iren->InvokeEvent(vtkCommand::KeyPressEvent, nullptr);
    iren->InvokeEvent(vtkCommand::CharEvent, nullptr);
    iren->InvokeEvent(vtkCommand::KeyReleaseEvent, nullptr);
  }

  void sendMouse(vtkRenderWindowInteractor* iren, unsigned long event, const Eigen::Vector2d& at,
                 bool shift = false) {
    iren->SetEventInformation(pixel(std::round(at.x())), pixel(std::round(at.y())), 0, shift ? 1 : 0);
    iren->InvokeEvent(event, nullptr);
  }

  void replayEvent(const hgdview::ReplayEvent& e, vtkRenderWindowInteractor* iren) {
    using Kind = hgdview::ReplayEvent::Kind;
    switch (e.kind) {
      case Kind::Key: sendKey(iren, e.text); break;
      case Kind::Radius: radius_ = e.radius; break;
      case Kind::Pick: {  // shift+click
        if (e.has_radius) radius_ = e.radius;
        const Eigen::Vector2d at = screenOf(e.from);
        sendMouse(iren, vtkCommand::LeftButtonPressEvent, at, true);
        sendMouse(iren, vtkCommand::LeftButtonReleaseEvent, at, true);
        break;
      }
      case Kind::Area: {
        const Eigen::Vector2d p0 = screenOf(e.from), p1 = screenOf(e.to);
        selectArea(pixel(std::floor(p0.x())), pixel(std::floor(p0.y())), pixel(std::ceil(p1.x())),
                   pixel(std::ceil(p1.y())));
        break;
      }
      case Kind::Drag: {
        if (!drag_mode_) sendKey(iren, "d");
        const Eigen::Vector2d a = screenOf(e.from);
        // The target's depth is that of the press: world targets are taken in that plane.
        sendMouse(iren, vtkCommand::LeftButtonPressEvent, a);
        const Eigen::Vector2d b = screenOf(e.to);
        for (int k = 1; k <= e.steps; ++k)
          sendMouse(iren, vtkCommand::MouseMoveEvent, a + (b - a) * (static_cast<double>(k) / e.steps));
        sendMouse(iren, vtkCommand::LeftButtonReleaseEvent, b);
        break;
      }
      case Kind::View:
        view_ = e.view;
        refresh();
        break;
      case Kind::Screenshot: screenshot(e.text); break;
      case Kind::Save: saveShape(e.text); break;
      case Kind::SaveScenario: saveScenario(e.text); break;
    }
  }

  std::string defaultPath(const std::string& suffix, const std::string& ext) const {
    const std::filesystem::path p(input_);
    return (p.parent_path() / (p.stem().string() + suffix + ext)).string();
  }
  static std::string extensionOf(const std::string& path) {
    const std::string e = std::filesystem::path(path).extension().string();
    return e.empty() ? ".ply" : e;
  }
  static std::string num(double v) {
    char b[32];
    std::snprintf(b, sizeof b, "%.3g", v);
    return b;
  }

 public:
  bool verbose_ = true;
  std::vector<std::string> inputs_;  // files no output may replace
  bool drag_mode_ = false;

 private:
  std::string input_;
  int width_, height_;
  hgd::ScenarioRunner run_;  // the shape, its handles, the deformer, moves and undo
  double diagonal_ = 1, radius_ = 0.03;
  std::vector<hgd::Region> fixed_regions_, joint_regions_;
  hgd::Region manipulated_region_;
  hgd::Handles handles_;
  std::vector<char> role_, selected_;
  std::vector<Eigen::Vector3f> colours_;
  pcl::PointCloud<pcl::PointXYZRGB>::Ptr display_, rest_;
  std::unique_ptr<pcl::visualization::PCLVisualizer> vis_;
  vtkSmartPointer<Style> style_;
  vtkSmartPointer<vtkScalarBarActor> scale_bar_;
  int view_ = 0;
  bool overlay_ = false, overlay_shown_ = false, help_visible_ = false;
  bool frame_mode_ = false, dragging_ = false, quit_ = false;
  Eigen::Vector3d drag_from_, drag_last_;
  double drag_depth_ = 0;
  std::string message_;
  std::string alert_;                  // see updateAlerts()
  std::vector<std::string> reported_;  // warnings already printed on stderr
  FrameStats stats_;
};

void Style::OnKeyDown() {
  if (viewer && viewer->key(Interactor->GetKeySym() ? Interactor->GetKeySym() : "", Interactor->GetKeyCode()))
    return;
  Superclass::OnKeyDown();
}

void Style::OnChar() {
  // Our keys were handled on key-down; keep VTK's own char bindings (w, s, f, e, ...) off them.
  const char k = Interactor->GetKeyCode();
  if (std::string("fmjcCdtvozynsSkh+=-q[],.").find(k) != std::string::npos && k != 0) return;
  Superclass::OnChar();
}

void Style::OnLeftButtonDown() {
  const int* p = Interactor->GetEventPosition();
  if (!selecting() && Interactor->GetShiftKey() && viewer) {
    viewer->pickAt(p[0], p[1]);
    return;
  }
  if (!selecting() && viewer && viewer->dragBegin(p[0], p[1])) return;
  Superclass::OnLeftButtonDown();
}

void Style::OnMouseMove() {
  const int* p = Interactor->GetEventPosition();
  if (viewer && viewer->dragMove(p[0], p[1])) return;
  Superclass::OnMouseMove();
}

void Style::OnLeftButtonUp() {
  const int* p = Interactor->GetEventPosition();
  if (viewer && viewer->dragEnd(p[0], p[1])) return;
  if (selecting() && viewer) {
    Superclass::OnLeftButtonUp();
    int x0, y0, x1, y1;
    rubberBand(x0, y0, x1, y1);
    viewer->selectArea(x0, y0, x1, y1);
    return;
  }
  Superclass::OnLeftButtonUp();
}

const char* kDescription =
    "Opens a shape for interactive deformation; 'h' in the window lists the keys.\n"
    "--replay plays a script of events and exits (the whole file is checked first); with\n"
    "--screenshot it then saves a PNG, with --stats it prints frame timings. The replay format\n"
    "and how the options combine: docs/replay.md.";

/// hgdeform-view's command line.
struct ViewArgs {
  std::string input, scenario, replay, shot;
  int width = 1100, height = 800;
  bool stats = false, quiet = false;
};

/// Parses the command line into `a`; returns -1 to go on, else the exit status.
int parseArgs(int argc, char** argv, ViewArgs& a) {
  CLI::App app(kDescription);
  hgdcli::configureApp(app, "hgdeform-view");
  app.add_option("INPUT", a.input, "the shape: PLY, PCD, OBJ, XYZ/TXT, OFF or STL")
      ->required()
      ->type_name("");
  app.add_option("-s,--scenario", a.scenario, "handles to load (docs/scenario.md)")->type_name("S.json");
  app.add_option("--replay", a.replay, "play a script of events, then exit (docs/replay.md)")
      ->type_name("EVENTS.json");
  app.add_option("--screenshot", a.shot, "save a PNG (after the replay, if any) and exit")
      ->type_name("OUT.png");
  std::string size;
  app.add_option("--size", size, "window size (default 1100x800)")
      ->check(CLI::Validator(
          [&a](std::string& text) -> std::string {
            int w = 0, h = 0;
            char rest = 0;
            if (std::sscanf(text.c_str(), "%dx%d%c", &w, &h, &rest) != 2 || w < 64 || h < 64)
              return "must be WIDTHxHEIGHT, each at least 64 (got '" + text + "')";
            a.width = w;
            a.height = h;
            return {};
          },
          "", "size"))
      ->type_name("WxH");
  app.add_flag("--stats", a.stats, "print frame timings");
  app.add_flag("-q,--quiet", a.quiet, "print nothing but errors");
  return hgdcli::parse(app, argc, argv);
}

}  // namespace

int main(int argc, char** argv) {
  hgdcli::singleThreadBlas();  // as hgdeform does (blas_guard.h)
  ViewArgs args;
  if (const int status = parseArgs(argc, argv, args); status >= 0) return status;
  const std::string &input = args.input, &scenario = args.scenario, &replay = args.replay, &shot = args.shot;
  const int width = args.width, height = args.height;
  const bool stats = args.stats, quiet = args.quiet;
  try {
    // No output of the viewer (screenshots, saved shapes and scenarios, from keys or replay
    // events) may replace one of its inputs.
    const std::vector<std::string> inputs = {input, scenario, replay};
    if (!shot.empty()) hgd::refuseInputs(shot, inputs);
    // The whole replay is checked before anything runs (no display needed): a bad event late in
    // the file does nothing at all, not even the events before it.
    std::vector<hgdview::ReplayEvent> events;
    if (!replay.empty()) {
      events = hgdview::readReplay(replay);
      hgdview::refuseInputsAsOutputs(events, replay, inputs);
    }
    if (const std::string problem = hgd::displayProblem(); !problem.empty())
      throw std::runtime_error(problem);
    Viewer viewer(input, width, height);
    viewer.verbose_ = !quiet;
    viewer.inputs_ = inputs;
    if (!scenario.empty()) viewer.loadScenario(scenario);
    viewer.open();
    viewer.vis().setSize(width, height);  // the first render may shrink the window
    if (!replay.empty()) {
      viewer.replay(events, replay, viewer.vis().getRenderWindow()->GetInteractor());
      if (!shot.empty()) viewer.screenshot(shot);
      if (stats) viewer.printStats();
      return 0;  // scripted: no interactive loop (and no close(), which crashes without one)
    }
    if (!shot.empty()) {
      viewer.screenshot(shot);
      return 0;
    }
    viewer.spin();
    if (stats) viewer.printStats();
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "hgdeform-view: " << e.what() << "\n";
    return 1;
  }
}
