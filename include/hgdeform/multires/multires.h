// The multi-resolution build (docs/method.md §7): the field, the pieces and the clusters
// on a voxel subsample, prolonged to every point.
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>
#include <algorithm>
#include <cstdint>
#include <memory>
#include <vector>

#include "hgdeform/cluster/clustering.h"
#include "hgdeform/cluster/handles.h"
#include "hgdeform/graph/neighbor_graph.h"
#include "hgdeform/interp/interpolation.h"

namespace hgd {

/// A voxel subsample: one point per occupied (cell, handle) pair, the one nearest the cell's
/// centre, so that every handle keeps points of its own. Every shape point has an anchor: the
/// coarse point of its cell (or, for a stray, the nearest one).
struct CoarseLevel {
  std::vector<int> points;            ///< coarse point -> shape point (its cell's representative)
  std::vector<std::uint32_t> anchor;  ///< shape point -> coarse point (its cell's)
  std::vector<std::uint32_t> weight;  ///< coarse point -> shape points it stands for
  /// Shape points alone in their block of cells (strays of a scan): no coarse point; each hangs
  /// from the nearest coarse point (its anchor) and takes its values.
  std::vector<int> strays;
  float cell = 0;  ///< the voxel side
  bool empty() const { return points.empty(); }
};

/// About `target` coarse points (within ±15% where the cloud allows). Empty when the handles
/// are too many to key the cells by (thousands): the caller stays at full resolution. Handle
/// indices must be valid. `find_strays`: a cloud's (a mesh has none).
/// `file_index`: each point's index in the file (Geometry::raw_index; null: its index here), and
/// `records` the file's record count (at least the points'): the grid's sizing subset and the
/// strays' typical-distance sample are the points at file indices on a stride, and of points as
/// near their cell's centre the first in the file stands for it. The level so depends on the
/// points and their indices in the file, not on the order they come in here (the Morton order),
/// which a build that streams the file can reproduce.
CoarseLevel coarsen(const pcl::PointCloud<pcl::PointXYZ>& points, const Handles& handles, std::size_t target,
                    bool find_strays = true, const std::vector<int>* file_index = nullptr,
                    std::size_t records = 0);

/// The handles (and joints) of the coarse level: the anchors of their points.
Handles coarseHandles(const Handles& handles, const CoarseLevel& level);

/// A coarse point's linear model of φ: its gradient (least squares over its graph neighbours)
/// and the range of values about it.
struct CoarseLinear {
  Eigen::Vector3f grad = Eigen::Vector3f::Zero();
  float lo = 0, hi = 0;
  /// φ at offset `d` from the coarse point whose value is `value`.
  float at(float value, const Eigen::Vector3f& d) const { return std::clamp(value + grad.dot(d), lo, hi); }
};

/// The models of the coarse points (`coarse`, their positions; `graph` on them; `constrained`:
/// handle points, whose models are their value alone).
std::vector<CoarseLinear> coarseLinearModels(const pcl::PointCloud<pcl::PointXYZ>& coarse,
                                             const NeighborGraph& graph, const std::vector<float>& coarse_phi,
                                             const std::vector<char>& constrained);

/// φ at every shape point from φ at the coarse points (`coarse_phi`, solved on `graph`, the
/// coarse points' neighbour graph; `constrained`: coarse handle points). A point takes its
/// anchor's value moved along the anchor's gradient (least squares over its graph neighbours),
/// limited to the range of values around the anchor; a handle's points take its value exactly.
std::vector<float> prolongField(const pcl::PointCloud<pcl::PointXYZ>& points, const CoarseLevel& level,
                                const NeighborGraph& graph, const std::vector<float>& coarse_phi,
                                const std::vector<char>& constrained);

/// The interpolation table of every shape point from the coarse level's clustering: each point
/// takes its anchor's two clusters, and its blend factor from its own φ where the anchor's came
/// from φ (else the anchor's). What building the table from per-point labels gave,
/// straight from the coarse level's clustering, with no per-point labels in between (16 bytes
/// a point fewer at the peak). `handles`: the shape's; normals are left to the caller.
InterpolationTable prolongInterpolation(const Clustering& coarse, const CoarseLevel& level,
                                        const std::vector<float>& coarse_phi, const std::vector<float>& phi,
                                        const Handles& handles, const pcl::PointCloud<pcl::PointXYZ>& points);

/// What the interpolation table of any shape point needs of the coarse level, kept so that a
/// streamed build makes its table block by block (prolongInterpolation's rows, point for point).
class BlockProlongation {
 public:
  /// `coarse`: the coarse clustering with its per-point labels; `points`: the coarse points'
  /// positions; `models`: coarseLinearModels; `fixed_handles`: the shape's fixed handle count
  /// (every one with points).
  BlockProlongation(const Clustering& coarse, pcl::PointCloud<pcl::PointXYZ> points,
                    std::vector<float> coarse_phi, std::vector<CoarseLinear> models,
                    std::size_t fixed_handles);
  ~BlockProlongation();
  BlockProlongation(const BlockProlongation&) = delete;
  BlockProlongation& operator=(const BlockProlongation&) = delete;

  /// The table of `points` (local positions): each with its anchor, whether it is a stray (it
  /// takes its anchor's factor) and its class (coarsen's: 1 the manipulated handle, 2 + k fixed
  /// handle k, pinned to their clusters; other classes not). Normals are left to the caller.
  InterpolationTable table(const pcl::PointCloud<pcl::PointXYZ>& points,
                           const std::vector<std::uint32_t>& anchor, const std::vector<char>& stray,
                           const std::vector<int>& cls) const;
  /// φ of a point at `p` anchored at coarse point a (a stray: the anchor's).
  float phi(std::uint32_t a, const Eigen::Vector3f& p, bool stray) const;

 private:
  struct Rule;
  std::unique_ptr<Rule> rule_;
  Clustering labels_;  // the coarse clustering (bands, clusters, labels)
  pcl::PointCloud<pcl::PointXYZ> points_;
  std::vector<float> phi_;
  std::vector<CoarseLinear> models_;
  std::size_t fixed_handles_;
};

/// The clusters of the shape from the coarse level's: member and sample indices become shape
/// indices; no per-point labels (lower, upper, alpha and nearest are left empty).
Clustering prolongClusters(Clustering coarse, const CoarseLevel& level);

}  // namespace hgd
