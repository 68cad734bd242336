#include "hgdeform/app/report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <nlohmann/json.hpp>

#include "hgdeform/io/colormap.h"
#include "hgdeform/io/fields.h"
#include "hgdeform/io/io.h"
#include "hgdeform/version.h"

namespace hgd {

namespace {}  // namespace

void storeField(Shape& shape, const Geometry& geometry, const std::vector<float>& values,
                const std::string& name, bool colour) {
  const int fi = addFloatField(shape.cloud, name);
  const std::size_t n = shape.size();
  for (std::size_t i = 0; i < n; ++i) {
    const int k = geometry.finite_index[i];
    writeValue(shape.cloud, i, shape.cloud.fields[static_cast<std::size_t>(fi)],
               k >= 0 ? values[static_cast<std::size_t>(k)] : std::numeric_limits<float>::quiet_NaN());
  }
  if (!colour) return;
  if (shape.format == FileFormat::Pcd || findField(shape.cloud, "rgb") >= 0) {
    const int ci = addFloatField(shape.cloud, "rgb");
    for (std::size_t i = 0; i < n; ++i) {
      const int k = geometry.finite_index[i];
      const Eigen::Vector3f c = colourMap(k >= 0 ? values[static_cast<std::size_t>(k)] : 0.0f) * 255.0f;
      const std::uint32_t packed = (static_cast<std::uint32_t>(c.x()) << 16) |
                                   (static_cast<std::uint32_t>(c.y()) << 8) |
                                   static_cast<std::uint32_t>(c.z());
      std::memcpy(shape.cloud.data.data() + i * shape.cloud.point_step +
                      shape.cloud.fields[static_cast<std::size_t>(ci)].offset,
                  &packed, 4);
    }
    return;
  }
  // PLY/OBJ: red/green/blue as uchar (reusing existing fields of those names, whatever their type).
  const char* names[3] = {"red", "green", "blue"};
  int idx[3];
  for (int c = 0; c < 3; ++c) {
    idx[c] = findField(shape.cloud, names[c]);
    if (idx[c] < 0) {
      idx[c] = addFloatField(shape.cloud, names[c]);
      shape.cloud.fields[static_cast<std::size_t>(idx[c])].datatype =
          pcl::PCLPointField::UINT8;  // first byte used
    }
  }
  const bool float_colour =
      shape.cloud.fields[static_cast<std::size_t>(idx[0])].datatype == pcl::PCLPointField::FLOAT32;
  for (std::size_t i = 0; i < n; ++i) {
    const int k = geometry.finite_index[i];
    const Eigen::Vector3f c = colourMap(k >= 0 ? values[static_cast<std::size_t>(k)] : 0.0f);
    for (int ch = 0; ch < 3; ++ch)
      writeValue(shape.cloud, i, shape.cloud.fields[static_cast<std::size_t>(idx[ch])],
                 float_colour ? c[ch] : c[ch] * 255.0f);
  }
}

std::string reportJson(const DeformReport& r) {
  nlohmann::json j;
  j["version"] = version();
  j["points"] = r.points;
  j["sample"] = r.sample;
  j["clusters"] = r.clusters;
  j["isovalues"] = r.isovalues;
  j["isoclusters"] = r.isovalues;  // the key before 0.2 (docs/changes.md)
  j["unreachable"] = r.unreachable;
  j["iterations"] = r.iterations;
  j["frames"] = r.frames;
  j["max_frame_iterations"] = r.max_frame_iterations;
  j["handle_error"] = r.handle_error;
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
  j["ms"] = {{"read", r.read_ms},
             {"build", r.build_ms},
             {"field", r.field_ms},
             {"normals", r.build.field.normals_ms},
             {"knn", r.build.field.knn_ms},
             {"laplacian", r.build.field.graph_ms + r.build.field.laplacian_ms},
             {"field_solve", r.build.field.solve_ms},
             {"sampling", r.sampling_ms},
             {"clusters", r.clusters_ms},
             {"solve", r.solve_ms},
             {"solve_per_iteration", r.solve_per_iteration_ms},
             {"interpolation", r.interpolation_ms},
             {"write", r.write_ms},
             {"total", r.total_ms}};
  return j.dump(2) + "\n";
}

void writeTextAtomically(const std::string& path, const std::string& text) {
  writeFileAtomically(path, text);
}

void writeReportJson(const std::string& path, const DeformReport& report) {
  writeTextAtomically(path, reportJson(report));
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
