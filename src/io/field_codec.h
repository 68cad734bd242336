// Private (not installed): the one codec of pcl::PCLPointField datatypes. Sizes, binary values
// decoded and encoded (either byte order), ascii tokens parsed and printed, and the type names of
// the PLY and PCD headers. Every reader and writer, and hgd::readValue/writeValue
// (fields.cpp), goes through it.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace pcl {
struct PCLPointCloud2;
}

namespace hgd::io_internal {

/// The outcome of parsing an ascii token into a typed value.
enum class Parse { Ok, Bad, Range };

/// Whether `type` is one of the integer datatypes (INT8 … UINT32).
bool isIntegerType(std::uint8_t type);
/// Whether `type` is FLOAT32 or FLOAT64.
bool isFloatType(std::uint8_t type);

/// A binary value of datatype `type` at `p`, byte-swapped if `swap`, as a double (NaN for an
/// unknown type).
double decodeValue(const std::uint8_t* p, std::uint8_t type, bool swap = false);

/// Stores `v` at `p` as a value of datatype `type` in host byte order: integer types are
/// rounded and clamped (NaN stores 0); an unknown type stores nothing.
void encodeValue(std::uint8_t* p, std::uint8_t type, double v);

/// Parses an ascii token into `dst` as a value of datatype `type` (host byte order): integers
/// out of the type's range are Parse::Range, non-numbers Parse::Bad.
Parse parseValue(std::string_view tok, std::uint8_t type, std::uint8_t* dst);

/// Appends the value of datatype `type` at `p` as text (shortest round-trip spelling; floating
/// values padded with zeros to at least `decimals` digits after the point, in fixed notation
/// unless `exponents`).
void appendValue(std::string& out, const std::uint8_t* p, std::uint8_t type, int decimals = 0,
                 bool exponents = true);

/// Appends `v` as a value of `type`: binary (host order) to `bin`, or text to `txt`.
void putValue(double v, std::uint8_t type, std::vector<std::uint8_t>* bin, std::string* txt);

/// Byte-swaps every value of every field of every point in place.
void swapCloud(pcl::PCLPointCloud2& cloud);

/// PLY property type names ("uchar", "float32", ...) to datatypes; false for an unknown name.
bool plyTypeFromName(std::string_view name, std::uint8_t* type);
/// The classic PLY name of a datatype ("uchar", "float", ...), "?" if unknown.
const char* plyTypeName(std::uint8_t type);

/// A PCD TYPE letter (I, U, F) and SIZE to a datatype; 0 if there is none.
std::uint8_t pcdDatatype(char type, std::uint64_t size);
/// The PCD TYPE letter of a datatype.
char pcdTypeLetter(std::uint8_t type);

}  // namespace hgd::io_internal
