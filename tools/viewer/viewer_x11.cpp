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

// Takes the pointer motions waiting at the head of the window's event queue (none other, and
// none past another event) and gives the last one's position, in X's window pixels (from the
// top left). A drag's frames cost more than the mouse's pace: the frame for where the pointer
// is now replaces the ones for where it was.
bool latestMotion(void* display, unsigned long window, int& x, int& y) {
  auto* d = static_cast<Display*>(display);
  if (!d || !window) return false;
  bool found = false;
  XEvent e;
  while (XPending(d) > 0) {
    XPeekEvent(d, &e);
    if (e.type != MotionNotify || e.xmotion.window != window) break;
    XNextEvent(d, &e);
    x = e.xmotion.x;
    y = e.xmotion.y;
    found = true;
  }
  return found;
}

}  // namespace hgdview
