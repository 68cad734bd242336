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

/// File formats hgdeform reads and writes: PLY, PCD, OBJ, ASCII XYZ/TXT point lists, OFF
/// and STL (ascii or binary).
/// Pts: Leica's ASCII point list (a line with the point count, then `x y z [intensity] [r g b]`
/// rows), as scanners and Open3D write it; read and written by the XYZ code. Las: ASPRS LAS
/// 1.0-1.4, point formats 0-10, uncompressed.
enum class FileFormat { Ply, Pcd, Obj, Xyz, Off, Stl, Pts, Las };

/// Encoding of a written file. Binary is the default, as in PCL.
enum class Encoding { Binary, Ascii };

/// What a file holds beyond per-point scalar fields and faces' vertex lists, kept so that a
/// shape written back in its own format loses nothing: PLY elements other than vertex and face
/// (a camera, edges), face properties (per-face colours), vertex list properties, comments;
/// an OBJ's texture coordinates, normals, groups, objects, materials and face corners; a PCD's
/// compression.
struct FileExtras {
  struct Property {
    std::string name;
    std::uint8_t type = 0;  ///< a pcl::PCLPointField datatype
    bool list = false;
    std::uint8_t count_type = 0;  ///< lists: the type of the length
  };
  /// A PLY element with every property in file order. `kept[k]` says whether property k's
  /// values are in `values` (else they are in the cloud's fields or, for the face element's
  /// vertex_indices, in `polygons`). `values` runs record by record, kept property by kept
  /// property; a list is its length followed by its items.
  struct Element {
    std::string name;
    std::uint64_t count = 0;
    std::vector<Property> props;
    std::vector<char> kept;
    std::vector<double> values;
  };
  std::vector<Element> ply_elements;  ///< every element of a PLY, in file order
  std::vector<std::string> ply_comments;
  /// OBJ: every line of the file, in order. 'v' lines are rewritten from the cloud's x/y/z,
  /// 'vn' lines from `obj_normals`; the rest is written back as it was.
  std::vector<std::string> obj_lines;
  std::vector<Eigen::Vector3f> obj_normals;      ///< the 'vn' values as read, in order
  std::vector<Eigen::Vector3f> obj_normals_out;  ///< turned with the shape (else written as read)
  /// Per 'vn': the first vertex a face pairs it with, or -1; in a point cloud (no faces) with
  /// as many 'vn' as 'v', the vertex of the same rank (as MeshLab and CloudCompare read one).
  std::vector<int> obj_normal_vertex;
  bool pcd_compressed = false;  ///< PCD read as binary_compressed
  /// LAS: the public header block as read (every byte, a newer version's too), the bytes from its
  /// end to the point records (the VLRs, the CRS among them, and any bytes a writer left there)
  /// and every byte after the point records (waveform data, EVLRs). Written back as LAS with the
  /// header's counts, bounds and (when points left what it could hold) offsets made true.
  std::vector<std::uint8_t> las_header, las_vlrs, las_tail;
  bool ply_big_endian = false;  ///< PLY read as binary_big_endian (written back so)
  /// XYZ/TXT: the names its columns were given (written back without a line of names, or with
  /// `xyz_header`, while the fields are these). The file's line of column names as it was
  /// written ("" if it had none), and the separator of its values as in its first row ("\t",
  /// ",", ", ", " "...).
  std::vector<std::string> xyz_names;
  std::string xyz_header;
  std::string xyz_separator = " ";
  /// XYZ/TXT/PTS: the file began with a line holding its point count (PTS).
  bool xyz_count_line = false;
  /// Text formats: how a field's values were spelt, for each field whose values written in fixed
  /// notation all had decimals: the fewest any had ("1.500000" everywhere: 6), and whether some
  /// were written with an exponent. Written back the same way (padded with zeros to as many
  /// decimals; in fixed notation unless the file used exponents), so a value that did not change
  /// comes back as the same text.
  struct TextColumn {
    std::string field;
    int decimals = 0;
    bool exponents = false;
    /// When the column's values were spelt with differing decimals ("1.5" beside "1.50"): each
    /// row's, in file order (-1: written with an exponent), so that every row comes back as spelt.
    std::vector<std::int8_t> rows;
  };
  std::vector<TextColumn> text_decimals;
  bool empty() const {
    return ply_elements.empty() && obj_lines.empty() && !pcd_compressed && las_header.empty() &&
           !ply_big_endian;
  }
};

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
  /// Everything else the file held (see FileExtras).
  FileExtras extras;
  /// What reading noticed that a front end should print as a warning: the content was read as
  /// another format than the extension says, or data the shape cannot hold was dropped.
  std::vector<std::string> warnings;

  std::size_t size() const { return static_cast<std::size_t>(cloud.width) * cloud.height; }
  bool isMesh() const { return !polygons.empty(); }
  bool isOrganized() const { return cloud.height > 1; }
};

}  // namespace hgd
