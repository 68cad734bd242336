// Interpolating cluster transforms back to every point (the paper's eq. 1; docs/method.md, section 6).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

#include "hgdeform/blend.h"
#include "hgdeform/clustering.h"

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
  /// One record per point, with its rest position and normal: interpolation streams through
  /// memory once per frame (at millions of points it is bound by memory traffic).
  struct Point {
    float p[3];
    float n[3];   ///< rest normal (zero when the table has none)
    int pair;     ///< index into `pairs`
    float alpha;  ///< blend factor between the pair's lower and upper clusters
  };
  std::vector<Point> points;
  bool has_normals = false;
  /// The distinct (lower, upper) pairs and each pair's rest centre (the mean of the two clusters'
  /// barycentres): the rotation-aware blend works per pair.
  std::vector<std::pair<int, int>> pairs;
  std::vector<Eigen::Vector3f> pair_centre;
  std::size_t size() const { return points.size(); }
};

/// The table for `points` (and their `normals`, which may be null) under a clustering.
InterpolationTable buildInterpolation(const std::vector<float>& phi, const Handles& handles,
                                      const Clustering& clustering,
                                      const pcl::PointCloud<pcl::PointXYZ>& points,
                                      const pcl::PointCloud<pcl::Normal>* normals);

/// Applies the blended transforms: positions p -> T p, normals n -> A^-T n (renormalised).
/// Parallel over points; writes into preallocated outputs (sized like the table).
/// `out_normals` may be null, and is not written when the table has no normals.
void interpolate(const InterpolationTable& table, const std::vector<LocalTransform>& transforms,
                 std::vector<Eigen::Vector3f>& out_points, std::vector<Eigen::Vector3f>* out_normals,
                 Blend blend = Blend::Linear);

}  // namespace hgd
