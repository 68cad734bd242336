// The viewer's input: the VTK interactor style (our keys and the handle drag first, PCL's
// behaviour for the rest), the keys, shift+click picks, the area selection and the drag gesture.
#include <vtkAbstractPicker.h>
#include <vtkAreaPicker.h>
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
  if (style_ && style_->selecting()) return "area";
  return "pick";
}

// One mode at a time: pick (the mouse turns the view; shift+click selects), area (the mouse
// draws a rectangle), drag (the mouse drags the manipulated handle), frame (keys move it).
void Viewer::setMode(const std::string& m) {
  drag_mode_ = m == "drag";
  frame_mode_ = m == "frame";
  if (style_) style_->setSelecting(m == "area");
  if (m == "area") message("area mode: drag a rectangle to select (x again: pick mode)");
  if (m == "drag") message("drag mode: left-drag the manipulated handle (d again: pick mode)");
  if (m == "frame") message("frame mode: arrows move, [ ] and , . turn the handle (t again: pick mode)");
  if (m == "pick") message("pick mode: the mouse turns the view, shift+click selects");
}

// C and n throw away what undo cannot bring back: they act when pressed twice in a row.
void Viewer::askAgain(char k, const std::string& what) {
  confirm_ = k;
  message(std::string("press ") + k + " again to " + what + " (undo cannot bring them back)" +
          (caps_lock_ && k == 'C' ? "; Caps Lock is on: c clears the selection" : ""));
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
  const char confirming = confirm_;  // C and n act when pressed twice in a row
  confirm_ = 0;
  const KeyBinding* binding = findKey(k);  // the table of keys.cpp: what acts when
  if (dragging_ && (!binding || (binding->waits & kWaitsForDrag))) {
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
    case KeyAction::ClearSelection: clearSelection(); return true;
    case KeyAction::ClearHandles: {
      const bool any = !handles_.fixed.empty() || !handles_.manipulated.empty() || !handles_.joints.empty();
      if (any && confirming != 'C') return askAgain('C', "clear every handle and move"), true;
      clearHandles();
      return true;
    }
    case KeyAction::AreaMode: setMode(std::string(mode()) == "area" ? "pick" : "area"); return true;
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
      refresh();
      return true;
    case KeyAction::Overlay:
      overlay_ = !overlay_;
      refresh();
      return true;
    case KeyAction::OpeningView: openingView(); return true;
    case KeyAction::Undo: undo(); return true;
    case KeyAction::Redo: redo(); return true;
    case KeyAction::RestShape:
      if (ready() && !run_.moves().empty() && confirming != 'n')
        return askAgain('n', "go back to the rest shape, dropping every move"), true;
      resetShape();
      return true;
    case KeyAction::SaveShape: saveShape(freshPath("-deformed", extensionOf(input_))); return true;
    case KeyAction::SaveScenario: saveScenario(freshPath("-scenario", ".json")); return true;
    case KeyAction::Screenshot: screenshot(freshPath("-screenshot", ".png")); return true;
    case KeyAction::Help:
      help_visible_ = !help_visible_;
      if (help_) help_->SetVisibility(help_visible_);
      render();
      return true;
    case KeyAction::RadiusUp:
      radius_ *= 1.25;
      message("selection radius " + num(radius_));
      return true;
    case KeyAction::RadiusDown:
      radius_ /= 1.25;
      message("selection radius " + num(radius_));
      return true;
    case KeyAction::PointSize: {  // < and > (+/- are the selection radius)
      if (!run_.geometry().faces.empty()) return message("point size: a mesh is drawn as a surface"), true;
      double size = 1;
      vis_->getPointCloudRenderingProperties(pcl::visualization::PCL_VISUALIZER_POINT_SIZE, size, "shape");
      size = std::clamp(size + (k == '>' ? 1.0 : -1.0), 1.0, 16.0);
      vis_->setPointCloudRenderingProperties(pcl::visualization::PCL_VISUALIZER_POINT_SIZE, size, "shape");
      message("point size " + num(size));
      return true;
    }
    case KeyAction::Quit: requestQuit(k); return true;
    case KeyAction::FrameTurn:  // frame mode's keys, above; nothing in the other modes
      message("[ ] , . turn the manipulated handle in frame mode (t)");
      return false;
    case KeyAction::None: return false;
  }
  return false;
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
  char at[96];
  std::snprintf(at, sizeof at, " at (%.6g, %.6g, %.6g)", p.x(), p.y(), p.z());
  message("selected " + std::to_string(count) + " points around point " +
          std::to_string(run_.geometry().raw_index[static_cast<std::size_t>(hit)]) + at);
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
    viewer->pickAt(p[0], p[1]);
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
  Superclass::OnMouseMove();
}

void Style::OnLeftButtonUp() {
  const int* p = Interactor->GetEventPosition();
  if (picked) {
    picked = false;
    return;
  }
  if (viewer && viewer->dragEnd(p[0], p[1])) return;
  if (band && selecting() && viewer) {
    band = false;
    Superclass::OnLeftButtonUp();
    int x0, y0, x1, y1;
    rubberBand(x0, y0, x1, y1);
    viewer->selectArea(x0, y0, x1, y1);
    return;
  }
  Superclass::OnLeftButtonUp();
}

}  // namespace hgdview
