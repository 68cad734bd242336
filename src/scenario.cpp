#include "hgdeform/scenario.h"

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

namespace hgd {

Region Region::sphere(const Eigen::Vector3d& c, double r) {
  Region reg;
  reg.kind = Kind::Sphere;
  reg.center = c;
  reg.radius = r;
  return reg;
}

Region Region::box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  Region reg;
  reg.kind = Kind::Box;
  reg.min = lo;
  reg.max = hi;
  return reg;
}

Region Region::fromIndices(std::vector<long long> idx) {
  Region reg;
  reg.kind = Kind::Indices;
  reg.indices = std::move(idx);
  return reg;
}

namespace {

using nlohmann::json;

constexpr const char* kFormat = "hgdeform-scenario/1";

struct Parser {
  std::string name;

  [[noreturn]] void fail(const std::string& path, const std::string& what) const {
    throw ScenarioError(name + ": " + (path.empty() ? "/" : path) + ": " + what);
  }

  void onlyKeys(const json& j, const std::string& path, std::initializer_list<const char*> keys) const {
    for (auto it = j.begin(); it != j.end(); ++it) {
      bool known = false;
      for (const char* k : keys) known = known || it.key() == k;
      if (!known) {
        std::string list;
        for (const char* k : keys) list += std::string(list.empty() ? "" : ", ") + k;
        fail(path + "/" + it.key(), "unknown key (expected one of: " + list + ")");
      }
    }
  }

  const json& object(const json& j, const std::string& path) const {
    if (!j.is_object()) fail(path, "must be an object");
    return j;
  }

  double number(const json& j, const std::string& path) const {
    if (!j.is_number()) fail(path, "must be a number");
    const double v = j.get<double>();
    if (!std::isfinite(v)) fail(path, "must be a finite number");
    return v;
  }

  Eigen::Vector3d vec3(const json& j, const std::string& path) const {
    if (!j.is_array() || j.size() != 3) fail(path, "must be an array of 3 numbers");
    Eigen::Vector3d v;
    for (int i = 0; i < 3; ++i) v[i] = number(j[i], path + "/" + std::to_string(i));
    return v;
  }

  const json& member(const json& j, const std::string& path, const char* key) const {
    auto it = j.find(key);
    if (it == j.end()) fail(path + "/" + key, "is required");
    return *it;
  }

  Region region(const json& j, const std::string& path) const {
    object(j, path);
    if (j.size() != 1) fail(path, "a region must have exactly one of: sphere, box, indices");
    Region r;
    r.json_path = path;
    if (j.contains("sphere")) {
      const std::string p = path + "/sphere";
      const json& s = object(j["sphere"], p);
      onlyKeys(s, p, {"center", "radius"});
      r.kind = Region::Kind::Sphere;
      r.center = vec3(member(s, p, "center"), p + "/center");
      r.radius = number(member(s, p, "radius"), p + "/radius");
      if (!(r.radius > 0)) fail(p + "/radius", "must be a positive number");
    } else if (j.contains("box")) {
      const std::string p = path + "/box";
      const json& b = object(j["box"], p);
      onlyKeys(b, p, {"min", "max"});
      r.kind = Region::Kind::Box;
      r.min = vec3(member(b, p, "min"), p + "/min");
      r.max = vec3(member(b, p, "max"), p + "/max");
      for (int i = 0; i < 3; ++i)
        if (r.min[i] > r.max[i]) fail(p + "/min/" + std::to_string(i), "must not exceed max");
    } else if (j.contains("indices")) {
      const std::string p = path + "/indices";
      const json& a = j["indices"];
      if (!a.is_array() || a.empty()) fail(p, "must be a non-empty array of point indices");
      r.kind = Region::Kind::Indices;
      r.indices.reserve(a.size());
      for (std::size_t i = 0; i < a.size(); ++i) {
        if (!a[i].is_number_integer() || a[i].get<long long>() < 0)
          fail(p + "/" + std::to_string(i), "must be a non-negative integer");
        r.indices.push_back(a[i].get<long long>());
      }
    } else {
      fail(path + "/" + j.begin().key(), "unknown region kind (expected sphere, box or indices)");
    }
    return r;
  }

  void moves(const json& j, const std::string& path, std::vector<Move>& out) const {
    if (j.is_array()) {
      if (j.empty()) fail(path, "a list of moves must not be empty");
      for (std::size_t i = 0; i < j.size(); ++i) moves(j[i], path + "/" + std::to_string(i), out);
      return;
    }
    object(j, path);
    if (j.size() != 1) fail(path, "a move must have exactly one of: drag, frame");
    Move m;
    if (j.contains("drag")) {
      const std::string p = path + "/drag";
      const json& d = object(j["drag"], p);
      onlyKeys(d, p, {"from", "to"});
      m.kind = Move::Kind::Drag;
      m.drag.from = vec3(member(d, p, "from"), p + "/from");
      m.drag.to = vec3(member(d, p, "to"), p + "/to");
    } else if (j.contains("frame")) {
      const std::string p = path + "/frame";
      const json& f = object(j["frame"], p);
      onlyKeys(f, p, {"translate", "rotate"});
      m.kind = Move::Kind::Frame;
      if (f.contains("translate")) m.frame.translate = vec3(f["translate"], p + "/translate");
      if (f.contains("rotate")) {
        const std::string q = p + "/rotate";
        const json& r = object(f["rotate"], q);
        onlyKeys(r, q, {"axis", "degrees", "center"});
        m.frame.axis = vec3(member(r, q, "axis"), q + "/axis");
        if (m.frame.axis.norm() == 0) fail(q + "/axis", "must not be the zero vector");
        m.frame.degrees = number(member(r, q, "degrees"), q + "/degrees");
        if (r.contains("center")) m.frame.center = vec3(r["center"], q + "/center");
      }
      if (!f.contains("translate") && !f.contains("rotate")) fail(p, "needs translate and/or rotate");
    } else {
      fail(path + "/" + j.begin().key(), "unknown move (expected drag or frame)");
    }
    out.push_back(m);
  }
};

}  // namespace

Scenario parseScenario(const std::string& json_text, const std::string& name) {
  Parser p{name};
  json j;
  try {
    j = json::parse(json_text);
  } catch (const json::parse_error& e) {
    // nlohmann's message includes the byte position; keep it.
    throw ScenarioError(name + ": invalid JSON: " + e.what());
  }
  p.object(j, "");
  p.onlyKeys(j, "", {"format", "fixed", "manipulated", "joints", "clusters", "move"});
  Scenario s;
  s.path = name;
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
    if (!c.is_number_integer() || c.get<long long>() < 1 || c.get<long long>() > 1000)
      p.fail("/clusters", "must be an integer from 1 to 1000");
    s.clusters = c.get<int>();
  }
  if (j.contains("move")) p.moves(j["move"], "/move", s.moves);
  return s;
}

Scenario readScenario(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ScenarioError(path + ": cannot open scenario file");
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw ScenarioError(path + ": cannot read scenario file");
  return parseScenario(ss.str(), path);
}

namespace {
nlohmann::json regionJson(const Region& r) {
  using nlohmann::json;
  auto v = [](const Eigen::Vector3d& x) { return json::array({x[0], x[1], x[2]}); };
  switch (r.kind) {
    case Region::Kind::Sphere: return {{"sphere", {{"center", v(r.center)}, {"radius", r.radius}}}};
    case Region::Kind::Box: return {{"box", {{"min", v(r.min)}, {"max", v(r.max)}}}};
    case Region::Kind::Indices: return {{"indices", r.indices}};
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
  if (!s.moves.empty()) {
    json moves = json::array();
    for (const auto& m : s.moves) {
      if (m.kind == Move::Kind::Drag) {
        moves.push_back({{"drag", {{"from", v(m.drag.from)}, {"to", v(m.drag.to)}}}});
      } else {
        json f;
        f["translate"] = v(m.frame.translate);
        if (m.frame.degrees != 0) {
          f["rotate"] = {{"axis", v(m.frame.axis)}, {"degrees", m.frame.degrees}};
          if (m.frame.center) f["rotate"]["center"] = v(*m.frame.center);
        }
        moves.push_back({{"frame", f}});
      }
    }
    j["move"] = moves.size() == 1 ? moves[0] : moves;
  }
  return j.dump(2) + "\n";
}

}  // namespace hgd
