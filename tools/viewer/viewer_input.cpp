// The viewer's input: the VTK interactor style (our keys and the handle drag first, PCL's
// behaviour for the rest), the keys, shift+click picks, the area selection and the drag gesture.
#include <vtkAbstractPicker.h>
#include <vtkAreaPicker.h>
#include <vtkCallbackCommand.h>
#include <vtkObjectFactory.h>
#include <vtkRenderWindow.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>

#include "viewer.h"

namespace hgdview {

vtkStandardNewMacro(Style);

const char* Viewer::mode() const {
  if (drag_mode_) return "drag";
  if (frame_mode_) return "frame";
  if (lasso_mode_) return "lasso";
  if (style_ && style_->selecting()) return "area";
  return "pick";
}

// One mode at a time: pick (the mouse turns the view; shift+click selects), area (the mouse
// draws a rectangle), drag (the mouse drags the manipulated handle), frame (keys move it).
void Viewer::setMode(const std::string& m) {
  drag_mode_ = m == "drag";
  frame_mode_ = m == "frame";
  lasso_mode_ = m == "lasso";
  if (style_) style_->setSelecting(m == "area");
  if (m == "area")
    message("area mode: drag a rectangle to select, with ctrl to deselect (x again: pick mode)");
  if (m == "lasso")
    message("lasso mode: draw round the points to select, with ctrl to deselect (p again: pick mode)");
  if (m == "drag") message("drag mode: left-drag the manipulated handle (d again: pick mode)");
  if (m == "frame") message("frame mode: arrows move, [ ] and , . turn the handle (t again: pick mode)");
  if (m == "pick") message("pick mode: the mouse turns the view, shift+click selects");
}

void Viewer::setCapsLock(bool on) {
  if (on == caps_lock_) return;
  caps_lock_ = on;
  if (style_) message(on ? "Caps Lock is on" : "Caps Lock is off");
}

// q and e quit; with unsaved changes only when pressed twice in a row.
void Viewer::requestQuit(char k) {
  if (unsaved_ && !quit_asked_) {
    quit_asked_ = true;
    return message(
        std::string("unsaved changes: press ") + k + " again to quit without saving " +
        (shape_unsaved_ ? "(s saves the shape, S the session)" : "(S saves the handles as a scenario)"));
  }
  quit_ = true;  // spin() ends
}

// Our keys, all of them: PCL's and VTK's own key bindings are off. Returns whether the key
// meant anything.
bool Viewer::key(const std::string& sym, char code) {
  const char k = code != 0 ? code : (sym.size() == 1 ? sym[0] : 0);
  // Modifier keys alone neither act nor cancel a pending quit.
  if (k == 0 && sym.find("Shift") != std::string::npos) return false;
  if (k == 0 && (sym.find("Control") != std::string::npos || sym.find("Alt") != std::string::npos ||
                 sym == "Caps_Lock"))
    return false;
  if (k != 'q' && k != 'e') quit_asked_ = false;
  const KeyBinding* binding = findKey(k);  // the table of keys.cpp: what acts when
  if ((dragging_ || !lasso_.empty()) && (!binding || (binding->waits & kWaitsForDrag))) {
    message("release the mouse button first");
    return true;
  }
  // Named keys wait too (the arrows move the handle).
  if (building_ && (!binding || (binding->waits & kWaitsForBuild))) {
    waiting_keys_.emplace_back(sym, code);  // pressed again, in order, when the build ends
    message("the deformer is still being built: " + (sym.empty() ? std::string(1, k) : sym) +
            " runs when it is done (" + std::to_string(waiting_keys_.size()) + " waiting)");
    return true;
  }
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
  if (!binding) {  // said, not silent (a key that does nothing looked like a key that failed)
    const bool arrow = sym == "Left" || sym == "Right" || sym == "Up" || sym == "Down";
    message(arrow ? "the arrow keys move the manipulated handle in frame mode (t)"
                  : "'" + (k != 0 ? std::string(1, k) : sym) + "' does nothing here (h lists the keys)");
    return false;
  }
  switch (binding->action) {
    case KeyAction::Fixed: markSelection(1); return true;
    case KeyAction::Manipulated: markSelection(2); return true;
    case KeyAction::Joint: markSelection(3); return true;
    case KeyAction::ClearSelection:
      clearSelection(false);
      message("selection cleared");
      refresh();
      return true;
    case KeyAction::ClearHandles: clearHandles(); return true;
    case KeyAction::AreaMode: setMode(std::string(mode()) == "area" ? "pick" : "area"); return true;
    case KeyAction::LassoMode: setMode(lasso_mode_ ? "pick" : "lasso"); return true;
    case KeyAction::UpAxis: cycleUp(); return true;
    case KeyAction::StandardView: standardView(k - '1'); return true;
    case KeyAction::Axes: showAxes(!axes_shown_); return true;
    case KeyAction::Shading: setShading(!shading_); return true;
    case KeyAction::DragMode: setMode(drag_mode_ ? "pick" : "drag"); return true;
    case KeyAction::FrameMode: setMode(frame_mode_ ? "pick" : "frame"); return true;
    case KeyAction::KeepOrientation:
      keep_orientation_ = !keep_orientation_;
      message(keep_orientation_ ? "drags keep the handle's orientation (it translates without turning)"
                                : "drags turn the handle as the shape pulls it (the paper's drag)");
      return true;
    case KeyAction::View:
      if (!ready()) {  // the field and the clusters are the deformer's: none to show yet
        view_ = 0;
        message(building_ ? "the field and the clusters show once the deformer is built"
                          : "the field and the clusters need a fixed and a manipulated handle (f, m)");
        refresh();
        return true;
      }
      view_ = (view_ + 1) % 3;
      message(view_ == 0 ? "view: colours" : view_ == 1 ? "view: the harmonic field" : "view: the clusters");
      refresh();
      return true;
    case KeyAction::Overlay:
      overlay_ = !overlay_;
      message(overlay_ ? "rest overlay on" : "rest overlay off");
      refresh();
      return true;
    case KeyAction::OpeningView:
      openingView();
      message("the whole shape in view");
      return true;
    case KeyAction::Undo: undo(); return true;
    case KeyAction::Redo: redo(); return true;
    case KeyAction::RestShape: resetShape(); return true;
    case KeyAction::SaveShape: saveShape(freshPath("-deformed", extensionOf(input_))); return true;
    case KeyAction::SaveScenario: saveScenario(freshPath("-scenario", ".json")); return true;
    case KeyAction::Screenshot: screenshot(freshPath("-screenshot", ".png")); return true;
    case KeyAction::Help:
      help_visible_ = !help_visible_;
      if (help_) help_->SetVisibility(help_visible_);
      message(help_visible_ ? "help shown" : "help hidden (h shows it)");
      return true;
    case KeyAction::RadiusUp:
      radius_ *= 1.25;
      message("selection radius " + num(radius_));
      return true;
    case KeyAction::RadiusDown:
      radius_ /= 1.25;
      message("selection radius " + num(radius_));
      return true;
    case KeyAction::PointSize: changePointSize(k == '>' ? 1 : -1); return true;
    case KeyAction::Quit: requestQuit(k); return true;
    case KeyAction::FrameTurn:  // frame mode's keys, above; nothing in the other modes
      message("[ ] , . turn the manipulated handle in frame mode (t)");
      return false;
    case KeyAction::None: return false;
  }
  return false;
}

void Viewer::changePointSize(int step) {
  if (!run_.geometry().faces.empty()) return message("point size: a mesh is drawn as a surface");
  double size = 1;
  vis_->getPointCloudRenderingProperties(pcl::visualization::PCL_VISUALIZER_POINT_SIZE, size, "shape");
  size = std::clamp(size + step, 1.0, 16.0);
  vis_->setPointCloudRenderingProperties(pcl::visualization::PCL_VISUALIZER_POINT_SIZE, size, "shape");
  message("point size " + num(size));
}

/// "selected 12 points" or "deselected 12 points".
static std::string selectedMessage(std::size_t count, bool remove) {
  return std::string(remove ? "deselected " : "selected ") + std::to_string(count) + " points";
}

// A click with shift: select (with ctrl, deselect) the points within the radius of the point
// under the cursor.
void Viewer::pickAt(int x, int y, bool remove) {
  const int hit = nearestOnScreen(x, y, 12.0);
  if (hit < 0) return message("nothing under the cursor");
  const Eigen::Vector3d p = deformed(static_cast<std::size_t>(hit));
  std::size_t count = 0;
  for (std::size_t i = 0; i < run_.geometry().size(); ++i)
    if ((deformed(i) - p).norm() <= radius_) {
      count += selected_[i] != (remove ? 0 : 1);
      selected_[i] = remove ? 0 : 1;
    }
  char at[96];
  std::snprintf(at, sizeof at, " at (%.6g, %.6g, %.6g)", p.x(), p.y(), p.z());
  message(selectedMessage(count, remove) + " around point " +
          std::to_string(run_.geometry().raw_index[static_cast<std::size_t>(hit)]) + at);
  refresh();
}

// The points whose projections fall inside a screen rectangle (every one, near side and far,
// as PCL's area pick and CloudCompare's segmentation take them); with ctrl, taken out.
void Viewer::selectArea(int x0, int y0, int x1, int y1, bool remove) {
  if (x0 > x1) std::swap(x0, x1);
  if (y0 > y1) std::swap(y0, y1);
  std::size_t count = 0;
  for (std::size_t i = 0; i < run_.geometry().size(); ++i) {
    const Eigen::Vector3d d = toDisplay(deformed(i));
    if (d.x() >= x0 && d.x() <= x1 && d.y() >= y0 && d.y() <= y1) {
      count += selected_[i] != (remove ? 0 : 1);
      selected_[i] = remove ? 0 : 1;
    }
  }
  message(selectedMessage(count, remove));
  refresh();
}

// The lasso: a loop drawn with the button held, closed at the release; the points whose
// projections fall inside it (even-odd rule) are selected, with ctrl deselected.
void Viewer::lassoBegin(int x, int y) {
  lasso_.assign(1, Eigen::Vector2d(x, y));
  drawLasso();
}

void Viewer::lassoMove(int x, int y) {
  if (lasso_.empty()) return;
  const Eigen::Vector2d p(x, y);
  if ((p - lasso_.back()).norm() < 3) return;  // a vertex every few pixels
  lasso_.push_back(p);
  drawLasso();
}

void Viewer::lassoEnd(int x, int y, bool remove) {
  if (lasso_.empty()) return;
  lassoMove(x, y);
  const std::vector<Eigen::Vector2d> loop = std::move(lasso_);
  lasso_.clear();
  drawLasso();
  if (loop.size() < 3) return message("draw round the points with the button held (a click selects nothing)");
  Eigen::Vector2d lo = loop[0], hi = loop[0];
  for (const Eigen::Vector2d& v : loop) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
  std::size_t count = 0;
  for (std::size_t i = 0; i < run_.geometry().size(); ++i) {
    const Eigen::Vector3d d = toDisplay(deformed(i));
    if (d.x() < lo.x() || d.x() > hi.x() || d.y() < lo.y() || d.y() > hi.y()) continue;
    bool inside = false;
    for (std::size_t a = 0, b = loop.size() - 1; a < loop.size(); b = a++) {
      const Eigen::Vector2d &p = loop[a], &q = loop[b];
      if ((p.y() > d.y()) != (q.y() > d.y()) &&
          d.x() < (q.x() - p.x()) * (d.y() - p.y()) / (q.y() - p.y()) + p.x())
        inside = !inside;
    }
    if (!inside) continue;
    count += selected_[i] != (remove ? 0 : 1);
    selected_[i] = remove ? 0 : 1;
  }
  message(selectedMessage(count, remove));
  refresh();
}

// Direct manipulation: press on the manipulated handle, move, release.
bool Viewer::dragBegin(int x, int y) {
  if (!drag_mode_ || !ready()) return false;
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
  // The handle moves as the pointer does from where it was pressed (the picked point may be
  // up to 20 pixels away): a press and release without motion moves nothing.
  drag_press_ = fromDisplay(x, y, drag_depth_);
  return true;
}

// Every live frame is the drag's own result: the move from the press to the cursor, solved from
// the state before the gesture exactly as the release commits it (and `hgdeform deform` replays
// it). So the last frame shown while the button is held is, point for point, the shape kept.
bool Viewer::dragMove(int x, int y) {
  if (!dragging_) return false;
  if (!ready()) {  // the handles went (cannot happen through keys while dragging; kept safe)
    dragging_ = false;
    live_shown_ = false;
    showLod(false);
    return true;
  }
  const Eigen::Vector3d to = drag_from_ + (fromDisplay(x, y, drag_depth_) - drag_press_);
  if (to == drag_last_) return true;  // nothing new to show (or, before any motion, nothing moved)
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
  if (run_.commitLive()) markUnsaved();
  updateAlerts();
  showLod(false);
  refresh();
  return true;
}

char keyChar(char code, bool shift, bool caps_lock) {
  if (!std::isalpha(static_cast<unsigned char>(code))) return code;
  const bool upper = shift != caps_lock;
  return static_cast<char>(upper ? std::toupper(static_cast<unsigned char>(code))
                                 : std::tolower(static_cast<unsigned char>(code)));
}

void Style::OnKeyDown() {
  const std::string sym = Interactor->GetKeySym() ? Interactor->GetKeySym() : "";
  // VTK hands a key over as its unshifted character and the shift flag, and says nothing of
  // Caps Lock. Events are handled after X has moved on (xdotool's "Caps_Lock s Caps_Lock"
  // arrives with the lock already off again), so the lock is tracked by the Caps_Lock presses
  // and set again from X at any other key that comes more than half a second after one (a
  // lock changed in another window is seen then), when the pointer enters the window, and at
  // a Caps_Lock press while it is unknown (X has it as that press left it). A replay's keys are
  // as written.
  const auto now = std::chrono::steady_clock::now();
  const bool burst = now - caps_time < std::chrono::milliseconds(500);
  if (sym == "Caps_Lock") {
    caps_lock = caps_lock < 0 ? askCapsLock() : 1 - caps_lock;
    caps_time = now;
    if (viewer && !replaying) viewer->setCapsLock(caps_lock == 1);
    return;
  }
  if (caps_lock < 0 || !burst) caps_lock = askCapsLock();
  if (viewer && !replaying) viewer->setCapsLock(caps_lock == 1);
  char code = keyChar(Interactor->GetKeyCode(), Interactor->GetShiftKey() != 0, !replaying && caps_lock == 1);
  // Shift on anything but a letter: the character the layout gives (Shift+comma is < on a US
  // keyboard), as a replay's {"key": "<"} names it. VTK says "comma", ',' and the shift flag:
  // only letters were shifted, so > arrived as . (in frame mode, a turn of the handle).
  std::string key_sym = sym;
  if (!replaying && Interactor->GetShiftKey() && code != 0 &&
      !std::isalpha(static_cast<unsigned char>(code))) {
    vtkRenderWindow* w = Interactor->GetRenderWindow();
    if (const char c = shiftedChar(w ? w->GetGenericDisplayId() : nullptr, sym.c_str()); c != 0) {
      code = c;
      key_sym = std::string(1, c);
    }
  }
  // Every key is ours (the help lists them): PCL's (u colour bar, g grid, j screenshot, e quit
  // at once, ...) and VTK's make no sense here and are off.
  if (viewer) viewer->key(key_sym, code);
}

int Style::askCapsLock() {
  vtkRenderWindow* w = Interactor ? Interactor->GetRenderWindow() : nullptr;
  return capsLockOn(w ? w->GetGenericDisplayId() : nullptr) ? 1 : 0;
}

void Style::OnEnter() {
  caps_lock = askCapsLock();  // Caps Lock may have changed in another window
  Superclass::OnEnter();
}

void Style::setSelecting(bool on) {
  if (on == selecting()) return;
  CurrentMode = on ? 1 : 0;
  if (!Interactor) return;
  if (on) {
    point_picker = Interactor->GetPicker();
    Interactor->SetPicker(vtkSmartPointer<vtkAreaPicker>::New());
  } else if (point_picker) {
    Interactor->SetPicker(point_picker);
  }
}

void Style::OnChar() {
  // Our keys were handled on key-down; VTK's char bindings (w, s, f, e, r, ...) stay off.
}

void Style::OnLeftButtonDown() {
  const int* p = Interactor->GetEventPosition();
  band = picked = false;
  if (Interactor->GetShiftKey() && viewer) {  // a pick, in any mode
    picked = true;
    viewer->pickAt(p[0], p[1], Interactor->GetControlKey() != 0);
    return;
  }
  if (viewer && viewer->lassoing()) {
    lasso = true;
    viewer->lassoBegin(p[0], p[1]);
    return;
  }
  if (!selecting() && viewer && viewer->dragBegin(p[0], p[1])) return;
  band = selecting();
  Superclass::OnLeftButtonDown();
}

void Style::OnMouseMove() {
  const int* p = Interactor->GetEventPosition();
  // A drag's frames cost more than the mouse's pace, and X coalesces the motions that come in
  // the meantime: VTK's window asks for motion hints, so X sends one motion and no other until
  // the window asks where the pointer is, which VTK does as it takes the motion. The position
  // here is where the pointer is now, and a frame drawn is followed by at most one more, for
  // where the pointer has gone since. (The viewer once took waiting motions off the queue
  // itself; a hint taken so was never answered with a query, and no motion came again until the
  // release: the shape stood still under a moving pointer, then jumped when the button came up.)
  if (viewer && viewer->dragMove(p[0], p[1])) return;
  if (lasso && viewer) return viewer->lassoMove(p[0], p[1]);
  // The right button's pan in area mode too: the rubber band's style answers motions only for
  // its band there.
  if (State == VTKIS_PAN) return vtkInteractorStyleTrackballCamera::OnMouseMove();
  Superclass::OnMouseMove();
}

void Style::OnLeftButtonUp() {
  const int* p = Interactor->GetEventPosition();
  if (picked) {
    picked = false;
    return;
  }
  if (lasso && viewer) {
    lasso = false;
    return viewer->lassoEnd(p[0], p[1], Interactor->GetControlKey() != 0);
  }
  if (viewer && viewer->dragEnd(p[0], p[1])) return;
  if (band && selecting() && viewer) {
    band = false;
    Superclass::OnLeftButtonUp();
    int x0, y0, x1, y1;
    rubberBand(x0, y0, x1, y1);
    viewer->selectArea(x0, y0, x1, y1, Interactor->GetControlKey() != 0);
    return;
  }
  Superclass::OnLeftButtonUp();
}

// The right button pans, as in CloudCompare (the middle button still does, as in PCL; VTK's
// right-button zoom is the wheel's).
void Style::OnRightButtonDown() {
  if (viewer && viewer->dragging()) return;
  const int* p = Interactor->GetEventPosition();
  FindPokedRenderer(p[0], p[1]);
  if (!CurrentRenderer) return;
  GrabFocus(EventCallbackCommand);
  StartPan();
}

void Style::OnRightButtonUp() {
  if (State == VTKIS_PAN) {
    EndPan();
    if (Interactor) ReleaseFocus();
  }
}

// Ctrl+wheel: the point size, as in CloudCompare; the wheel alone zooms.
void Style::OnMouseWheelForward() {
  if (viewer && viewer->dragging()) return;
  if (Interactor->GetControlKey() && viewer) return viewer->changePointSize(1);
  Superclass::OnMouseWheelForward();
}

void Style::OnMouseWheelBackward() {
  if (viewer && viewer->dragging()) return;
  if (Interactor->GetControlKey() && viewer) return viewer->changePointSize(-1);
  Superclass::OnMouseWheelBackward();
}

}  // namespace hgdview
