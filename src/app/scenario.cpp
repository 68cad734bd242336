#include "hgdeform/app/scenario.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cfloat>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>

namespace hgd {

Region Region::sphere(const Eigen::Vector3d& c, double r) {
  Region reg;
  reg.kind = Kind::Sphere;
  reg.centre = c;
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

Region Region::cylinder(const Eigen::Vector3d& start, const Eigen::Vector3d& end, double r) {
  Region reg;
  reg.kind = Kind::Cylinder;
  reg.start = start;
  reg.end = end;
  reg.radius = r;
  return reg;
}

Region Region::field(const std::string& name, double value) {
  Region reg;
  reg.kind = Kind::Field;
  reg.field_name = name;
  reg.equals = value;
  return reg;
}

Region Region::fieldRange(const std::string& name, double lo, double hi) {
  Region reg;
  reg.kind = Kind::Field;
  reg.field_name = name;
  reg.field_min = lo;
  reg.field_max = hi;
  return reg;
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

std::string jsonPointerStep(const std::string& key) {
  std::string out = "/";
  for (const char ch : key) {
    const auto c = static_cast<unsigned char>(ch);
    if (ch == '~') {
      out += "~0";
    } else if (ch == '/') {
      out += "~1";
    } else if (c < 0x20 || c == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", c);
      out += buf;
    } else {
      out += ch;
    }
  }
  return out;
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

/// Rejects duplicated keys while parsing (the last one would silently win otherwise), naming
/// the JSON path of the second occurrence.
class DuplicateKeyCheck {
 public:
  explicit DuplicateKeyCheck(std::string name) : name_(std::move(name)) {}

  bool operator()(int /*depth*/, nlohmann::json::parse_event_t event, nlohmann::json& parsed) {
    using E = nlohmann::json::parse_event_t;
    switch (event) {
      case E::object_start: frames_.push_back({false, 0, {}, {}}); break;
      case E::array_start: frames_.push_back({true, 0, {}, {}}); break;
      case E::key: {
        Frame& f = frames_.back();
        f.key = parsed.get<std::string>();
        if (!f.keys.insert(f.key).second) throw ScenarioError(name_ + ": " + path() + ": duplicate key");
        break;
      }
      case E::object_end:
      case E::array_end:
        frames_.pop_back();
        completed();
        break;
      case E::value: completed(); break;
    }
    return true;
  }

 private:
  struct Frame {
    bool array;
    std::size_t index;
    std::string key;
    std::set<std::string> keys;
  };
  void completed() {
    if (!frames_.empty() && frames_.back().array) ++frames_.back().index;
  }
  std::string path() const {
    std::string p;
    for (const Frame& f : frames_) p += f.array ? "/" + std::to_string(f.index) : jsonPointerStep(f.key);
    return p;
  }
  std::string name_;
  std::vector<Frame> frames_;
};

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
        fail(path + jsonPointerStep(it.key()), "unknown key (expected one of: " + list + ")");
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

  /// A position or displacement of a move: finite and of a magnitude real shapes have.
  Eigen::Vector3d coordinates(const json& j, const std::string& path) const {
    const Eigen::Vector3d v = vec3(j, path);
    for (int i = 0; i < 3; ++i)
      if (std::abs(v[i]) > kMaxCoordinate)
        fail(path + "/" + std::to_string(i), "must be a coordinate between -1e15 and 1e15");
    return v;
  }

  const json& member(const json& j, const std::string& path, const char* key) const {
    auto it = j.find(key);
    if (it == j.end()) fail(path + jsonPointerStep(key), "is required");
    return *it;
  }

  Region region(const json& j, const std::string& path) const {
    object(j, path);
    if (j.size() != 1) fail(path, "a region must have exactly one of: sphere, box, cylinder, field, indices");
    Region r;
    r.json_path = path;
    if (j.contains("sphere")) {
      const std::string p = path + "/sphere";
      const json& s = object(j["sphere"], p);
      onlyKeys(s, p, {"center", "radius"});
      r.kind = Region::Kind::Sphere;
      r.centre = vec3(member(s, p, "center"), p + "/center");
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
        if (!a[i].is_number_integer() ||
            (a[i].is_number_unsigned() &&
             a[i].get<unsigned long long>() > static_cast<unsigned long long>(LLONG_MAX)) ||
            (!a[i].is_number_unsigned() && a[i].get<long long>() < 0))
          fail(p + "/" + std::to_string(i), "must be a non-negative integer (a point index)");
        r.indices.push_back(a[i].get<long long>());
      }
    } else if (j.contains("cylinder")) {
      const std::string p = path + "/cylinder";
      const json& c = object(j["cylinder"], p);
      onlyKeys(c, p, {"start", "end", "radius"});
      r.kind = Region::Kind::Cylinder;
      r.start = vec3(member(c, p, "start"), p + "/start");
      r.end = vec3(member(c, p, "end"), p + "/end");
      r.radius = number(member(c, p, "radius"), p + "/radius");
      if (!(r.radius > 0)) fail(p + "/radius", "must be a positive number");
      // Too short an axis has no direction (its squared length underflows): as good as none.
      if (!((r.end - r.start).squaredNorm() >= DBL_MIN)) fail(p + "/end", "must differ from start");
    } else if (j.contains("field")) {
      const std::string p = path + "/field";
      const json& f = object(j["field"], p);
      onlyKeys(f, p, {"name", "equals", "min", "max"});
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
      fail(path + jsonPointerStep(j.begin().key()),
           "unknown region kind (expected sphere, box, cylinder, field or indices)");
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
    if (j.contains("drag")) {
      const std::string p = path + "/drag";
      const json& d = object(j["drag"], p);
      onlyKeys(d, p, {"from", "to", "keep_orientation"});
      m.kind = Move::Kind::Drag;
      m.drag.from = coordinates(member(d, p, "from"), p + "/from");
      m.drag.to = coordinates(member(d, p, "to"), p + "/to");
      if (d.contains("keep_orientation")) {
        if (!d["keep_orientation"].is_boolean()) fail(p + "/keep_orientation", "must be true or false");
        m.drag.keep_orientation = d["keep_orientation"].get<bool>();
      }
    } else if (j.contains("frame")) {
      const std::string p = path + "/frame";
      const json& f = object(j["frame"], p);
      onlyKeys(f, p, {"translate", "rotate"});
      m.kind = Move::Kind::Frame;
      if (f.contains("translate")) m.frame.translate = coordinates(f["translate"], p + "/translate");
      if (f.contains("rotate")) {
        const std::string q = p + "/rotate";
        const json& r = object(f["rotate"], q);
        onlyKeys(r, q, {"axis", "degrees", "center"});
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
      fail(path + jsonPointerStep(j.begin().key()), "unknown move (expected drag or frame)");
    }
    out.push_back(m);
  }
};

}  // namespace

Scenario parseScenario(const std::string& json_text, const std::string& file_name) {
  // Text with no file behind it is named "scenario" in messages, never "": /clusters: ...".
  const std::string name = file_name.empty() ? "scenario" : file_name;
  Parser p{name};
  json j;
  try {
    j = json::parse(json_text, DuplicateKeyCheck(name));
  } catch (const json::exception& e) {
    // Syntax errors and numbers out of range (1e400). nlohmann's message includes the byte
    // position; keep it.
    throw ScenarioError(name + ": invalid JSON: " + e.what());
  }
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
  struct Closer {
    void operator()(std::FILE* f) const { std::fclose(f); }
  };
  // Non-blocking, so that a FIFO given as the scenario is refused instead of waiting for a writer.
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) throw ScenarioError(path + ": cannot open scenario file: " + std::strerror(errno));
  std::unique_ptr<std::FILE, Closer> file(::fdopen(fd, "rb"));
  if (!file) {
    const int e = errno;
    ::close(fd);
    throw ScenarioError(path + ": cannot open scenario file: " + std::strerror(e));
  }
  struct stat st {};
  if (::fstat(::fileno(file.get()), &st) != 0)
    throw ScenarioError(path + ": cannot open scenario file: " + std::strerror(errno));
  if (S_ISDIR(st.st_mode))
    throw ScenarioError(path + ": cannot open scenario file: " + std::strerror(EISDIR));
  if (!S_ISREG(st.st_mode)) throw ScenarioError(path + ": cannot open scenario file: not a regular file");
  if (st.st_size == 0) throw ScenarioError(path + ": empty file");
  const auto size = static_cast<std::uintmax_t>(st.st_size);
  if (size > kMaxScenarioBytes)
    throw ScenarioError(path + ": file too large for a scenario (" + std::to_string(size) + " bytes)");
  std::string text(static_cast<std::size_t>(size), '\0');
  if (std::fread(text.data(), 1, text.size(), file.get()) != text.size())
    throw ScenarioError(
        path + ": cannot read scenario file: " +
        (std::ferror(file.get()) ? std::strerror(errno) : "the file shrank while being read"));
  return parseScenario(text, path);
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
