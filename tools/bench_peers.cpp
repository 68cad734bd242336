#include "bench_peers.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <vector>

#include "bench_references.h"
#include "hgdeform/io/io.h"
#include "support/arap.h"
#include "support/quality.h"
#include "support/shapes.h"

namespace hgdbench {

/// The Armadillo's handles: the feet fixed (the lowest 6% of its height), the top of the head
/// manipulated (the highest 8%).
hgd::Handles armadilloHandles(const hgd::Geometry& g) {
  hgd::Handles h;
  h.fixed.emplace_back();
  const Eigen::AlignedBox3f box = hgd::boundingBox(*g.points);
  const Eigen::Vector3d lo = box.min().cast<double>() + g.origin, hi = box.max().cast<double>() + g.origin;
  const double height = hi.y() - lo.y();
  for (std::size_t i = 0; i < g.size(); ++i) {
    const double y = g.world(i).y();
    if (y < lo.y() + 0.06 * height) h.fixed[0].push_back(static_cast<int>(i));
    if (y > hi.y() - 0.08 * height) h.manipulated.push_back(static_cast<int>(i));
  }
  return h;
}

namespace {

/// Distortion at the commit that set these figures (the quality rows' "reference" column): a
/// change that makes a shape more than 5% worse says so in the bench's output.
struct QualityReference {
  const char* name;
  double distortion;
};
const QualityReference kQualityReference[] = {{"armadillo", 0.01490}, {"quadruped", 0.01466}};

/// The opt-in mode closest to ARAP that the bench reports beside the default: 32 isovalues and
/// E_Prop reweighted over 8 rounds (docs/method.md, "Shape quality").
hgd::DeformOptions reweightedOptions() {
  hgd::DeformOptions o;
  o.clusters.isovalues = 32;
  o.gauss_newton.reweight_rounds = 8;
  return o;
}

/// The shape after a frame move of the handle by `move` with options `o`, and the move's ms.
std::vector<Eigen::Vector3d> movedShape(const hgd::Geometry& g, const hgd::Handles& h,
                                        const Eigen::Vector3d& move, const hgd::DeformOptions& o,
                                        double& move_ms) {
  hgd::Deformer d(g, h, o);
  const auto f0 = std::chrono::steady_clock::now();
  d.setHandleTransform(Eigen::Affine3d(Eigen::Translation3d(move)));
  move_ms = msSince(f0);
  std::vector<Eigen::Vector3d> out(g.size());
  for (std::size_t i = 0; i < g.size(); ++i) out[i] = d.deformedWorld(i);
  return out;
}

/// One quality case: hgdeform (default options, and the opt-in reweighted mode) and CGAL's ARAP
/// run to convergence on the same mesh, handles and rigid move (the handle translated by
/// `move`, exactly, in all). Local distortion (support/quality.h) of each, the mean motion of
/// `other` (a branch no handle is on) over the move's length, and the largest length change of
/// `parts` (limbs that should not stretch).
nlohmann::json qualityCase(const std::string& name, const hgd::Shape& shape, const hgd::Handles& h,
                           const Eigen::Vector3d& move, const std::vector<int>& other,
                           const std::vector<hgd::quality::Part>& parts) {
  const hgd::Geometry g = hgd::extractGeometry(shape);
  std::vector<Eigen::Vector3d> rest(g.size());
  for (std::size_t i = 0; i < g.size(); ++i) rest[i] = g.world(i);
  const auto t0 = std::chrono::steady_clock::now();
  hgd::Deformer d(g, h, hgd::DeformOptions{});
  const double build_ms = msSince(t0);
  const auto f0 = std::chrono::steady_clock::now();
  d.setHandleTransform(Eigen::Affine3d(Eigen::Translation3d(move)));
  const double move_ms = msSince(f0);
  std::vector<Eigen::Vector3d> ours(g.size());
  for (std::size_t i = 0; i < g.size(); ++i) ours[i] = d.deformedWorld(i);

  const std::vector<std::array<int, 3>> triangles = hgdbench::fanTriangles(g.faces);
  std::vector<int> fixed;
  for (const auto& region : h.fixed) fixed.insert(fixed.end(), region.begin(), region.end());
  // Converged for the measure reported: the distortion changes less than 0.5% over the last 50
  // iterations (ARAP's energy creeps on for thousands; the measure settles long before).
  const hgdbench::ArapResult arap = hgdbench::cgalArapConverged(
      rest, triangles, fixed, h.manipulated, move, 0, 800, 25, hgd::quality::distortionSettles(rest));
  const double ours_d = hgd::quality::localDistortion(rest, ours),
               arap_d = hgd::quality::localDistortion(rest, arap.positions);
  double reference = 0;
  for (const auto& r : kQualityReference)
    if (name == r.name) reference = r.distortion;
  nlohmann::json out = {{"case", name},
                        {"points", g.size()},
                        {"faces", triangles.size()},
                        {"clusters", d.clustering().clusters.size()},
                        {"hgdeform_distortion", ours_d},
                        {"arap_distortion", arap_d},
                        {"distortion_over_arap", ours_d / std::max(1e-12, arap_d)},
                        {"reference_distortion", reference},
                        {"over_reference", reference > 0 ? ours_d / reference : 0.0},
                        {"arap_iterations", arap.iterations},
                        {"arap_converged", arap.converged},
                        {"arap_ms", arap.ms},
                        {"hgdeform_build_ms", build_ms},
                        {"hgdeform_move_ms", move_ms}};
  double reweighted_ms = 0;
  const std::vector<Eigen::Vector3d> reweighted = movedShape(g, h, move, reweightedOptions(), reweighted_ms);
  const double reweighted_d = hgd::quality::localDistortion(rest, reweighted);
  out["reweighted_distortion"] = reweighted_d;
  out["reweighted_over_arap"] = reweighted_d / std::max(1e-12, arap_d);
  out["reweighted_move_ms"] = reweighted_ms;
  if (!other.empty()) {
    out["other_branch_points"] = other.size();
    out["hgdeform_other_branch"] = hgd::quality::meanDisplacement(rest, ours, other) / move.norm();
    out["arap_other_branch"] = hgd::quality::meanDisplacement(rest, arap.positions, other) / move.norm();
    out["reweighted_other_branch"] = hgd::quality::meanDisplacement(rest, reweighted, other) / move.norm();
  }
  if (!parts.empty()) {
    out["hgdeform_length_change"] = hgd::quality::largestLengthChange(rest, ours, parts);
    out["arap_length_change"] = hgd::quality::largestLengthChange(rest, arap.positions, parts);
    out["reweighted_length_change"] = hgd::quality::largestLengthChange(rest, reweighted, parts);
  }
  return out;
}

}  // namespace

/// The peer (issue: one frame against five iterations of CGAL's ARAP): the Armadillo mesh
/// itself, the same handles and drag for both; hgdeform's frame is solve + interpolation,
/// CGAL's is new targets + deform(5 iterations). Medians over the frames.
nlohmann::json runArap(const std::string& armadillo, int repeat) {
  const hgd::Shape shape = hgd::readShape(armadillo);
  const hgd::Geometry g = hgd::extractGeometry(shape);
  const hgd::Handles h = armadilloHandles(g);
  const int frames = 10;
  std::vector<double> ours, build, reweighted;
  for (int r = 0; r < std::max(1, repeat / 2); ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    hgd::Deformer d(g, h, hgd::DeformOptions{});
    build.push_back(msSince(t0));
    standardDrag(d, h, frames, [&](int, double ms, const hgd::SolveStats&) { ours.push_back(ms); });
    hgd::Deformer dr(g, h, reweightedOptions());
    standardDrag(dr, h, frames, [&](int, double ms, const hgd::SolveStats&) { reweighted.push_back(ms); });
  }
  std::vector<Eigen::Vector3d> points(g.size());
  for (std::size_t i = 0; i < g.size(); ++i) points[i] = g.world(i);
  const std::vector<std::array<int, 3>> triangles = hgdbench::fanTriangles(g.faces);
  const Eigen::AlignedBox3f box = hgd::boundingBox(*g.points);
  const Eigen::Vector3d move(0, 0, 0.1 * static_cast<double>((box.max() - box.min()).norm()));  // as the drag
  const hgdbench::ArapTimes arap =
      hgdbench::cgalArap(points, triangles, h.fixed[0], h.manipulated, move, frames, 5);
  const double ours_ms = median(ours), arap_ms = median(arap.frame_ms);
  return {{"points", g.size()},
          {"faces", arap.faces},
          {"faces_refused_by_cgal", arap.faces_refused},
          {"fixed", h.fixed[0].size()},
          {"manipulated", h.manipulated.size()},
          {"hgdeform_build_ms", median(build)},
          {"hgdeform_frame_ms", ours_ms},
          {"cgal_arap_preprocess_ms", arap.preprocess_ms},
          {"cgal_arap_5_iterations_ms", arap_ms},
          {"arap_over_frame", arap_ms / std::max(1e-9, ours_ms)},
          {"hgdeform_reweighted_frame_ms", median(reweighted)},
          {"arap_over_reweighted_frame", arap_ms / std::max(1e-9, median(reweighted))}};
}

/// The quality rows: the Armadillo (feet fixed, the top of the head moved up by a tenth of the
/// diagonal) when its file is there, and the procedural quadruped (three feet fixed, the right
/// hind foot moved back and up; the other hind shin is the branch that should stay).
nlohmann::json runQuality(const std::string& armadillo) {
  nlohmann::json rows = nlohmann::json::array();
  if (std::filesystem::exists(armadillo)) {
    const hgd::Shape shape = hgd::readShape(armadillo);
    const hgd::Geometry g = hgd::extractGeometry(shape);
    const hgd::Handles h = armadilloHandles(g);
    const Eigen::AlignedBox3f box = hgd::boundingBox(*g.points);
    rows.push_back(qualityCase(
        "armadillo", shape, h,
        Eigen::Vector3d(0, 0, 0.1 * static_cast<double>((box.max() - box.min()).norm())), {}, {}));
  }
  const hgd::Shape q = hgd::shapes::quadruped();
  const hgd::Geometry g = hgd::extractGeometry(q);
  const auto ours = [&](std::vector<int> file) {  // file order -> the Geometry's (Morton) order
    for (int& i : file) i = g.finite_index[static_cast<std::size_t>(i)];
    return file;
  };
  hgd::Handles h;
  std::vector<hgd::quality::Part> planted;  // the three fixed legs, foot to top
  for (const int leg : {0, 1, 3}) {
    h.fixed.push_back(ours(hgd::shapes::quadrupedFoot(q, leg)));
    planted.push_back({h.fixed.back(), ours(hgd::shapes::quadrupedLegTop(q, leg))});
  }
  h.manipulated = ours(hgd::shapes::quadrupedFoot(q, 2));
  rows.push_back(qualityCase("quadruped", q, h, Eigen::Vector3d(-0.25, 0.2, 0),
                             ours(hgd::shapes::quadrupedShin(q, 3)), planted));
  return rows;
}

}  // namespace hgdbench
