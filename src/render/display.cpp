// Whether an X display can be opened (X11 kept out of the renderer's own file: its macros
// clash with Eigen's and VTK's names).
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
  XCloseDisplay(d);
  return "";
}

}  // namespace hgd
