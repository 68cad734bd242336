// Plays a replay file's events (read and checked as a whole by replay.cpp, before the first
// runs) as the user's own: keys and mouse events go through the interactor, so the same code
// handles them.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <stdexcept>

#include "viewer.h"

namespace hgdview {

// Plays events that hgdview::readReplay() has checked (all of them, before the first runs).
void Viewer::replay(const std::vector<hgdview::ReplayEvent>& events, const std::string& path,
                    vtkRenderWindowInteractor* iren) {
  for (const hgdview::ReplayEvent& e : events) {
    try {
      replayEvent(e, iren);
    } catch (const std::exception& ex) {
      throw std::runtime_error(path + ": " + e.path + ": " + ex.what());
    }
  }
}

Eigen::Vector2d Viewer::screenOf(const hgdview::ReplayPosition& p) {
  return p.world ? Eigen::Vector2d(toDisplay(p.at).head<2>()) : Eigen::Vector2d(p.at.head<2>());
}

// A window coordinate as an int. World points far off the screen (or at the eye) project to
// huge or NaN display coordinates, which no int holds: they land far outside the window.
int Viewer::pixel(double v) {
  if (std::isnan(v)) return -1000000;
  return static_cast<int>(std::clamp(v, -1e6, 1e6));
}

void Viewer::sendKey(vtkRenderWindowInteractor* iren, const std::string& key) {
  // Named keys (Left, Right, Up, Down) go as key symbols; others as characters.
  // A capital letter comes with the shift flag, as from a keyboard.
  const bool named = key.size() > 1;
  const bool shift = !named && std::isupper(static_cast<unsigned char>(key[0]));
  iren->SetKeyEventInformation(0, shift ? 1 : 0, named ? 0 : key[0], 1, key.c_str());
  if (style_) style_->replaying = true;
  iren->InvokeEvent(vtkCommand::KeyPressEvent, nullptr);
  if (style_) style_->replaying = false;
  iren->InvokeEvent(vtkCommand::CharEvent, nullptr);
  iren->InvokeEvent(vtkCommand::KeyReleaseEvent, nullptr);
}

void Viewer::sendMouse(vtkRenderWindowInteractor* iren, unsigned long event, const Eigen::Vector2d& at,
                       bool shift) {
  iren->SetEventInformation(pixel(std::round(at.x())), pixel(std::round(at.y())), 0, shift ? 1 : 0);
  iren->InvokeEvent(event, nullptr);
}

void Viewer::replayEvent(const hgdview::ReplayEvent& e, vtkRenderWindowInteractor* iren) {
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

}  // namespace hgdview
