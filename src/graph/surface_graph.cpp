#include "hgdeform/graph/surface_graph.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include "hgdeform/graph/normal_filter.h"
#include "hgdeform/graph/normals.h"
#include "hgdeform/graph/strays.h"
#include "util/phases.h"

namespace hgd {

void SurfaceGraph::setInputCloud(const pcl::PointCloud<pcl::PointXYZ>::ConstPtr& cloud) {
  if (cloud != cloud_) valid_ = false;
  cloud_ = cloud;
}

void SurfaceGraph::setInputNormals(const pcl::PointCloud<pcl::Normal>::ConstPtr& normals) {
  if (normals != input_normals_) valid_ = false;
  input_normals_ = normals;
}

void SurfaceGraph::setPolygons(const std::vector<pcl::Vertices>& polygons) {
  polygons_ = polygons;
  valid_ = false;
}

void SurfaceGraph::setOptions(const GraphOptions& options) {
  if (options.k_neighbors != options_.k_neighbors || options.k_normals != options_.k_normals ||
      options.mesh_ring != options_.mesh_ring || options.normal_filter != options_.normal_filter ||
      options.orient_to_viewpoint != options_.orient_to_viewpoint || options.viewpoint != options_.viewpoint)
    valid_ = false;
  options_ = options;
}

bool SurfaceGraph::compute() {
  if (!cloud_ || cloud_->empty()) throw std::invalid_argument("SurfaceGraph: no input cloud");
  if (valid_) return false;
  build();
  return true;
}

void SurfaceGraph::build() {
  const auto& pts = *cloud_;
  PhaseClock clock;  // each lap in the build's phase log and, in ms, in timings_
  const bool have_normals = input_normals_ && input_normals_->size() == pts.size();
  const bool mesh = !polygons_.empty();
  const bool ring = mesh && options_.mesh_ring;
  // One kNN query serves both normal estimation and the neighbour graph.
  const int k =
      (have_normals || mesh) ? options_.k_neighbors : std::max(options_.k_neighbors, options_.k_normals);
  knn_ = KnnTable{};
  if (!ring) knn_ = computeKnn(pts, k);
  timings_.knn_ms = clock.lap("graph.knn");
  if (have_normals) {
    normals_ = input_normals_;
  } else if (mesh) {
    auto n = meshNormals(pts, polygons_);
    // Vertices on no face: fall back to estimated normals so that they can still connect.
    bool missing = false;
    for (const auto& v : *n) missing = missing || !std::isfinite(v.normal_x);
    if (missing) {
      if (knn_.k == 0) knn_ = computeKnn(pts, options_.k_neighbors);
      auto est = estimateNormals(pts, knn_, options_.k_normals);
      for (std::size_t i = 0; i < n->size(); ++i)
        if (!std::isfinite((*n)[i].normal_x)) (*n)[i] = (*est)[i];
    }
    normals_ = n;
  } else {
    normals_ =
        estimateNormals(pts, knn_, options_.k_normals, options_.orient_to_viewpoint, options_.viewpoint);
  }
  // Stored normals with inconsistent signs (merged scans, resampled meshes) would make the
  // filter see thin gaps everywhere: re-oriented like estimated ones (a unit-length copy).
  reoriented_ = false;
  if (have_normals && options_.normal_filter && !ring && knn_.k > 0 &&
      !consistentlyOriented(pts, *normals_, knn_, options_.k_neighbors)) {
    pcl::PointCloud<pcl::Normal>::Ptr unit(new pcl::PointCloud<pcl::Normal>(*normals_));
    for (auto& v : *unit) {
      const float len = v.getNormalVector3fMap().norm();
      v.getNormalVector3fMap() =
          len > 0 ? Eigen::Vector3f(v.getNormalVector3fMap() / len) : Eigen::Vector3f::UnitZ();
    }
    orientNormals(pts, knn_, options_.k_normals, *unit);
    normals_ = unit;
    reoriented_ = true;
  }
  timings_.normals_ms = clock.lap("graph.normals");
  dropped_.clear();
  joined_.clear();
  if (ring) {
    graph_ = ringGraph(pts.size(), polygons_);
  } else {
    graph_ = knnGraph(knn_, options_.k_neighbors, options_.normal_filter ? normals_.get() : nullptr, &pts,
                      &dropped_);
    if (mesh && !dropped_.empty()) {
      // Mesh edges are never dropped: the mesh says those vertices are adjacent. Only the
      // dropped pairs that are mesh edges come back; the rest of the 1-ring is not added, as
      // its long edges would weigh as much as a kNN pair in the uniform Laplacian and bend
      // the field (the Armadillo's local distortion rose 2.3% when the whole ring was added).
      const NeighborGraph r = ringGraph(pts.size(), polygons_);
      std::vector<std::pair<int, int>> back;
      for (const auto& e : dropped_) {
        const auto x = static_cast<std::size_t>(e.first);
        if (std::binary_search(r.begin(x), r.end(x), e.second)) back.push_back(e);
      }
      graph_ = addEdges(graph_, back);
    }
  }
  timings_.graph_ms = clock.lap("graph.edges");
  // Stray points of a cloud hang from the surface as leaves, so that they cannot carry the
  // field across a gap (meshes have none).
  outliers_ = mesh ? std::vector<char>{} : findOutliers(pts, knn_);
  if (std::find(outliers_.begin(), outliers_.end(), 1) != outliers_.end()) {
    graph_ = attachOutliers(pts, graph_, knn_, outliers_);
    dropped_.erase(std::remove_if(dropped_.begin(), dropped_.end(),
                                  [&](const std::pair<int, int>& e) {
                                    return outliers_[static_cast<std::size_t>(e.first)] ||
                                           outliers_[static_cast<std::size_t>(e.second)];
                                  }),
                   dropped_.end());
  } else {
    outliers_.clear();
  }
  timings_.graph_ms += clock.lap("graph.strays");
  base_piece_.clear();
  if (!dropped_.empty()) connectedComponents(graph_, base_piece_);
  timings_.graph_ms += clock.lap("graph.pieces");  // the graph: edges, strays and pieces
  valid_ = true;
}

void SurfaceGraph::joinPieces(const std::vector<char>& constrained) {
  // Pieces that each hold a handle stay apart (a handle on one layer of a sheet does not pull
  // the other), also through a piece between them (three stacked plates, handles on the outer
  // two): pieces are merged in pair order, and a pair that would merge two groups that each
  // hold a handle is left out.
  joined_.clear();
  if (dropped_.empty()) return;
  const std::size_t pieces =
      base_piece_.empty()
          ? 0
          : static_cast<std::size_t>(*std::max_element(base_piece_.begin(), base_piece_.end())) + 1;
  std::vector<char> has_handle(pieces, 0);
  for (std::size_t i = 0; i < constrained.size(); ++i)
    if (constrained[i]) has_handle[static_cast<std::size_t>(base_piece_[i])] = 1;
  std::vector<int> parent(pieces);
  std::iota(parent.begin(), parent.end(), 0);
  const auto find = [&](int x) {
    while (parent[static_cast<std::size_t>(x)] != x) {
      parent[static_cast<std::size_t>(x)] =
          parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(x)])];
      x = parent[static_cast<std::size_t>(x)];
    }
    return x;
  };
  for (const auto& [a, b] : dropped_) {
    const int pa = base_piece_[static_cast<std::size_t>(a)], pb = base_piece_[static_cast<std::size_t>(b)];
    if (pa == pb || (has_handle[static_cast<std::size_t>(pa)] && has_handle[static_cast<std::size_t>(pb)]))
      continue;
    const int ra = find(pa), rb = find(pb);
    if (ra != rb) {
      if (has_handle[static_cast<std::size_t>(ra)] && has_handle[static_cast<std::size_t>(rb)]) continue;
      parent[static_cast<std::size_t>(rb)] = ra;
      has_handle[static_cast<std::size_t>(ra)] |= has_handle[static_cast<std::size_t>(rb)];
    }
    joined_.emplace_back(a, b);
  }
  if (!joined_.empty()) graph_joined_ = addEdges(graph_, joined_);
}

}  // namespace hgd
