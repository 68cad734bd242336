#include "hgdeform/app/report.h"

#include <cstdio>

#include "app/report_json.h"
#include "hgdeform/io/io.h"
#include "hgdeform/version.h"

namespace hgd {

namespace {

/// The timings reportFigures() keeps, by key.
struct Timing {
  const char* key;
  double DeformReport::*ms;
};
const Timing kFigureTimings[] = {
    {"read", &DeformReport::read_ms},
    {"build", &DeformReport::build_ms},
    {"field", &DeformReport::field_ms},
    {"sampling", &DeformReport::sampling_ms},
    {"clusters", &DeformReport::clusters_ms},
    {"solve", &DeformReport::solve_ms},
    {"interpolation", &DeformReport::interpolation_ms},
    {"write", &DeformReport::write_ms},
    {"total", &DeformReport::total_ms},
};

}  // namespace

nlohmann::json reportFigures(const DeformReport& r) {
  nlohmann::json ms = nlohmann::json::object();
  for (const Timing& t : kFigureTimings) ms[t.key] = r.*t.ms;
  return {{"points", r.points}, {"clusters", r.clusters},         {"iterations", r.iterations},
          {"frames", r.frames}, {"handle_error", r.handle_error}, {"ms", ms}};
}

void readReportFigures(const nlohmann::json& j, DeformReport& r) {
  r.points = j.at("points").get<std::size_t>();
  r.clusters = j.at("clusters").get<std::size_t>();
  r.iterations = j.at("iterations").get<int>();
  r.frames = j.at("frames").get<int>();
  r.handle_error = j.at("handle_error").get<double>();
  const nlohmann::json& ms = j.at("ms");
  for (const Timing& t : kFigureTimings) r.*t.ms = ms.at(t.key).get<double>();
}

nlohmann::json reportToJson(const DeformReport& r) {
  nlohmann::json j = reportFigures(r);
  j["version"] = version();
  j["sample"] = r.sample;
  j["isovalues"] = r.isovalues;
  j["isoclusters"] = r.isovalues;  // the key before 0.2 (docs/changes.md)
  j["unreachable"] = r.unreachable;
  j["max_frame_iterations"] = r.max_frame_iterations;
  j["reached"] = r.reached;
  j["notes"] = r.notes;
  j["warnings"] = r.warnings;
  j["pieces"] = {{"followed_points", r.pieces.followed_points},
                 {"followed_pieces", r.pieces.followed_pieces},
                 {"stayed_points", r.pieces.stayed_points},
                 {"stayed_pieces", r.pieces.stayed_pieces},
                 {"rigid_points", r.pieces.rigid_points},
                 {"rigid_pieces", r.pieces.rigid_pieces},
                 {"reach", r.pieces.reach}};
  j["surface"] = {{"split_points", r.surface.split_points},
                  {"max_stretch", r.surface.max_stretch},
                  {"pairs", r.surface.pairs}};
  j["energy"] = {{"detail", r.energy.detail},
                 {"prop", r.energy.prop},
                 {"manip", r.energy.manip},
                 {"length", r.energy.length},
                 {"total", r.energy.total()}};
  if (r.peak_rss_mb > 0) j["peak_rss_mb"] = r.peak_rss_mb;
  if (r.huge_page_malloc) j["huge_page_malloc"] = true;
  nlohmann::json& ms = j["ms"];
  ms["normals"] = r.build.field.normals_ms;
  ms["knn"] = r.build.field.knn_ms;
  ms["laplacian"] = r.build.field.graph_ms + r.build.field.laplacian_ms;
  ms["field_solve"] = r.build.field.solve_ms;
  ms["solve_per_iteration"] = r.solve_per_iteration_ms;
  // Every phase of the Deformer's build in order (BuildTimings::phases), as the bench lists them.
  nlohmann::json& phases = j["build_phases"] = nlohmann::json::array();
  for (const BuildPhase& p : r.build.phases) phases.push_back({{"name", p.name}, {"ms", p.ms}});
  return j;
}

std::string reportJson(const DeformReport& r) {
  return reportToJson(r).dump(2) + "\n";
}

void writeReportJson(const std::string& path, const DeformReport& report) {
  writeFileAtomically(path, reportJson(report));
}

std::string summaryLine(const DeformReport& r) {
  char buf[512];
  std::snprintf(
      buf, sizeof buf,
      "%zu points, %zu clusters, %d frames, %d Gauss-Newton iterations (max %d per frame), handle error "
      "%.3g; "
      "build %.0f ms (field %.0f, sampling %.0f, clusters %.0f), solve %.1f ms (%.3f per iteration), "
      "interpolation %.1f ms, total %.0f ms",
      r.points, r.clusters, r.frames, r.iterations, r.max_frame_iterations, r.handle_error, r.build_ms,
      r.field_ms, r.sampling_ms, r.clusters_ms, r.solve_ms, r.solve_per_iteration_ms, r.interpolation_ms,
      r.total_ms);
  return buf;
}

}  // namespace hgd
