#include "hgdeform/deformer/precompute.h"

#include <algorithm>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "deformer/precompute_internal.h"
#include "hgdeform/graph/normals.h"
#include "util/parallel.h"
#include "util/phases.h"
#include "util/timer.h"

namespace hgd {

namespace {

void checkHandles(const Geometry& geometry, const Handles& handles) {
  auto check = [&](const std::vector<int>& idx) {
    for (const int i : idx)
      if (i < 0 || static_cast<std::size_t>(i) >= geometry.size())
        throw std::invalid_argument("Deformer: handle index " + std::to_string(i) + " out of range");
  };
  for (const auto& f : handles.fixed) check(f);
  check(handles.manipulated);
  for (const auto& j : handles.joints) check(j);
}

/// The sample, the pieces and the clusters of `points` (the field's, which has just solved
/// `phi`); `weight`: the points each stands for in the pieces report (may be null).
Clustering clusterField(const pcl::PointCloud<pcl::PointXYZ>& points, const std::vector<float>& phi,
                        const Handles& handles, const std::vector<std::uint32_t>* weight,
                        const DeformOptions& options, DeformationData& data, Stopwatch& sw) {
  PhaseClock clock;
  const NeighborGraph& graph = data.graph->graph();
  // Stray points of a scan stay out of the sample (meshes have none).
  const std::vector<char>& outliers = data.graph->outliers();
  const std::vector<int> sample =
      sampleSurface(points, handles, options.clusters.samples, outliers.empty() ? nullptr : &outliers);
  data.timings.sampling_ms = sw.lap();
  clock.lap("cluster.sample");
  data.pieces = analysePieces(points, graph, data.field.pieceLabels(), handles, sample, 2.0, weight);
  clock.lap("cluster.pieces");
  Clustering clustering = buildClusters(points, graph, phi, handles, data.field.unreachable(), sample,
                                        options.clusters, data.pieces.follow, outliers);
  clock.skip();  // (buildClusters records its own phases)
  return clustering;
}

void fullResolution(const Geometry& geometry, const Handles& handles, const DeformOptions& options,
                    DeformationData& data, Stopwatch& sw) {
  // The graph is kept: new handles only re-solve.
  data.field.setHandles(handles.fixed, handles.manipulated);
  data.field.compute(data.phi);
  data.timings.field = data.field.timings();
  data.timings.field_ms = sw.lap();
  data.timings.coarse_ms = 0;
  data.unreachable_points = data.field.unreachable().size();

  const auto& pts = *geometry.points;
  Clustering clustering = clusterField(pts, data.phi, handles, nullptr, options, data, sw);
  PhaseClock clock;
  // Normals rotate with the shape as the file gave them (the filter may have re-oriented its
  // own copy); either way shared with the table, not copied.
  data.table = buildInterpolation(data.phi, handles, clustering, pts,
                                  geometry.hasFileNormals()
                                      ? pcl::PointCloud<pcl::Normal>::ConstPtr(geometry.file_normals)
                                      : data.graph->normalCloud());
  clock.skip();  // (the table's own phases)
  data.clustering = withoutPointLabels(std::move(clustering));
  clock.lap("cluster.drop_labels");
}

/// The coarse level's normals: the file's, else a mesh's (where every coarse vertex has one);
/// null where the coarse level is to estimate them.
pcl::PointCloud<pcl::Normal>::Ptr coarseNormals(const Geometry& geometry, const CoarseLevel& coarse) {
  const auto& pts = *geometry.points;
  const std::size_t m = coarse.points.size();
  pcl::PointCloud<pcl::Normal>::ConstPtr full = geometry.hasFileNormals() ? geometry.file_normals : nullptr;
  if (!full && !geometry.faces.empty()) full = meshNormals(pts, geometry.faces);
  if (!full) return nullptr;
  pcl::PointCloud<pcl::Normal>::Ptr normals(new pcl::PointCloud<pcl::Normal>);
  normals->resize(m);
  std::vector<char> finite(m, 0);
  std::size_t missing = 0;
  for (std::size_t a = 0; a < m; ++a) {
    (*normals)[a] = (*full)[static_cast<std::size_t>(coarse.points[a])];
    finite[a] = (*normals)[a].getNormalVector3fMap().allFinite();
    missing += !finite[a];
  }
  // A representative without a normal (a vertex on no face) takes one of its cell's; a cell
  // with none at all leaves the coarse level to estimate them.
  for (std::size_t i = 0; i < pts.size() && missing > 0; ++i) {
    const std::uint32_t a = coarse.anchor[i];
    if (finite[a] || !(*full)[i].getNormalVector3fMap().allFinite()) continue;
    (*normals)[a] = (*full)[i];
    finite[a] = 1;
    --missing;
  }
  return missing > 0 ? nullptr : normals;
}

void coarseResolution(const Geometry& geometry, const Handles& handles, const DeformOptions& options,
                      DeformationData& data, Stopwatch& sw) {
  // A prebuilt level brings the whole shape's handles on it (the geometry holds some points).
  PhaseClock clock;
  const auto& pts = *geometry.points;
  const CoarseLevel& coarse = data.coarse;
  const std::size_t m = coarse.points.size();
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  cloud->resize(m);
  for (std::size_t a = 0; a < m; ++a) (*cloud)[a] = pts[static_cast<std::size_t>(coarse.points[a])];
  data.graph->setInputCloud(cloud);
  data.graph->setInputNormals(coarseNormals(geometry, coarse));
  const Handles coarse_handles = data.prebuilt ? data.prebuilt->handles : coarseHandles(handles, coarse);
  data.field.setHandles(coarse_handles.fixed, coarse_handles.manipulated);
  const double coarse_ms = sw.lap();
  clock.lap("multires.coarse_input");
  std::vector<float> coarse_phi;
  data.field.compute(coarse_phi);
  data.timings.field = data.field.timings();
  sw.lap();
  clock.skip();
  std::vector<char> constrained(m, 0);
  for (const auto& f : coarse_handles.fixed)
    for (int a : f) constrained[static_cast<std::size_t>(a)] = 1;
  for (int a : coarse_handles.manipulated) constrained[static_cast<std::size_t>(a)] = 1;
  data.phi = prolongField(pts, coarse, data.graph->graph(), coarse_phi, constrained);
  clock.lap("multires.prolong_field");
  data.timings.coarse_ms = coarse_ms + sw.ms();
  data.timings.field_ms = data.timings.field.total() + data.timings.coarse_ms;
  sw.lap();
  data.unreachable_points = 0;
  for (const int a : data.field.unreachable())
    data.unreachable_points += coarse.weight[static_cast<std::size_t>(a)];

  // Pieces and clusters on the coarse level, then every point takes its anchor's, straight into
  // the table (no per-point labels in between).
  Clustering coarse_clusters =
      clusterField(*cloud, coarse_phi, coarse_handles, &coarse.weight, options, data, sw);
  clock.skip();
  data.pieces.follow.clear();  // the coarse points' (each point takes its anchor's clusters)
  if (data.prebuilt)
    data.blocks = std::make_shared<const BlockProlongation>(
        coarse_clusters, *cloud, coarse_phi,
        coarseLinearModels(*cloud, data.graph->graph(), coarse_phi, constrained), handles.fixed.size());
  data.table = prolongInterpolation(coarse_clusters, coarse, coarse_phi, data.phi, handles, pts);
  clock.skip();  // (the table's own phases)
  data.clustering = prolongClusters(std::move(coarse_clusters), coarse);
  clock.lap("multires.prolong_clusters");
  char note[200];
  std::snprintf(note, sizeof note,
                "multi-resolution: field, pieces and clusters on %zu of %zu points (voxel side %.3g); "
                "full resolution on request",
                m, data.prebuilt ? data.prebuilt->shape_points : pts.size(),
                static_cast<double>(coarse.cell));
  data.clustering.notes.emplace_back(note);
  InterpolationTable& table = data.table;
  if (geometry.hasFileNormals()) {  // shared, not copied
    table.normal_cloud = geometry.file_normals;
    table.has_normals = true;
  } else {  // a point's rest normal: its anchor's
    const auto& normals = data.graph->normals();
    table.normals.resize(pts.size());
    const long long n = static_cast<long long>(pts.size());
#pragma omp parallel for schedule(dynamic, dynamicChunk(n)) if (n > kParallelMin)
    for (long long i = 0; i < n; ++i)
      table.normals[static_cast<std::size_t>(i)] =
          normals[coarse.anchor[static_cast<std::size_t>(i)]].getNormalVector3fMap();
    table.has_normals = true;
  }
  clock.lap("interp.normals");
}

}  // namespace

void setGraphInput(SurfaceGraph& graph, const Geometry& geometry) {
  graph.setInputCloud(geometry.points);
  graph.setInputNormals(geometry.hasFileNormals() ? geometry.file_normals : nullptr);
  if (!geometry.faces.empty()) graph.setPolygons(geometry.faces);
}

void precompute(const Geometry& geometry, const Handles& handles, const DeformOptions& options,
                DeformationData& data) {
  if (handles.manipulated.empty()) throw std::invalid_argument("Deformer: the manipulated handle is empty");
  if (handles.fixed.empty()) throw std::invalid_argument("Deformer: no fixed handle");
  Stopwatch sw;
  // The phases go to data.timings.phases (a caller recording into it already keeps its own).
  if (t_phase_log != &data.timings.phases) data.timings.phases.clear();
  PhaseRecording recording(&data.timings.phases);
  if (!data.graph) {  // the first call chooses the resolution
    data.graph = std::make_shared<SurfaceGraph>();
    data.field.setSurfaceGraph(data.graph);
    // The mesh's 1-ring, when asked for, is a graph over every vertex: full resolution.
    data.multires =
        data.prebuilt || (options.multires_above > 0 && geometry.size() > options.multires_above &&
                          options.coarse_points > 0 && options.coarse_points < geometry.size() &&
                          !(options.field.mesh_ring && !geometry.faces.empty()));
    if (!data.multires) setGraphInput(*data.graph, geometry);  // else the handles' coarse level
    data.field.setOptions(options.field);
  }
  if (data.prebuilt) {
    checkHandles(geometry, handles);
    data.coarse = data.prebuilt->level;
  } else if (data.multires) {
    checkHandles(geometry, handles);
    const std::size_t target =
        options.points_per_coarse > 0
            ? std::min(options.coarse_points, geometry.size() / options.points_per_coarse)
            : options.coarse_points;
    data.coarse = coarsen(*geometry.points, handles, target, geometry.faces.empty(),
                          geometry.raw_index.size() == geometry.size() ? &geometry.raw_index : nullptr,
                          geometry.finite_index.size());
    if (data.coarse.empty()) {  // thousands of handles: no cell key holds them all
      data.multires = false;
      setGraphInput(*data.graph, geometry);
    }
  }
  if (data.multires)
    coarseResolution(geometry, handles, options, data, sw);
  else
    fullResolution(geometry, handles, options, data, sw);
  data.timings.clusters_ms = sw.lap();
}

std::vector<SolverCluster> solverClusters(const Clustering& clustering,
                                          const pcl::PointCloud<pcl::PointXYZ>& points,
                                          const DeformOptions& options, const Eigen::Vector3d& centre,
                                          double scale) {
  int n_iso = 0;
  for (const auto& cl : clustering.clusters) n_iso += cl.kind == ClusterKind::Iso;
  const double w_mhc =
      options.weights.mhc_per_cluster > 0 ? std::max(1.0, options.weights.mhc_per_cluster * n_iso) : 1.0;
  std::vector<SolverCluster> sc(clustering.clusters.size());
  for (std::size_t c = 0; c < sc.size(); ++c) {
    const Cluster& cl = clustering.clusters[c];
    sc[c].barycentre = (cl.barycentre - centre) * scale;
    sc[c].points.reserve(cl.members.size());
    for (int i : cl.members)
      sc[c].points.push_back((points[static_cast<std::size_t>(i)].getVector3fMap().cast<double>() - centre) *
                             scale);
    // The manipulated cluster is free: a frame move holds it (solveHandle), a drag matches it.
    sc[c].constant = cl.kind == ClusterKind::Fixed || cl.kind == ClusterKind::Static;
    sc[c].rot_weight = cl.kind == ClusterKind::Manipulated ? w_mhc
                       : cl.kind == ClusterKind::Range     ? options.bone_rigidity * w_mhc
                       : cl.kind == ClusterKind::Iso       ? options.iso_rigidity
                                                           : 1.0;
  }
  return sc;
}

}  // namespace hgd
