// Whether an X display can be opened and draws with OpenGL (GLX) (X11 kept out of the
// renderer's own file: its macros clash with Eigen's and VTK's names).
#include <X11/Xlib.h>

#include <cstdlib>
#include <string>

namespace hgd {

std::string displayProblem();  // render.h (not included: it brings Eigen, whose names X11's macros break)

std::string displayProblem() {
  const char* name = std::getenv("DISPLAY");
  if (!name || !*name) return "no X display: DISPLAY is not set (run under xvfb-run -a for scripts)";
  Display* d = XOpenDisplay(nullptr);
  if (!d)
    return std::string("cannot open the X display '") + name +
           "' (no X server there? run under xvfb-run -a for scripts)";
  // VTK draws with OpenGL through GLX; on a server without it no visual fits and VTK aborts.
  int opcode = 0, event = 0, error = 0;
  if (!XQueryExtension(d, "GLX", &opcode, &event, &error)) {
    XCloseDisplay(d);
    return std::string("the X display '") + name +
           "' has no GLX extension, so nothing can be drawn there with OpenGL (run under xvfb-run -a, "
           "or start the X server with GLX)";
  }
  // Kept open, not closed: an X server whose last client leaves resets itself (Xvfb under
  // xvfb-run does), and VTK's window, connecting a moment later, would find it resetting and
  // abort ("bad X server connection"). The connection closes when the process ends.
  static Display* kept = nullptr;
  if (kept)
    XCloseDisplay(d);
  else
    kept = d;
  return "";
}

}  // namespace hgd
