// The coarse level of a shape built by passes over its file (a scan larger than memory): the
// frame Geometry would give the file's points and the level coarsen would build on them, point
// for point, without holding the points. Memory: the coarse level, the handles, a block of
// records and the few points the stray rule looks at.
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <unordered_map>
#include <vector>

#include "hgdeform/io/records.h"

namespace hgd {

/// Handles by the file's record indices (each list ascending, without repeats).
struct RecordHandles {
  std::vector<std::vector<std::uint64_t>> fixed;
  std::vector<std::uint64_t> manipulated;
  std::vector<std::vector<std::uint64_t>> joints;
};

struct StreamedLevelOptions {
  std::size_t coarse_points = 65536;   ///< DeformOptions::coarse_points
  std::size_t points_per_coarse = 10;  ///< DeformOptions::points_per_coarse
  bool find_strays = true;             ///< a cloud's (a mesh has none)
  std::size_t block = 1 << 16;         ///< records a read
  /// The ranks of a split run (null or one rank: this process reads every record). Each reads
  /// its share (shareOf) and every pass is gathered: every rank returns the same level, the
  /// level one process builds.
  StreamRanks* ranks = nullptr;
};

/// What extractGeometry and coarsen give a file's points, found by passes over its records.
struct StreamedLevel {
  // The frame (Geometry's).
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::AlignedBox3f body;      ///< Geometry::body
  std::uint64_t records = 0;     ///< the file's records
  std::uint64_t points = 0;      ///< finite points kept (Geometry::size())
  std::uint64_t far_points = 0;  ///< Geometry::far_points
  bool file_normals = false;     ///< Geometry::hasFileNormals()
  std::vector<std::string> warnings;
  // The coarse level (coarsen's), empty when the points are too few for one (`target` 0).
  float cell = 0;                            ///< CoarseLevel::cell
  pcl::PointCloud<pcl::PointXYZ> coarse;     ///< the coarse points (CoarseLevel::points' positions)
  pcl::PointCloud<pcl::Normal> normals;      ///< their file normals (file_normals)
  std::vector<std::uint64_t> coarse_record;  ///< coarse point -> its record
  std::vector<std::uint32_t> weight;         ///< CoarseLevel::weight
  /// Coarse point -> its rank among the coarse points in Geometry's (Morton) order: the order of
  /// CoarseLevel::points' indices.
  std::vector<std::uint32_t> morton_rank;
  /// The handles on the coarse level (coarseHandles: the anchors of each list's kept points).
  std::vector<std::vector<int>> coarse_fixed, coarse_joints;
  std::vector<int> coarse_manipulated;
  std::vector<std::uint64_t> strays;        ///< CoarseLevel::strays' records, ascending
  std::vector<std::uint32_t> stray_anchor;  ///< their anchors

  /// The local (float) position of a point Geometry keeps (world - origin, rounded to float).
  Eigen::Vector3f local(const Eigen::Vector3d& world) const { return (world - origin).cast<float>(); }
  /// Whether the record at `world` (finite) is one Geometry keeps: not a 'no return' at (0, 0, 0)
  /// set apart, not too far, not a far stray.
  bool kept(std::uint64_t record, const Eigen::Vector3d& world) const;
  /// The anchor (CoarseLevel::anchor) of a kept point: its record, local position and class
  /// (classOf).
  std::uint32_t anchorOf(std::uint64_t record, const Eigen::Vector3f& p, int cls) const;
  /// The anchor of a kept point that is not one of `strays`: the coarse point of its cell.
  std::uint32_t cellAnchor(const Eigen::Vector3f& p, int cls) const;
  /// Geometry's Morton key of a kept point (its order among the points: by key, then record).
  std::uint32_t mortonKey(const Eigen::Vector3d& world) const;
  /// A record's class in the coarse grid: 0 free, 1 the manipulated handle, 2 + k fixed handle
  /// k, then the joints (coarsen's).
  int classOf(std::uint64_t record) const;

  // (The rules' state, for kept, anchorOf and classOf.)
  Eigen::Vector3d frame_centre = Eigen::Vector3d::Zero();
  Eigen::Vector3d morton_lo = Eigen::Vector3d::Zero();
  double morton_scale = 0;
  double far = 0, stray_distance = 0;
  bool zeros_apart = false;
  std::vector<std::uint64_t> far_strays;  ///< Geometry's strays set apart, ascending
  Eigen::Vector3f grid_lo = Eigen::Vector3f::Zero();
  int axis_bits = 0;
  std::vector<std::uint64_t> cell_key;  ///< the coarse cells' keys, ascending
  std::vector<std::uint32_t> cell_id;   ///< their coarse points
  /// The handle records and their classes, ascending: record << 16 | class (8 bytes a handle
  /// point: a tenth of a 200M-point scan in handles is 160 MB).
  std::vector<std::uint64_t> record_class;
  /// A pass's classes of records asked in ascending order (a cursor over record_class).
  class ClassCursor {
   public:
    explicit ClassCursor(const StreamedLevel& level) : v_(level.record_class) {}
    int of(std::uint64_t record) {
      while (at_ < v_.size() && (v_[at_] >> 16) < record) ++at_;
      return at_ < v_.size() && (v_[at_] >> 16) == record ? static_cast<int>(v_[at_] & 0xFFFFu) : 0;
    }

   private:
    const std::vector<std::uint64_t>& v_;
    std::size_t at_ = 0;
  };
};

/// Builds the level by passes over the file's records: a strided read for the frame, a pass
/// for what is set apart and the body, one for the cells, and one over the points the stray
/// rule looks at when a cell is sparse. Throws IoError naming the file when it cannot be read,
/// or when its shape is one this build cannot reproduce (a sample that holds no finite record).
StreamedLevel streamCoarseLevel(const RecordLayout& layout, const RecordHandles& handles,
                                const StreamedLevelOptions& options);
/// The same with the handles found once the frame is (`handles_of` is given the level with its
/// frame set: kept() answers; it may read the file). It returns a reference to handles that live
/// until this returns (the caller's, not a copy: a scan's handle lists can be gigabytes); declare
/// a lambda's return type `-> const RecordHandles&`, or it returns a temporary.
StreamedLevel streamCoarseLevel(const RecordLayout& layout,
                                const std::function<const RecordHandles&(const StreamedLevel&)>& handles_of,
                                const StreamedLevelOptions& options);

}  // namespace hgd
