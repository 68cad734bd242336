// Typed access to the fields of a pcl::PCLPointCloud2 blob, whatever their declared types, and
// storeField: a per-point scalar (the harmonic field) stored into a shape, with its colour map.
#pragma once

#include <pcl/PCLPointCloud2.h>

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace hgd {

struct Geometry;
struct Shape;

/// Size in bytes of one value of a pcl::PCLPointField datatype (INT8 … FLOAT64); 0 if unknown.
std::size_t datatypeSize(std::uint8_t datatype);

/// Index of the field called `name` in cloud.fields, or -1.
int findField(const pcl::PCLPointCloud2& cloud, const std::string& name);

/// The value of element `element` of `field` at `point`, converted to double.
double readValue(const pcl::PCLPointCloud2& cloud, std::size_t point, const pcl::PCLPointField& field,
                 std::size_t element = 0);

/// Stores `value` at `point` converted to the field's declared type (rounded and clamped for
/// integer types).
void writeValue(pcl::PCLPointCloud2& cloud, std::size_t point, const pcl::PCLPointField& field, double value,
                std::size_t element = 0);

/// Appends a FLOAT32 scalar field called `name` (or reuses an existing field of that name) and
/// returns its index. Existing data is kept; the new field is zero until written.
int addFloatField(pcl::PCLPointCloud2& cloud, const std::string& name);

/// Changes the datatype of the given fields (indices into cloud.fields), converting every value;
/// the point record is repacked (fields in their order). Used to widen integer coordinates that
/// cannot hold a deformed position.
void retypeFields(pcl::PCLPointCloud2& cloud, const std::vector<int>& fields, std::uint8_t datatype);

/// Name of the x/y/z or normal component field actually used by a cloud: normals are
/// "normal_x" in PCD/PCL and "nx" in PLY; both are recognised.
struct XyzFields {
  int x = -1, y = -1, z = -1;
  int nx = -1, ny = -1, nz = -1;
  bool hasXyz() const { return x >= 0 && y >= 0 && z >= 0; }
  bool hasNormals() const { return nx >= 0 && ny >= 0 && nz >= 0; }
};
XyzFields findXyzFields(const pcl::PCLPointCloud2& cloud);

/// Where a cloud keeps its per-point colours, for everything that draws them (the renderer and
/// the viewer). `red`/`green`/`blue` fields win over a packed one: 8-bit integers are 0..255,
/// 16-bit ones 0..65535, any other type 0..1, or 0..255 when some value of the cloud exceeds 1
/// (float colours are written both ways). Else `rgb`, else `rgba`: 4 bytes (declared float, as
/// PCL writes it, or uint32) holding 0xAARRGGBB.
struct ColourFields {
  int red = -1, green = -1, blue = -1;
  double scale = 1;  ///< red/green/blue: the value of full intensity
  int packed = -1;   ///< rgb or rgba
  bool any() const { return (red >= 0 && green >= 0 && blue >= 0) || packed >= 0; }
};
ColourFields findColourFields(const pcl::PCLPointCloud2& cloud);

/// The colour of `point`, each component in [0, 1] (NaN reads as 0); grey when `fields` has none.
Eigen::Vector3f readColour(const pcl::PCLPointCloud2& cloud, std::size_t point, const ColourFields& fields);

/// Adds (or overwrites) a float field `name` holding `values` (one per finite point; NaN for
/// points that are not finite). With `colour`, also writes the values as a blue-to-red colour
/// map: red/green/blue uchar fields for PLY/OBJ, a packed `rgb` field for PCD.
void storeField(Shape& shape, const Geometry& geometry, const std::vector<float>& values,
                const std::string& name, bool colour = false);

}  // namespace hgd
