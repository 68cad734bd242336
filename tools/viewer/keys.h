// The viewer's keys, written once: what each key does (Viewer::key in viewer_input.cpp acts by
// this table), whether it acts during a drag or while the deformer builds, and how the help
// overlay ('h') and `hgdeform-view --help` name it. PCL's and VTK's own keys are off; the mouse
// turns, pans and zooms the view as in PCL. README.md's viewer section shows the same keys (keysMarkdown).
#pragma once

#include <string>

namespace hgdview {

enum class KeyAction {
  None,  // a gesture the help names (shift+click), no key
  AreaMode,
  LassoMode,
  DragMode,
  FrameMode,
  FrameTurn,  // [ ] , . in frame mode (the arrows, named keys, move the handle)
  RadiusUp,
  RadiusDown,
  ClearSelection,
  Fixed,
  Manipulated,
  Joint,
  ClearHandles,
  KeepOrientation,
  View,
  Overlay,
  PointSize,
  OpeningView,
  UpAxis,
  StandardView,  // 1-6: front, back, left, right, top, bottom
  Axes,
  Shading,
  Undo,
  Redo,
  RestShape,
  SaveShape,
  SaveScenario,
  Screenshot,
  Help,
  Quit,
};

/// When a key waits (does nothing but say why) instead of acting; or-ed.
enum KeyWaits : unsigned {
  kWaitsNever = 0,
  /// While the mouse button holds a drag: a key that changed the handles, the shape or the mode
  /// would pull the deformer from under the live frames.
  kWaitsForDrag = 1,
  /// While the deformer is being built: the keys that need it (named keys too: the arrows).
  kWaitsForBuild = 2,
};

struct KeyBinding {
  const char* keys;  ///< the characters that press it ("" for a gesture)
  KeyAction action;
  const char* shown;  ///< how the help names it; nullptr: with the entry before (e.g. "+/-")
  const char* what;   ///< what the help says it does
  unsigned waits;     ///< KeyWaits
};

/// The binding of character `k`, or nullptr (no key of the viewer; 0 for a named key).
const KeyBinding* findKey(char k);

/// The help overlay: one line per help line of the table, items "x  area select" apart by three
/// spaces; a line longer than `columns` characters (0: no limit) goes on between items on the
/// next, indented.
std::string helpOverlay(std::size_t columns = 0);

/// The keys as README.md's Markdown table (`hgdeform-view --keys-markdown`; a test checks that
/// README.md holds it as written here).
std::string keysMarkdown();

/// The keys for `--help`: one item per line, indented.
std::string keysHelp();

}  // namespace hgdview
