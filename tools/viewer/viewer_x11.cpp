// What the viewer asks the X server directly (kept apart: X11's macros break Eigen's names).
#include <X11/XKBlib.h>
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

// The character a key gives with Shift held, on the keyboard's own layout: VTK hands a key over
// as its unshifted keysym (Shift+comma as "comma") and the shift flag. The key that sends
// `keysym` is looked up, then what its shifted level sends; 0 when there is none, or it is no
// printable ASCII character (Latin-1 keysyms 0x20-0x7e are the characters themselves).
char shiftedChar(void* display, const char* keysym) {
  auto* d = static_cast<Display*>(display);
  if (!d || !keysym) return 0;
  const KeySym ks = XStringToKeysym(keysym);
  if (ks == NoSymbol) return 0;
  const KeyCode kc = XKeysymToKeycode(d, ks);
  if (kc == 0) return 0;
  const KeySym shifted = XkbKeycodeToKeysym(d, kc, 0, 1);
  return shifted >= 0x20 && shifted <= 0x7e ? static_cast<char>(shifted) : 0;
}

}  // namespace hgdview
