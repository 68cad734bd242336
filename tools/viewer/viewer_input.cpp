// The viewer's input: the VTK interactor style (our keys and the handle drag first, PCL's
// behaviour for the rest), the keys, shift+click picks, the area selection and the drag gesture.
#include <vtkObjectFactory.h>

#include <algorithm>

#include "viewer.h"

namespace hgdview {

vtkStandardNewMacro(Style);

// Our keys; returns false for keys that PCL/VTK should handle.
bool Viewer::key(const std::string& sym, char code) {
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
    case 'l':
      keep_orientation_ = !keep_orientation_;
      message(keep_orientation_ ? "drags keep the handle's orientation (it translates without turning)"
                                : "drags turn the handle as the shape pulls it (the paper's drag)");
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
void Viewer::pickAt(int x, int y) {
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
void Viewer::selectArea(int x0, int y0, int x1, int y1) {
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
bool Viewer::dragBegin(int x, int y) {
  if (!drag_mode_ || !run_.ready()) return false;
  const int hit = nearestOnScreen(x, y, 20.0, /*manipulated_only=*/true);
  if (hit < 0) {
    message("press on the manipulated handle (red) to drag it");
    return true;
  }
  dragging_ = true;
  showLod(true);
  stats_.drawn = lod_.empty() ? run_.geometry().size() : lod_.size();
  drag_from_ = deformed(static_cast<std::size_t>(hit));
  drag_depth_ = toDisplay(drag_from_).z();
  drag_last_ = drag_from_;
  return true;
}

// Every live frame is the drag's own result: the move from the press to the cursor, solved from
// the state before the gesture exactly as the release commits it (and `hgdeform deform` replays
// it). So the last frame shown while the button is held is, point for point, the shape kept.
bool Viewer::dragMove(int x, int y) {
  if (!dragging_) return false;
  const Eigen::Vector3d to = fromDisplay(x, y, drag_depth_);
  if (live_shown_ && to == drag_last_) return true;  // nothing new to show
  hgd::Move m;
  m.kind = hgd::Move::Kind::Drag;
  m.drag.from = drag_from_;
  m.drag.to = to;
  m.drag.keep_orientation = keep_orientation_;
  const auto t0 = Clock::now();
  run_.previewMove(m, lod_.empty() ? nullptr : &lod_);
  const double total = msSince(t0);
  stats_.interpolate.push_back(run_.deformer().lastInterpolationMs());
  stats_.solve.push_back(total - run_.deformer().lastInterpolationMs());
  drag_last_ = to;
  live_shown_ = true;
  // The warnings of what is shown (a surface pulled apart), where the whole shape is drawn.
  if (lod_.empty()) updateAlerts(/*live=*/true);
  updatePositions();
  return true;
}

bool Viewer::dragEnd(int x, int y) {
  if (!dragging_) return false;
  dragMove(x, y);  // a release away from the last motion shows that place first
  dragging_ = false;
  live_shown_ = false;
  // Keep what was shown: the runner records the move of the last live frame without solving
  // it again (the level of detail's other points are interpolated with the same transforms).
  run_.commitLive();
  updateAlerts();
  showLod(false);
  refresh();
  return true;
}

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

}  // namespace hgdview
