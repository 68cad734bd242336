// Scenario files (the format: docs/scenario.md): which parts of a shape are handles and how the
// manipulated one moves. One parser, used by the CLI, the batch runner and the viewer alike.
#pragma once

#include <Eigen/Core>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "hgdeform/interp/blend.h"

namespace hgd {

/// A scenario that does not parse or does not fit its shape. what() reads
/// "<file>: <json path>: <problem>", e.g. "s.json: /fixed/1/sphere/radius: must be a positive number".
class ScenarioError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A region of a shape: a sphere, an axis-aligned box, a cylinder (a segment and a radius,
/// flat caps), explicit point indices (file order), or the points whose per-point field has a
/// value (`equals`) or lies in a range (`field_min` .. `field_max`, inclusive; an absent bound
/// is infinite).
struct Region {
  enum class Kind { Sphere, Box, Indices, Cylinder, Field };
  Kind kind = Kind::Indices;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  // sphere (the file's "center")
  double radius = 0;                                 // sphere, cylinder
  Eigen::Vector3d min = Eigen::Vector3d::Zero();     // box
  Eigen::Vector3d max = Eigen::Vector3d::Zero();     // box
  std::vector<long long> indices;                    // indices
  Eigen::Vector3d start = Eigen::Vector3d::Zero();   // cylinder: the axis from start ...
  Eigen::Vector3d end = Eigen::Vector3d::Zero();     // ... to end
  std::string field_name;                            // field
  std::optional<double> equals;                      // field: this value, or else the range:
  double field_min = -std::numeric_limits<double>::infinity();
  double field_max = std::numeric_limits<double>::infinity();
  std::string json_path;  // where it was read, e.g. "/fixed/0"

  static Region sphere(const Eigen::Vector3d& c, double r);
  static Region box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi);
  static Region fromIndices(std::vector<long long> idx);
  static Region cylinder(const Eigen::Vector3d& start, const Eigen::Vector3d& end, double r);
  /// Points whose field `name` equals `value` (for `rgb`/`rgba`: the packed colour as an
  /// integer, 0xRRGGBB / 0xAARRGGBB).
  static Region field(const std::string& name, double value);
  /// Points whose field `name` lies in [lo, hi]; pass -inf or +inf for a one-sided range.
  static Region fieldRange(const std::string& name, double lo, double hi);
};

/// Direct manipulation: the manipulated handle's point nearest `from` is dragged to `to`.
/// With `keep_orientation` the handle translates without turning (Deformer::translateHandle);
/// without it, the paper's drag: the handle follows by shape matching and may turn.
struct DragMove {
  Eigen::Vector3d from = Eigen::Vector3d::Zero();
  Eigen::Vector3d to = Eigen::Vector3d::Zero();
  bool keep_orientation = false;
};

/// Frame metaphor: the manipulated handle gets this rigid motion exactly:
/// x -> R(axis, degrees) (x - centre) + centre + translate; centre defaults to the handle's
/// barycentre.
struct FrameMove {
  Eigen::Vector3d translate = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
  double degrees = 0;
  std::optional<Eigen::Vector3d> centre;  ///< the file's "center" (JSON keys keep the spec's spelling)
};

struct Move {
  enum class Kind { Drag, Frame };
  Kind kind = Kind::Drag;
  DragMove drag;
  FrameMove frame;
};

struct Scenario {
  std::vector<Region> fixed;
  Region manipulated;
  std::vector<Region> joints;
  std::optional<int> clusters;
  /// Linear (the paper's eq. 1) or Rotation (rotation-aware); absent: the tool's default.
  std::optional<Blend> blend;
  /// "resolution": "full" keeps every point in the field's graph however many there are
  /// (DeformOptions::multires_above = 0); "auto" or absent: the tool's default.
  std::optional<bool> full_resolution;
  std::vector<Move> moves;  // applied in order; empty = no move
  std::string path;         // file it came from (for messages)

  // Building a scenario in code, without JSON:
  //   hgd::Scenario s;
  //   s.fix(hgd::Region::box(lo, hi)).manipulate(hgd::Region::sphere(c, r)).drag(from, to);
  Scenario& fix(Region region);         ///< adds a fixed handle
  Scenario& manipulate(Region region);  ///< sets the manipulated handle
  Scenario& joint(Region region);       ///< adds a joint (a bone between two handles' clusters)
  /// Adds a drag: the manipulated handle's point nearest `from` is dragged to `to`.
  Scenario& drag(const Eigen::Vector3d& from, const Eigen::Vector3d& to, bool keep_orientation = false);
  Scenario& frame(const FrameMove& move);  ///< adds a frame move
};

/// Parses scenario JSON text. `name` is used in messages (a file name).
Scenario parseScenario(const std::string& json_text, const std::string& name);

/// Reads and parses a scenario file.
Scenario readScenario(const std::string& path);

/// Serialises a scenario as hgdeform-scenario/1 JSON (what the viewer saves).
std::string scenarioToJson(const Scenario& scenario);

}  // namespace hgd
