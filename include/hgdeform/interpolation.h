// Interpolating cluster transforms back to every point (ALGORITHM.md §4, the paper's eq. 1).
#pragma once

#include <Eigen/Core>
#include <vector>

#include "hgdeform/clustering.h"

namespace hgd {

/// A cluster's transform in the shape's local frame: x -> A x + b.
struct LocalAffine {
  Eigen::Matrix3f A = Eigen::Matrix3f::Identity();
  Eigen::Vector3f b = Eigen::Vector3f::Zero();
};

/// For every point: the two clusters that bracket its harmonic value on its own branch, and
/// the blend factor (T = (1 - alpha) T_lo + alpha T_hi). Handle points take their handle's
/// cluster on both sides; points in parts that touch no handle take a static cluster.
struct InterpolationTable {
  std::vector<int> lo, hi;
  std::vector<float> alpha;
  std::size_t size() const { return alpha.size(); }
};

InterpolationTable buildInterpolation(const std::vector<float>& phi, const Handles& handles,
                                      const Clustering& clustering);

/// Applies the blended transforms: positions p -> T p, normals n -> A^-T n (renormalised).
/// Parallel over points; writes into preallocated outputs (sized like the table). `normals`
/// and `out_normals` may be null.
void interpolate(const InterpolationTable& table, const std::vector<LocalAffine>& transforms,
                 const pcl::PointCloud<pcl::PointXYZ>& points, const pcl::PointCloud<pcl::Normal>* normals,
                 std::vector<Eigen::Vector3f>& out_points, std::vector<Eigen::Vector3f>* out_normals);

}  // namespace hgd
