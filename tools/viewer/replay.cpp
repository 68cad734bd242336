#include "replay.h"

#include <cmath>
#include <initializer_list>

#include "app/json_reader.h"
#include "hgdeform/io/io.h"

namespace hgdview {

namespace {

using nlohmann::json;

/// Coordinates of a real shape (as scenarios allow), and pixels of a real window: beyond these
/// the arithmetic, and the conversion to integer pixels, would overflow.
constexpr double kMaxCoordinate = 1e15;
constexpr double kMaxPixel = 1e6;
constexpr unsigned kMaxSteps = 10000;
constexpr std::uintmax_t kMaxReplayBytes = std::uintmax_t{1} << 26;

constexpr const char* kEvents = "key, radius, pick, area, drag, view, screenshot, save, save_scenario";

[[noreturn]] void raiseReplayError(const std::string& message) {
  throw ReplayError(message);
}

struct Parser : hgd::JsonReader {
  using JsonReader::JsonReader;

  double positive(const json& j, const std::string& path) const {
    const double v = number(j, path);
    if (!(v > 0) || v > kMaxCoordinate) fail(path, "must be a positive number (at most 1e15)");
    return v;
  }

  std::string text(const json& j, const std::string& path) const {
    if (!j.is_string() || j.get_ref<const std::string&>().empty()) fail(path, "must be a non-empty string");
    const std::string& s = j.get_ref<const std::string&>();
    if (s.find('\0') != std::string::npos) fail(path, "must not contain a NUL character");
    return s;
  }

  /// `n` numbers each within `limit`: world coordinates or pixels.
  Eigen::Vector4d numbers(const json& j, const std::string& path, std::size_t n, double limit,
                          const char* what) const {
    if (!j.is_array() || j.size() != n) fail(path, "must be an array of " + std::to_string(n) + " numbers");
    Eigen::Vector4d v = Eigen::Vector4d::Zero();
    for (std::size_t i = 0; i < n; ++i) {
      const std::string p = path + "/" + std::to_string(i);
      v[static_cast<Eigen::Index>(i)] = number(j[i], p);
      if (std::abs(v[static_cast<Eigen::Index>(i)]) > limit) fail(p, what);
    }
    return v;
  }

  ReplayPosition world(const json& j, const std::string& path) const {
    ReplayPosition r;
    r.world = true;
    r.at = numbers(j, path, 3, kMaxCoordinate, "must be a coordinate between -1e15 and 1e15").head<3>();
    return r;
  }

  ReplayPosition screen(double x, double y) const {
    ReplayPosition r;
    r.world = false;
    r.at = {x, y, 0};
    return r;
  }

  Eigen::Vector4d pixels(const json& j, const std::string& path, std::size_t n) const {
    return numbers(j, path, n, kMaxPixel, "must be a pixel coordinate between -1e6 and 1e6");
  }

  /// {"world": [x, y, z]} or {"screen": [x, y]}; `keys` are the keys the object may have.
  ReplayPosition position(const json& j, const std::string& path,
                          std::initializer_list<const char*> keys = {"world", "screen"}) const {
    objectWith(j, path, keys);
    const bool w = j.contains("world"), s = j.contains("screen");
    if (w == s) fail(path, "must have exactly one of: world, screen");
    if (w) return world(j["world"], path + "/world");
    const Eigen::Vector4d p = pixels(j["screen"], path + "/screen", 2);
    return screen(p[0], p[1]);
  }

  ReplayEvent event(const json& j, const std::string& path) const {
    objectWith(j, path,
               {"key", "radius", "pick", "area", "drag", "view", "screenshot", "save", "save_scenario"});
    if (j.size() != 1) fail(path, std::string("an event must have exactly one of: ") + kEvents);
    ReplayEvent e;
    e.path = path;
    const std::string key = j.begin().key(), p = path + hgd::jsonPointerStep(key);
    const json& v = j.begin().value();
    if (key == "key") {
      e.kind = ReplayEvent::Kind::Key;
      e.text = text(v, p);
    } else if (key == "radius") {
      e.kind = ReplayEvent::Kind::Radius;
      e.radius = positive(v, p);
    } else if (key == "pick") {
      e.kind = ReplayEvent::Kind::Pick;
      e.from = position(v, p, {"world", "screen", "radius"});
      if (v.contains("radius")) {
        e.has_radius = true;
        e.radius = positive(v["radius"], p + "/radius");
      }
    } else if (key == "area") {
      e.kind = ReplayEvent::Kind::Area;
      objectWith(v, p, {"screen", "from", "to"});
      if (v.contains("screen")) {
        if (v.contains("from") || v.contains("to"))
          fail(p, "must have either \"screen\" or \"from\" and \"to\", not both");
        const Eigen::Vector4d r = pixels(v["screen"], p + "/screen", 4);
        e.from = screen(r[0], r[1]);
        e.to = screen(r[2], r[3]);
      } else {
        if (v.empty()) fail(p, "needs \"screen\": [x0, y0, x1, y1] or \"from\" and \"to\": [x, y, z]");
        e.from = world(member(v, p, "from"), p + "/from");
        e.to = world(member(v, p, "to"), p + "/to");
      }
    } else if (key == "drag") {
      e.kind = ReplayEvent::Kind::Drag;
      objectWith(v, p, {"from", "to", "steps"});
      e.from = position(member(v, p, "from"), p + "/from");
      e.to = position(member(v, p, "to"), p + "/to");
      if (v.contains("steps")) {
        const json& s = v["steps"];
        // Non-negative integers parse as unsigned, negative ones as signed.
        const bool ok = s.is_number_unsigned()
                            ? s.get<unsigned long long>() >= 1 && s.get<unsigned long long>() <= kMaxSteps
                        : s.is_number_integer() ? s.get<long long>() >= 1 && s.get<long long>() <= kMaxSteps
                                                : false;
        if (!ok) fail(p + "/steps", "must be an integer from 1 to " + std::to_string(kMaxSteps));
        e.steps = s.get<int>();
      }
    } else if (key == "view") {
      e.kind = ReplayEvent::Kind::View;
      const std::string name = text(v, p);
      if (name == "colours")
        e.view = 0;
      else if (name == "field")
        e.view = 1;
      else if (name == "clusters")
        e.view = 2;
      else
        fail(p, "must be \"colours\", \"field\" or \"clusters\"");
    } else {
      e.kind = key == "screenshot" ? ReplayEvent::Kind::Screenshot
               : key == "save"     ? ReplayEvent::Kind::Save
                                   : ReplayEvent::Kind::SaveScenario;
      e.text = text(v, p);
    }
    return e;
  }
};

}  // namespace

const char* eventName(ReplayEvent::Kind kind) {
  switch (kind) {
    case ReplayEvent::Kind::Key: return "key";
    case ReplayEvent::Kind::Radius: return "radius";
    case ReplayEvent::Kind::Pick: return "pick";
    case ReplayEvent::Kind::Area: return "area";
    case ReplayEvent::Kind::Drag: return "drag";
    case ReplayEvent::Kind::View: return "view";
    case ReplayEvent::Kind::Screenshot: return "screenshot";
    case ReplayEvent::Kind::Save: return "save";
    case ReplayEvent::Kind::SaveScenario: return "save_scenario";
  }
  return "?";
}

const std::string* outputOf(const ReplayEvent& e) {
  const bool writes = e.kind == ReplayEvent::Kind::Screenshot || e.kind == ReplayEvent::Kind::Save ||
                      e.kind == ReplayEvent::Kind::SaveScenario;
  return writes ? &e.text : nullptr;
}

std::vector<ReplayEvent> parseReplay(const std::string& json_text, const std::string& name) {
  const Parser p(name, raiseReplayError);
  const json j = p.parse(json_text);
  // {"events": [...]} or, as the first replay files were, the bare array.
  std::string base;
  const json* events = &j;
  if (j.is_object()) {
    p.onlyKeys(j, "", {"events"});
    events = &p.member(j, "", "events");
    base = "/events";
  }
  if (!events->is_array())
    p.fail(base, j.is_object() ? "must be an array of events"
                               : "must be an object {\"events\": [...]} (or an array of events)");
  std::vector<ReplayEvent> out;
  out.reserve(events->size());
  for (std::size_t i = 0; i < events->size(); ++i)
    out.push_back(p.event((*events)[i], base + "/" + std::to_string(i)));
  return out;
}

std::vector<ReplayEvent> readReplay(const std::string& path) {
  return parseReplay(hgd::readJsonFile(path, "replay", kMaxReplayBytes, raiseReplayError), path);
}

void refuseInputsAsOutputs(const std::vector<ReplayEvent>& events, const std::string& name,
                           const std::vector<std::string>& inputs) {
  for (const ReplayEvent& e : events)
    if (const std::string* out = outputOf(e)) {
      try {
        hgd::refuseInputs(*out, inputs);
      } catch (const std::exception& ex) {
        throw ReplayError(name + ": " + e.path + "/" + eventName(e.kind) + ": " + ex.what());
      }
    }
}

}  // namespace hgdview
