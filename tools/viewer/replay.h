// The replay files of hgdeform-view (--replay EVENTS.json; the format is in docs/replay.md):
// read and checked as a whole before any event runs, with JSON-path errors as scenarios have.
#pragma once

#include <Eigen/Core>
#include <stdexcept>
#include <string>
#include <vector>

namespace hgdview {

/// "<file>: <JSON pointer>: <what>", or "<file>: invalid JSON: ..." and the like.
class ReplayError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Where a pick, a drag end or an area corner is: a point of the shape's space, or a pixel of
/// the window (x, y from the bottom left; `at.z()` unused).
struct ReplayPosition {
  bool world = true;
  Eigen::Vector3d at = Eigen::Vector3d::Zero();
};

struct ReplayEvent {
  enum class Kind { Key, Radius, Pick, Area, Drag, View, Screenshot, Save, SaveScenario };
  Kind kind = Kind::Key;
  std::string path;         ///< the event's JSON pointer ("/events/3"), for messages
  std::string text;         ///< key: the key; screenshot, save, save_scenario: the output file
  double radius = 0;        ///< radius; pick: the new selection radius when `has_radius`
  bool has_radius = false;  ///< pick only
  ReplayPosition from, to;  ///< pick: from; drag: from and to; area: two opposite corners
  int steps = 20;           ///< drag: mouse moves between press and release
  int view = 0;             ///< view: 0 colours, 1 field, 2 clusters
};

/// The event's key in the file ("drag", "save_scenario", ...).
const char* eventName(ReplayEvent::Kind kind);

/// The file an event writes, or nullptr (screenshot, save and save_scenario write one).
const std::string* outputOf(const ReplayEvent& e);

/// Parses and checks a whole replay; `name` prefixes the messages. Throws ReplayError.
std::vector<ReplayEvent> parseReplay(const std::string& json_text, const std::string& name);

/// Reads a replay file (a regular file; a FIFO or a directory is refused) and parses it.
std::vector<ReplayEvent> readReplay(const std::string& path);

/// Throws ReplayError "<file>: /events/N/save: <output>: refusing to overwrite the input ..."
/// when an event of the replay would write over one of `inputs` (before any event runs).
void refuseInputsAsOutputs(const std::vector<ReplayEvent>& events, const std::string& name,
                           const std::vector<std::string>& inputs);

}  // namespace hgdview
