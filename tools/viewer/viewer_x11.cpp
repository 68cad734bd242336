// What the viewer asks the X server directly (kept apart: X11's macros break Eigen's names).
#include <X11/Xlib.h>

namespace hgdview {

// Whether Caps Lock is on: VTK hands a key over as the letter and the shift flag only.
bool capsLockOn(void* display) {
  auto* d = static_cast<Display*>(display);
  if (!d) return false;
  Window root = 0, child = 0;
  int rx = 0, ry = 0, wx = 0, wy = 0;
  unsigned int mask = 0;
  if (!XQueryPointer(d, DefaultRootWindow(d), &root, &child, &rx, &ry, &wx, &wy, &mask)) return false;
  return (mask & LockMask) != 0;
}

}  // namespace hgdview
