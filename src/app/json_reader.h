// The one reader of hgdeform's JSON files, scenarios (src/app/scenario.cpp) and the viewer's replays
// (tools/viewer/replay.cpp) alike: the file read safely (a regular file of bounded size; a FIFO
// or a directory refused), the text parsed with duplicated keys refused, and checks that name the
// JSON pointer of a problem: "<file>: <pointer>: <what>". Each kind of file throws its own error
// type (ScenarioError, ReplayError) through a `JsonRaise`.
// For the library and its tools: not installed (it includes nlohmann/json.hpp, which the
// installed package does not require).
#pragma once

#include <cstdint>
#include <initializer_list>
#include <nlohmann/json.hpp>
#include <string>

namespace hgd {

/// Throws the error of a kind of file with `message` as what(); must not return.
using JsonRaise = void (*)(const std::string& message);

/// One JSON-pointer step for `key` (declared in scenario.h too, where it is public).
std::string jsonPointerStep(const std::string& key);

/// The whole text of the file at `path`, a `kind` file ("scenario", "replay") of at most
/// `max_bytes`. Raises "<path>: cannot open <kind> file: ...", "<path>: empty file",
/// "<path>: file too large for a <kind> (N bytes)" or "<path>: cannot read <kind> file: ...".
/// Opened non-blocking, so that a FIFO is refused instead of waiting for a writer.
std::string readJsonFile(const std::string& path, const char* kind, std::uintmax_t max_bytes,
                         JsonRaise raise);

/// Parses and checks the JSON of one file called `name` (the prefix of every message).
class JsonReader {
 public:
  using json = nlohmann::json;

  JsonReader(std::string name, JsonRaise raise) : name_(std::move(name)), raise_(raise) {}

  const std::string& name() const { return name_; }

  /// The document; a duplicated key raises "<name>: <pointer>: duplicate key" (the last one would
  /// silently win otherwise), any other parse error (syntax, a number beyond a double such as
  /// 1e400) "<name>: invalid JSON: <nlohmann's message, with the byte position>".
  json parse(const std::string& text) const;

  /// Raises "<name>: <path>: <what>" ("/" for the root).
  [[noreturn]] void fail(const std::string& path, const std::string& what) const;

  /// "a, b, c".
  static std::string list(std::initializer_list<const char*> keys);

  /// Raises "unknown key (expected one of: ...)" at the first key of `j` not in `keys`.
  void onlyKeys(const json& j, const std::string& path, std::initializer_list<const char*> keys) const;
  /// `j`, which must be an object.
  const json& object(const json& j, const std::string& path) const;
  /// `j`, which must be an object with no other keys than `keys` (onlyKeys).
  const json& objectWith(const json& j, const std::string& path,
                         std::initializer_list<const char*> keys) const;
  /// `j[key]`, which must be there ("is required").
  const json& member(const json& j, const std::string& path, const char* key) const;
  /// A finite number.
  double number(const json& j, const std::string& path) const;

 private:
  std::string name_;
  JsonRaise raise_;
};

}  // namespace hgd
