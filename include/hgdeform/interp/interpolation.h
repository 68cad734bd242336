// Interpolating cluster transforms back to every point (the paper's eq. 1; docs/method.md, section 6).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "hgdeform/cluster/clustering.h"
#include "hgdeform/interp/blend.h"

namespace hgd {

/// A cluster's transform in the shape's local frame, x -> A x + b, with what the rotation-aware
/// blend needs: its rigid part x -> R x + rb, R the rotation of the polar decomposition
/// A = R S (also as a quaternion q) and rb such that the barycentre g maps where A maps it.
struct LocalTransform {
  Eigen::Matrix3f A = Eigen::Matrix3f::Identity();
  Eigen::Vector3f b = Eigen::Vector3f::Zero();
  Eigen::Quaternionf q = Eigen::Quaternionf::Identity();
  Eigen::Matrix3f R = Eigen::Matrix3f::Identity();
  Eigen::Vector3f rb = Eigen::Vector3f::Zero();
  Eigen::Vector3f g = Eigen::Vector3f::Zero();  ///< rest barycentre

  /// Sets A and b and derives the polar parts.
  void set(const Eigen::Matrix3f& a, const Eigen::Vector3f& translation, const Eigen::Vector3f& barycentre);
};
/// The name before 0.2.
using LocalAffine [[deprecated("renamed hgd::LocalTransform")]] = LocalTransform;

/// For every point: the two clusters that bracket its harmonic value on its own branch, and
/// the blend factor (T = (1 - alpha) T_lower + alpha T_upper). Handle points take their handle's
/// cluster on both sides; points in parts that touch no handle take a static cluster.
struct InterpolationTable {
  /// One 20-byte record per point with its rest position: a frame streams through these once
  /// (at millions of points it is bound by memory traffic, like a copy of the positions).
  struct Point {
    /// Uninitialised: a table of millions is sized without a serial pass that zeroes it, and its
    /// pages are first written by the (parallel) pass that fills the records.
    Point() {}  // NOLINT(modernize-use-equals-default): `= default` would zero on resize
    float p[3];
    float alpha;         ///< blend factor between the pair's lower and upper clusters
    std::uint32_t pair;  ///< index into `pairs`
  };
  std::vector<Point> points;
  /// Rest normals, apart from the records: only a normals pass reads them. Either the table's
  /// own (`normals`: a multi-resolution build's, each point its anchor's), or the cloud given to
  /// buildInterpolation (`normal_cloud`, shared, not copied); restNormal() reads whichever.
  std::vector<Eigen::Vector3f> normals;
  pcl::PointCloud<pcl::Normal>::ConstPtr normal_cloud;
  bool has_normals = false;
  /// The distinct (lower, upper) pairs and each pair's rest centre (the mean of the two clusters'
  /// barycentres): the rotation-aware blend works per pair.
  std::vector<std::pair<int, int>> pairs;
  std::vector<Eigen::Vector3f> pair_centre;
  std::size_t size() const { return points.size(); }

  /// Point i's rest normal (has_normals must be true).
  Eigen::Vector3f restNormal(std::size_t i) const {
    return normal_cloud ? Eigen::Vector3f((*normal_cloud)[i].getNormalVector3fMap()) : normals[i];
  }

  /// A point's two clusters and its blend factor between them, as interpolation applies them
  /// (handle points: their handle's cluster on both sides).
  struct Bracket {
    int lower = -1, upper = -1;
    float alpha = 0;
    /// The nearer of the two (for display).
    int nearest() const { return alpha < 0.5f ? lower : upper; }
  };
  Bracket bracket(std::size_t i) const {
    const Point& r = points[i];
    return {pairs[r.pair].first, pairs[r.pair].second, r.alpha};
  }
};

/// The table for `points` under a clustering with per-point brackets (Clustering::lower, upper,
/// alpha). `normals` (may be null; else one per point) are shared with the table (normal_cloud),
/// not copied.
InterpolationTable buildInterpolation(const std::vector<float>& phi, const Handles& handles,
                                      const Clustering& clustering,
                                      const pcl::PointCloud<pcl::PointXYZ>& points,
                                      pcl::PointCloud<pcl::Normal>::ConstPtr normals);

/// Applies the blended transforms to the positions, p -> T p. Parallel over points; writes into
/// a preallocated output (sized like the table).
void interpolatePositions(const InterpolationTable& table, const std::vector<LocalTransform>& transforms,
                          std::vector<Eigen::Vector3f>& out_points, Blend blend);

/// Applies the blended transforms to the rest normals, n -> A^-T n (renormalised; a rotation for
/// the rotation-aware blend). Does nothing when the table has no normals.
void interpolateNormals(const InterpolationTable& table, const std::vector<LocalTransform>& transforms,
                        std::vector<Eigen::Vector3f>& out_normals, Blend blend);

/// Both: positions, and normals when `out_normals` is not null and the table has normals.
void interpolate(const InterpolationTable& table, const std::vector<LocalTransform>& transforms,
                 std::vector<Eigen::Vector3f>& out_points, std::vector<Eigen::Vector3f>* out_normals,
                 Blend blend);

/// A cluster's transform in the shape's local frame in double precision, x -> A x + b, for the
/// pass that writes the result (ExactInterpolation). `identity`: the transform is exactly the
/// identity (fixed handles, parts that stay, a shape not moved): its points do not move at all.
struct ExactTransform {
  Eigen::Matrix3d A = Eigen::Matrix3d::Identity();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  bool identity = true;
};

/// The blend of interpolatePositions() evaluated in double, point by point, on rest positions
/// given in double (the file's own values, not the table's float copies): what is written back
/// keeps the input's precision, and a point whose clusters do not move is reported as unmoved, so
/// that its value is left as the file had it, to the bit. It refers to the table it was made
/// from (Deformer::exactInterpolation(): valid until the deformer's handles change).
class ExactInterpolation {
 public:
  /// `barycentres`: each cluster's rest barycentre (local frame), for the rotation-aware blend's
  /// pair centres.
  ExactInterpolation(const InterpolationTable& table, std::vector<ExactTransform> transforms,
                     const std::vector<Eigen::Vector3d>& barycentres, Blend blend);
  /// Whether table point i moves (some cluster it blends with a non-zero weight is not the identity).
  bool moves(std::size_t i) const;
  /// Table point i's deformed position (local frame) from its rest position `p` (local frame).
  Eigen::Vector3d apply(std::size_t i, const Eigen::Vector3d& p) const;
  /// Table point i's turned normal (unit; the blend of interpolateNormals() in double).
  Eigen::Vector3d applyNormal(std::size_t i, const Eigen::Vector3d& n) const;

 private:
  struct Pair {
    Eigen::Vector4d qa, qb;
    Eigen::Vector3d c, ta, tb;
    int lower = 0, upper = 0;
  };
  const InterpolationTable* table_;
  std::vector<ExactTransform> transforms_;
  std::vector<Pair> pairs_;
  Blend blend_;
};

}  // namespace hgd
