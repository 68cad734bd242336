#include "keys.h"

#include <algorithm>
#include <cstddef>
#include <cstring>
#include <vector>

namespace hgdview {

namespace {

using A = KeyAction;
constexpr unsigned kDrag = kWaitsForDrag, kBuild = kWaitsForBuild;

/// One line of the help overlay and the keys it shows, in order.
struct HelpLine {
  const char* start;
  std::vector<KeyBinding> keys;
  const char* end;
};

// The help shows them in this order; the bindings without `shown` go with the one before.
const std::vector<HelpLine> kLines = {
    {"modes: ",
     {
         {"x", A::AreaMode, "x", "area select", kDrag},
         {"p", A::LassoMode, "p", "lasso select", kDrag},
         {"d", A::DragMode, "d", "drag the manipulated handle", kDrag | kBuild},
         {"t", A::FrameMode, "t", "frame (arrows, [ ], , .)", kDrag | kBuild},
         {"[],.", A::FrameTurn, nullptr, nullptr, kDrag | kBuild},
     },
     "   (again: pick)"},
    {"",
     {
         {"", A::None, "shift+click", "select around a point (any mode)", kWaitsNever},
         {"", A::None, "ctrl", "with shift+click, area or lasso: deselect", kWaitsNever},
         {"+=", A::RadiusUp, "+/-", "radius", kDrag},
         {"-", A::RadiusDown, nullptr, nullptr, kDrag},
         {"c", A::ClearSelection, "c", "clear selection", kDrag},
     },
     ""},
    {"",
     {
         {"f", A::Fixed, "f", "fixed handle", kDrag | kBuild},
         {"m", A::Manipulated, "m", "manipulated handle", kDrag | kBuild},
         {"j", A::Joint, "j", "joint", kDrag | kBuild},
         {"C", A::ClearHandles, "C", "clear all handles (z: back)", kDrag | kBuild},
         {"l", A::KeepOrientation, "l", "drags keep orientation", kDrag | kBuild},
     },
     ""},
    {"",
     {
         {"v", A::View, "v", "view: colours / field / clusters", kDrag | kBuild},
         {"o", A::Overlay, "o", "rest overlay", kDrag | kBuild},
         {"<>", A::PointSize, "< >", "point size (or ctrl+wheel)", kDrag},
         {"i", A::Shading, "i", "shading on/off", kDrag},
         {"a", A::Axes, "a", "axes", kWaitsNever},
     },
     ""},
    {"",
     {
         {"r", A::OpeningView, "r", "fit the shape", kDrag},
         {"123456", A::StandardView, "1-6", "front back left right top bottom", kDrag},
         {"u", A::UpAxis, "u", "up axis", kDrag},
         {"", A::None, "mouse", "left turns, right/middle pans, wheel zooms", kWaitsNever},
     },
     ""},
    {"",
     {
         {"z", A::Undo, "z/y", "undo/redo", kDrag | kBuild},
         {"y", A::Redo, nullptr, nullptr, kDrag | kBuild},
         {"n", A::RestShape, "n", "rest shape (z: back)", kDrag | kBuild},
     },
     ""},
    {"",
     {
         {"s", A::SaveShape, "s", "save shape", kBuild},
         {"S", A::SaveScenario, "S", "save scenario", kDrag | kBuild},
         {"k", A::Screenshot, "k", "screenshot (numbered, never replaced)", kWaitsNever},
         {"h", A::Help, "h", "help", kWaitsNever},
         {"qe", A::Quit, "q/e", "quit", kWaitsNever},
     },
     ""},
};

}  // namespace

const KeyBinding* findKey(char k) {
  if (k == 0) return nullptr;
  for (const HelpLine& line : kLines)
    for (const KeyBinding& b : line.keys)
      if (std::strchr(b.keys, k) != nullptr) return &b;
  return nullptr;
}

std::string helpOverlay(std::size_t columns) {
  std::string text;
  for (const HelpLine& line : kLines) {
    std::vector<std::string> parts;
    if (line.start[0] != '\0') parts.emplace_back(line.start);
    for (const KeyBinding& b : line.keys)
      if (b.shown != nullptr) parts.push_back(std::string(b.shown) + "  " + b.what);
    if (line.end[0] != '\0') parts.back() += line.end;
    std::string out;
    std::size_t width = 0;  // of the output's last line
    for (std::size_t k = 0; k < parts.size(); ++k) {
      const bool joined = k > 0 && (k != 1 || line.start[0] == '\0');  // "modes: " runs into its first item
      const std::string sep = k == 0 ? "" : (joined ? "   " : "");
      if (columns > 0 && width > 0 && width + sep.size() + parts[k].size() > columns) {
        out += "\n    ";
        width = 4;
      } else {
        out += sep;
        width += sep.size();
      }
      out += parts[k];
      width += parts[k].size();
    }
    text += std::string(text.empty() ? "" : "\n") + out;
  }
  return text;
}

std::string keysMarkdown() {
  std::string text = "| key | does |\n| --- | --- |\n";
  for (const HelpLine& line : kLines)
    for (const KeyBinding& b : line.keys) {
      if (b.shown == nullptr) continue;
      std::string key = b.shown, cell;
      // Each key in code spans: "z/y" is `z`/`y`, "1-6" is `1`-`6`; words (shift+click, mouse)
      // as they are.
      const bool words = key.find("click") != std::string::npos || key == "mouse" || key == "ctrl";
      if (words) {
        cell = key;
      } else {
        std::string part;  // one key, closed by a space, or by / or - after a key ("+/-")
        const auto close = [&](const char* then) {
          if (!part.empty()) cell += "`" + part + "`";
          part.clear();
          cell += then;
        };
        for (const char c : key) {
          if (c == ' ')
            close(" ");
          else if ((c == '/' || c == '-') && !part.empty())
            close(c == '/' ? "/" : "-");
          else
            part += c;
        }
        close("");
      }
      text += "| " + cell + " | " + b.what + " |\n";
    }
  return text;
}

std::string keysHelp() {
  std::string text = "Keys in the window (also 'h' there; a mode's key again goes back to pick mode):\n";
  for (const HelpLine& line : kLines)
    for (const KeyBinding& b : line.keys)
      if (b.shown != nullptr) {
        std::string item = std::string("  ") + b.shown;
        item.resize(std::max<std::size_t>(item.size() + 2, 15), ' ');
        text += item + b.what + "\n";
      }
  return text;
}

}  // namespace hgdview
