// The computational view of a shape: its finite points (NaNs dropped, index maps kept), in a
// local frame about the shape's median so that georeferenced coordinates keep float precision
// and a far stray does not spend it. The float positions are for computing the deformation;
// what is written back is computed in double from the file's own values (Deformer::writeDeformed).
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <cstddef>
#include <string>
#include <vector>

#include "hgdeform/io/shape.h"

namespace hgd {

struct Geometry {
  /// Finite points, relative to `origin` (world = local + origin), in space-filling-curve
  /// (Morton) order, not the file's: neighbours lie near each other in memory whatever order
  /// the file has. raw_index / finite_index translate.
  pcl::PointCloud<pcl::PointXYZ>::Ptr points{new pcl::PointCloud<pcl::PointXYZ>};
  /// Normals from the file (finite, non-zero), or empty when the file has none.
  pcl::PointCloud<pcl::Normal>::Ptr file_normals{new pcl::PointCloud<pcl::Normal>};
  /// Faces with indices into `points` (faces touching a non-finite vertex are dropped).
  std::vector<pcl::Vertices> faces;
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  std::vector<int> raw_index;     ///< finite point -> index in the file
  std::vector<int> finite_index;  ///< index in the file -> finite point, or -1 for NaN/inf points
                                  ///< and points set apart as absurdly far (far_points)
  /// Points set apart because they lie more than a million times the shape's size (or 1e12
  /// units) from its median: they are not deformed and are written back untouched.
  std::size_t far_points = 0;
  /// The bounding box (local frame) of the shape's body: its points within four times its size of
  /// its median, which is every point of a shape without strays. The deformer's scale (drag
  /// tolerances and steps) and the viewer's are taken from it, so a far stray does not make
  /// them coarse.
  Eigen::AlignedBox3f body;
  /// What extraction noticed that a front end should print (far points set apart).
  std::vector<std::string> warnings;

  std::size_t size() const { return points->size(); }
  bool hasFileNormals() const { return !file_normals->empty(); }
  /// World coordinates of finite point i.
  Eigen::Vector3d world(std::size_t i) const { return (*points)[i].getVector3fMap().cast<double>() + origin; }
};

/// The local frame's sample: the records whose index in the file is a multiple of this (at most
/// about 65,536 of a file's `records`; those that are finite), so that a pass over a file can
/// take it without knowing first which records are finite.
inline std::size_t frameSampleStep(std::size_t records) {
  return records > 65536 ? records / 65536 : 1;
}

/// Extracts the finite points (and normals, faces) of a shape. Throws IoError naming the file
/// when it has no x/y/z fields or no finite point, or when its points span more than 1e11 units
/// (the middle 98% of them: corrupt coordinates).
Geometry extractGeometry(const Shape& shape);

/// Writes positions (local frame of `geometry`) and, when given and the shape has normal
/// fields, normals back into the shape's x/y/z (and normal) fields at their declared types.
/// Points that were not finite are left untouched.
void storePositions(Shape& shape, const Geometry& geometry, const std::vector<Eigen::Vector3f>& positions,
                    const std::vector<Eigen::Vector3f>* normals = nullptr);

/// The axis-aligned bounding box of a cloud's points (empty for an empty cloud).
Eigen::AlignedBox3f boundingBox(const pcl::PointCloud<pcl::PointXYZ>& points);

/// The rotation nearest `a` (the R of its polar decomposition a = R S, by SVD): a proper
/// rotation even when `a` reflects.
template <typename Scalar>
Eigen::Matrix<Scalar, 3, 3> nearestRotation(const Eigen::Matrix<Scalar, 3, 3>& a) {
  Eigen::JacobiSVD<Eigen::Matrix<Scalar, 3, 3>> svd(a, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix<Scalar, 3, 3> u = svd.matrixU();
  const Eigen::Matrix<Scalar, 3, 3> v = svd.matrixV();
  if ((u * v.transpose()).determinant() < 0) u.col(2) *= Scalar(-1);
  return u * v.transpose();
}

/// The box of the shape's body (Geometry::body), or of every finite point when it is not set.
Eigen::AlignedBox3f bodyBox(const Geometry& geometry);

/// Diagonal of the shape's body (Geometry::body; of every finite point when it is not set), 0
/// for a single point.
double boundingBoxDiagonal(const Geometry& geometry);

}  // namespace hgd
