// A shape as read from a file: every field of every point, in file order, plus mesh faces.
#pragma once

#include <pcl/PCLPointCloud2.h>
#include <pcl/Vertices.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

namespace hgd {

/// File formats hgdeform reads and writes.
enum class FileFormat { Ply, Pcd, Obj };

/// Encoding of a written file. Binary is the default, as in PCL.
enum class Encoding { Binary, Ascii };

/// A point cloud or mesh with all its per-point fields.
///
/// `cloud` holds every point of the file in file order, NaN points included, with every field
/// at its declared type (x/y/z may be float or double), so that a shape written back keeps
/// its fields, count, order, width/height and NaNs. `polygons` holds faces (indices into the
/// points) for meshes; it is empty for point clouds.
struct Shape {
  pcl::PCLPointCloud2 cloud;
  std::vector<pcl::Vertices> polygons;
  /// PCD VIEWPOINT, kept so that a written PCD has the scan's sensor pose.
  Eigen::Vector4f sensor_origin = Eigen::Vector4f::Zero();
  Eigen::Quaternionf sensor_orientation = Eigen::Quaternionf::Identity();
  /// Where the shape came from (for messages), and its format.
  std::string path;
  FileFormat format = FileFormat::Ply;

  std::size_t size() const { return static_cast<std::size_t>(cloud.width) * cloud.height; }
  bool isMesh() const { return !polygons.empty(); }
  bool isOrganized() const { return cloud.height > 1; }
};

}  // namespace hgd
