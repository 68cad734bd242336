#include "hgdeform/app/scenario.h"

#include <cfloat>
#include <climits>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>

#include "app/json_reader.h"

namespace hgd {

namespace {
/// A region of `kind` with what `set` gives it.
template <class Set>
Region makeRegion(Region::Kind kind, const Set& set) {
  Region reg;
  reg.kind = kind;
  set(reg);
  return reg;
}
}  // namespace

Region Region::sphere(const Eigen::Vector3d& c, double r) {
  return makeRegion(Kind::Sphere, [&](Region& g) {
    g.centre = c;
    g.radius = r;
  });
}

Region Region::box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  return makeRegion(Kind::Box, [&](Region& g) {
    g.min = lo;
    g.max = hi;
  });
}

Region Region::fromIndices(std::vector<long long> idx) {
  return makeRegion(Kind::Indices, [&](Region& g) { g.indices = std::move(idx); });
}

Region Region::cylinder(const Eigen::Vector3d& start, const Eigen::Vector3d& end, double r) {
  return makeRegion(Kind::Cylinder, [&](Region& g) {
    g.start = start;
    g.end = end;
    g.radius = r;
  });
}

Region Region::field(const std::string& name, double value) {
  return makeRegion(Kind::Field, [&](Region& g) {
    g.field_name = name;
    g.equals = value;
  });
}

Region Region::fieldRange(const std::string& name, double lo, double hi) {
  return makeRegion(Kind::Field, [&](Region& g) {
    g.field_name = name;
    g.field_min = lo;
    g.field_max = hi;
  });
}

const char* blendName(Blend blend) {
  return blend == Blend::Linear ? "linear" : "rotation";
}

bool parseBlend(const std::string& text, Blend& blend) {
  if (text == "linear")
    blend = Blend::Linear;
  else if (text == "rotation")
    blend = Blend::Rotation;
  else
    return false;
  return true;
}

// In-code scenarios name their regions as a file would, so that errors read the same.
Scenario& Scenario::fix(Region region) {
  if (region.json_path.empty()) region.json_path = "/fixed/" + std::to_string(fixed.size());
  fixed.push_back(std::move(region));
  return *this;
}

Scenario& Scenario::manipulate(Region region) {
  if (region.json_path.empty()) region.json_path = "/manipulated";
  manipulated = std::move(region);
  return *this;
}

Scenario& Scenario::joint(Region region) {
  if (region.json_path.empty()) region.json_path = "/joints/" + std::to_string(joints.size());
  joints.push_back(std::move(region));
  return *this;
}

Scenario& Scenario::drag(const Eigen::Vector3d& from, const Eigen::Vector3d& to, bool keep_orientation) {
  Move m;
  m.kind = Move::Kind::Drag;
  m.drag.from = from;
  m.drag.to = to;
  m.drag.keep_orientation = keep_orientation;
  moves.push_back(m);
  return *this;
}

Scenario& Scenario::frame(const FrameMove& move) {
  Move m;
  m.kind = Move::Kind::Frame;
  m.frame = move;
  moves.push_back(m);
  return *this;
}

namespace {

using nlohmann::json;

constexpr const char* kFormat = "hgdeform-scenario/1";
/// Lists of moves may nest (a list is a move); deeper than this is no scenario anyone wrote.
constexpr int kMaxMoveDepth = 32;
/// Positions and translations beyond this are not coordinates of a real shape (and would
/// overflow the solver's arithmetic).
constexpr double kMaxCoordinate = 1e15;
constexpr double kMaxDegrees = 1e6;
constexpr std::uintmax_t kMaxScenarioBytes = std::uintmax_t{1} << 30;

[[noreturn]] void raiseScenarioError(const std::string& message) {
  throw ScenarioError(message);
}

struct Parser : JsonReader {
  using JsonReader::JsonReader;

  Eigen::Vector3d vec3(const json& j, const std::string& path) const {
    if (!j.is_array() || j.size() != 3) fail(path, "must be an array of 3 numbers");
    Eigen::Vector3d v;
    for (int i = 0; i < 3; ++i) v[i] = number(j[i], path + "/" + std::to_string(i));
    return v;
  }

  /// A position or displacement of a move: finite and of a magnitude real shapes have.
  Eigen::Vector3d coordinates(const json& j, const std::string& path) const {
    const Eigen::Vector3d v = vec3(j, path);
    for (int i = 0; i < 3; ++i)
      if (std::abs(v[i]) > kMaxCoordinate)
        fail(path + "/" + std::to_string(i), "must be a coordinate between -1e15 and 1e15");
    return v;
  }

  Region region(const json& j, const std::string& path) const {
    object(j, path);
    if (j.size() != 1) fail(path, "a region must have exactly one of: sphere, box, cylinder, field, indices");
    Region r;
    r.json_path = path;
    // The one key names the kind; its value is the region's body.
    const std::string kind = j.begin().key(), p = path + jsonPointerStep(kind);
    const json& v = j.begin().value();
    if (kind == "sphere") {
      const json& s = objectWith(v, p, {"center", "radius"});
      r.kind = Region::Kind::Sphere;
      r.centre = vec3(member(s, p, "center"), p + "/center");
      r.radius = number(member(s, p, "radius"), p + "/radius");
      if (!(r.radius > 0)) fail(p + "/radius", "must be a positive number");
    } else if (kind == "box") {
      const json& b = objectWith(v, p, {"min", "max"});
      r.kind = Region::Kind::Box;
      r.min = vec3(member(b, p, "min"), p + "/min");
      r.max = vec3(member(b, p, "max"), p + "/max");
      for (int i = 0; i < 3; ++i)
        if (r.min[i] > r.max[i]) fail(p + "/min/" + std::to_string(i), "must not exceed max");
    } else if (kind == "indices") {
      const json& a = v;  // an array
      if (!a.is_array() || a.empty()) fail(p, "must be a non-empty array of point indices");
      r.kind = Region::Kind::Indices;
      r.indices.reserve(a.size());
      for (std::size_t i = 0; i < a.size(); ++i) {
        if (!a[i].is_number_integer() ||
            (a[i].is_number_unsigned() &&
             a[i].get<unsigned long long>() > static_cast<unsigned long long>(LLONG_MAX)) ||
            (!a[i].is_number_unsigned() && a[i].get<long long>() < 0))
          fail(p + "/" + std::to_string(i), "must be a non-negative integer (a point index)");
        r.indices.push_back(a[i].get<long long>());
      }
    } else if (kind == "cylinder") {
      const json& c = objectWith(v, p, {"start", "end", "radius"});
      r.kind = Region::Kind::Cylinder;
      r.start = vec3(member(c, p, "start"), p + "/start");
      r.end = vec3(member(c, p, "end"), p + "/end");
      r.radius = number(member(c, p, "radius"), p + "/radius");
      if (!(r.radius > 0)) fail(p + "/radius", "must be a positive number");
      // Too short an axis has no direction (its squared length underflows): as good as none.
      if (!((r.end - r.start).squaredNorm() >= DBL_MIN)) fail(p + "/end", "must differ from start");
    } else if (kind == "field") {
      const json& f = objectWith(v, p, {"name", "equals", "min", "max"});
      r.kind = Region::Kind::Field;
      const json& n = member(f, p, "name");
      if (!n.is_string() || n.get<std::string>().empty()) fail(p + "/name", "must be a field name");
      r.field_name = n.get<std::string>();
      const bool range = f.contains("min") || f.contains("max");
      if (f.contains("equals") && range)
        fail(p + (f.contains("min") ? "/min" : "/max"), "cannot go with equals (one value, or a range)");
      if (!f.contains("equals") && !range) fail(p, "needs equals, or min and/or max");
      const bool packed = r.field_name == "rgb" || r.field_name == "rgba";
      if (packed && range)
        fail(p + (f.contains("min") ? "/min" : "/max"),
             "a packed colour (" + r.field_name + ") has no order: select one colour with equals");
      if (f.contains("equals")) {
        r.equals = number(f["equals"], p + "/equals");
        const double top = r.field_name == "rgb" ? 0xFFFFFF : 0xFFFFFFFF;
        if (packed && !(f["equals"].is_number_integer() && *r.equals >= 0 && *r.equals <= top))
          fail(p + "/equals", "must be the packed colour as an integer (" +
                                  std::string(r.field_name == "rgb" ? "0xRRGGBB" : "0xAARRGGBB") +
                                  ", from 0 to " + std::to_string(static_cast<unsigned long>(top)) + ")");
      }
      if (f.contains("min")) r.field_min = number(f["min"], p + "/min");
      if (f.contains("max")) r.field_max = number(f["max"], p + "/max");
      if (r.field_min > r.field_max) fail(p + "/min", "must not exceed max");
    } else {
      fail(p, "unknown region kind (expected sphere, box, cylinder, field or indices)");
    }
    return r;
  }

  void moves(const json& j, const std::string& path, std::vector<Move>& out, int depth = 0) const {
    if (j.is_array()) {
      if (j.empty()) fail(path, "a list of moves must not be empty");
      if (depth >= kMaxMoveDepth)
        fail(path, "lists of moves nested more than " + std::to_string(kMaxMoveDepth) + " deep");
      for (std::size_t i = 0; i < j.size(); ++i) moves(j[i], path + "/" + std::to_string(i), out, depth + 1);
      return;
    }
    object(j, path);
    if (j.size() != 1) fail(path, "a move must have exactly one of: drag, frame");
    Move m;
    const std::string kind = j.begin().key(), p = path + jsonPointerStep(kind);
    const json& v = j.begin().value();
    if (kind == "drag") {
      const json& d = objectWith(v, p, {"from", "to", "keep_orientation"});
      m.kind = Move::Kind::Drag;
      m.drag.from = coordinates(member(d, p, "from"), p + "/from");
      m.drag.to = coordinates(member(d, p, "to"), p + "/to");
      if (d.contains("keep_orientation")) {
        if (!d["keep_orientation"].is_boolean()) fail(p + "/keep_orientation", "must be true or false");
        m.drag.keep_orientation = d["keep_orientation"].get<bool>();
      }
    } else if (kind == "frame") {
      const json& f = objectWith(v, p, {"translate", "rotate"});
      m.kind = Move::Kind::Frame;
      if (f.contains("translate")) m.frame.translate = coordinates(f["translate"], p + "/translate");
      if (f.contains("rotate")) {
        const std::string q = p + "/rotate";
        const json& r = objectWith(f["rotate"], q, {"axis", "degrees", "center"});
        m.frame.axis = vec3(member(r, q, "axis"), q + "/axis");
        // Zero, or so small or large that its length under- or overflows: no direction.
        const double sq = m.frame.axis.squaredNorm();
        if (!(sq >= DBL_MIN && std::isfinite(sq)))
          fail(q + "/axis", m.frame.axis.isZero(0)
                                ? "must not be the zero vector"
                                : "must be a vector of moderate length (its length " +
                                      std::string(sq < 1 ? "underflows" : "overflows") + ")");
        m.frame.degrees = number(member(r, q, "degrees"), q + "/degrees");
        if (std::abs(m.frame.degrees) > kMaxDegrees) fail(q + "/degrees", "must be between -1e6 and 1e6");
        if (r.contains("center")) m.frame.centre = coordinates(r["center"], q + "/center");
      }
      if (!f.contains("translate") && !f.contains("rotate")) fail(p, "needs translate and/or rotate");
    } else {
      fail(p, "unknown move (expected drag or frame)");
    }
    out.push_back(m);
  }
};

}  // namespace

Scenario parseScenario(const std::string& json_text, const std::string& file_name) {
  // Text with no file behind it is named "scenario" in messages, never "": /clusters: ...".
  const std::string name = file_name.empty() ? "scenario" : file_name;
  const Parser p(name, raiseScenarioError);
  json j = p.parse(json_text);
  p.object(j, "");
  p.onlyKeys(j, "", {"format", "fixed", "manipulated", "joints", "clusters", "blend", "resolution", "move"});
  Scenario s;
  s.path = file_name;
  if (j.contains("format") && (!j["format"].is_string() || j["format"].get<std::string>() != kFormat))
    p.fail("/format", std::string("must be \"") + kFormat + "\"");
  const json& fixed = p.member(j, "", "fixed");
  if (!fixed.is_array() || fixed.empty()) p.fail("/fixed", "must be a non-empty array of regions");
  for (std::size_t i = 0; i < fixed.size(); ++i)
    s.fixed.push_back(p.region(fixed[i], "/fixed/" + std::to_string(i)));
  s.manipulated = p.region(p.member(j, "", "manipulated"), "/manipulated");
  if (j.contains("joints")) {
    const json& joints = j["joints"];
    if (!joints.is_array()) p.fail("/joints", "must be an array of regions");
    for (std::size_t i = 0; i < joints.size(); ++i)
      s.joints.push_back(p.region(joints[i], "/joints/" + std::to_string(i)));
  }
  if (j.contains("clusters")) {
    const json& c = j["clusters"];
    // A whole number however spelt: 12, 12.0 and 1.2e1 alike.
    const double v = c.is_number() ? c.get<double>() : 0;
    if (!c.is_number() || !(v >= 1 && v <= 1000) || v != std::floor(v))
      p.fail("/clusters", "must be an integer from 1 to 1000");
    s.clusters = static_cast<int>(v);
  }
  if (j.contains("blend")) {
    const json& b = j["blend"];
    Blend blend = Blend::Rotation;
    if (!b.is_string() || !parseBlend(b.get<std::string>(), blend))
      p.fail("/blend", "must be \"linear\" or \"rotation\"");
    s.blend = blend;
  }
  if (j.contains("resolution")) {
    const json& r = j["resolution"];
    if (!r.is_string() || (r.get<std::string>() != "auto" && r.get<std::string>() != "full"))
      p.fail("/resolution", "must be \"auto\" or \"full\"");
    s.full_resolution = r.get<std::string>() == "full";
  }
  if (j.contains("move")) p.moves(j["move"], "/move", s.moves);
  return s;
}

Scenario readScenario(const std::string& path) {
  return parseScenario(readJsonFile(path, "scenario", kMaxScenarioBytes, raiseScenarioError), path);
}

namespace {
nlohmann::json regionJson(const Region& r) {
  using nlohmann::json;
  auto v = [](const Eigen::Vector3d& x) { return json::array({x[0], x[1], x[2]}); };
  switch (r.kind) {
    case Region::Kind::Sphere: return {{"sphere", {{"center", v(r.centre)}, {"radius", r.radius}}}};
    case Region::Kind::Box: return {{"box", {{"min", v(r.min)}, {"max", v(r.max)}}}};
    case Region::Kind::Indices: return {{"indices", r.indices}};
    case Region::Kind::Cylinder:
      return {{"cylinder", {{"start", v(r.start)}, {"end", v(r.end)}, {"radius", r.radius}}}};
    case Region::Kind::Field: {
      json f = {{"name", r.field_name}};
      if (r.equals) {
        // Whole numbers as integers: labels and packed colours read back as they were written.
        const double e = *r.equals;
        if (e == std::floor(e) && std::abs(e) < 9007199254740992.0)
          f["equals"] = static_cast<long long>(e);
        else
          f["equals"] = e;
      } else {
        if (std::isfinite(r.field_min)) f["min"] = r.field_min;
        if (std::isfinite(r.field_max)) f["max"] = r.field_max;
        if (!f.contains("min") && !f.contains("max"))
          f["min"] = std::numeric_limits<double>::lowest();  // all
      }
      return {{"field", f}};
    }
  }
  return {};
}
}  // namespace

std::string scenarioToJson(const Scenario& s) {
  using nlohmann::json;
  auto v = [](const Eigen::Vector3d& x) { return json::array({x[0], x[1], x[2]}); };
  json j;
  j["format"] = kFormat;
  j["fixed"] = json::array();
  for (const auto& r : s.fixed) j["fixed"].push_back(regionJson(r));
  j["manipulated"] = regionJson(s.manipulated);
  if (!s.joints.empty()) {
    j["joints"] = json::array();
    for (const auto& r : s.joints) j["joints"].push_back(regionJson(r));
  }
  if (s.clusters) j["clusters"] = *s.clusters;
  if (s.blend) j["blend"] = blendName(*s.blend);
  if (s.full_resolution) j["resolution"] = *s.full_resolution ? "full" : "auto";
  if (!s.moves.empty()) {
    json moves = json::array();
    for (const auto& m : s.moves) {
      if (m.kind == Move::Kind::Drag) {
        json d = {{"from", v(m.drag.from)}, {"to", v(m.drag.to)}};
        if (m.drag.keep_orientation) d["keep_orientation"] = true;
        moves.push_back({{"drag", d}});
      } else {
        json f;
        f["translate"] = v(m.frame.translate);
        if (m.frame.degrees != 0) {
          f["rotate"] = {{"axis", v(m.frame.axis)}, {"degrees", m.frame.degrees}};
          if (m.frame.centre) f["rotate"]["center"] = v(*m.frame.centre);
        }
        moves.push_back({{"frame", f}});
      }
    }
    j["move"] = moves.size() == 1 ? moves[0] : moves;
  }
  return j.dump(2) + "\n";
}

}  // namespace hgd
