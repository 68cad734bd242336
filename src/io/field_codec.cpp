// The one codec of pcl::PCLPointField datatypes (see field_codec.h).
#include "io/field_codec.h"

#include <pcl/PCLPointCloud2.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "io/internal.h"

namespace hgd {

std::size_t datatypeSize(std::uint8_t datatype) {
  switch (datatype) {
    case pcl::PCLPointField::INT8:
    case pcl::PCLPointField::UINT8: return 1;
    case pcl::PCLPointField::INT16:
    case pcl::PCLPointField::UINT16: return 2;
    case pcl::PCLPointField::INT32:
    case pcl::PCLPointField::UINT32:
    case pcl::PCLPointField::FLOAT32: return 4;
    case pcl::PCLPointField::FLOAT64: return 8;
    default: return 0;
  }
}

namespace io_internal {
namespace {

template <typename T>
T loadAs(const std::uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

template <typename T>
Parse storeParsed(long long v, std::uint8_t* dst) {
  if (v < static_cast<long long>(std::numeric_limits<T>::min()) ||
      v > static_cast<long long>(std::numeric_limits<T>::max()))
    return Parse::Range;
  const T t = static_cast<T>(v);
  std::memcpy(dst, &t, sizeof t);
  return Parse::Ok;
}

template <typename T>
void storeRounded(std::uint8_t* p, double value) {
  if (std::isnan(value)) value = 0;
  value = std::clamp(std::round(value), static_cast<double>(std::numeric_limits<T>::lowest()),
                     static_cast<double>(std::numeric_limits<T>::max()));
  const T v = static_cast<T>(value);
  std::memcpy(p, &v, sizeof(T));
}

struct PlyType {
  const char* name;
  std::uint8_t type;
};
constexpr PlyType kPlyTypes[] = {
    {"char", Field::INT8},       {"uchar", Field::UINT8},    {"short", Field::INT16},
    {"ushort", Field::UINT16},   {"int", Field::INT32},      {"uint", Field::UINT32},
    {"float", Field::FLOAT32},   {"double", Field::FLOAT64}, {"int8", Field::INT8},
    {"uint8", Field::UINT8},     {"int16", Field::INT16},    {"uint16", Field::UINT16},
    {"int32", Field::INT32},     {"uint32", Field::UINT32},  {"float32", Field::FLOAT32},
    {"float64", Field::FLOAT64},
};

}  // namespace

bool isIntegerType(std::uint8_t type) {
  return type == Field::INT8 || type == Field::UINT8 || type == Field::INT16 || type == Field::UINT16 ||
         type == Field::INT32 || type == Field::UINT32;
}

bool isFloatType(std::uint8_t type) {
  return type == Field::FLOAT32 || type == Field::FLOAT64;
}

double decodeValue(const std::uint8_t* p, std::uint8_t type, bool swap) {
  std::uint8_t tmp[8] = {};
  const std::size_t n = datatypeSize(type);
  std::memcpy(tmp, p, n);
  if (swap) std::reverse(tmp, tmp + n);
  switch (type) {
    case Field::INT8: return loadAs<std::int8_t>(tmp);
    case Field::UINT8: return loadAs<std::uint8_t>(tmp);
    case Field::INT16: return loadAs<std::int16_t>(tmp);
    case Field::UINT16: return loadAs<std::uint16_t>(tmp);
    case Field::INT32: return loadAs<std::int32_t>(tmp);
    case Field::UINT32: return loadAs<std::uint32_t>(tmp);
    case Field::FLOAT32: return loadAs<float>(tmp);
    case Field::FLOAT64: return loadAs<double>(tmp);
    default: return std::numeric_limits<double>::quiet_NaN();
  }
}

void encodeValue(std::uint8_t* p, std::uint8_t type, double v) {
  switch (type) {
    case Field::INT8: storeRounded<std::int8_t>(p, v); break;
    case Field::UINT8: storeRounded<std::uint8_t>(p, v); break;
    case Field::INT16: storeRounded<std::int16_t>(p, v); break;
    case Field::UINT16: storeRounded<std::uint16_t>(p, v); break;
    case Field::INT32: storeRounded<std::int32_t>(p, v); break;
    case Field::UINT32: storeRounded<std::uint32_t>(p, v); break;
    case Field::FLOAT32: {
      const float f = static_cast<float>(v);
      std::memcpy(p, &f, sizeof f);
      break;
    }
    case Field::FLOAT64: std::memcpy(p, &v, sizeof v); break;
    default: break;
  }
}

Parse parseValue(std::string_view tok, std::uint8_t type, std::uint8_t* dst) {
  // A finite number beyond the type's range (1e39 in a float, 1e400 in a double) would become
  // an infinity: out of range, as an integer that does not fit is.
  if (type == Field::FLOAT32) {
    float f = 0;
    if (!parseFloating(tok, &f)) return Parse::Bad;
    if (overflowed(tok, f)) return Parse::Range;
    std::memcpy(dst, &f, sizeof f);
    return Parse::Ok;
  }
  if (type == Field::FLOAT64) {
    double d = 0;
    if (!parseFloating(tok, &d)) return Parse::Bad;
    if (overflowed(tok, d)) return Parse::Range;
    std::memcpy(dst, &d, sizeof d);
    return Parse::Ok;
  }
  long long v = 0;
  const Parse p = parseInteger(tok, &v);
  if (p != Parse::Ok) return p;
  switch (type) {
    case Field::INT8: return storeParsed<std::int8_t>(v, dst);
    case Field::UINT8: return storeParsed<std::uint8_t>(v, dst);
    case Field::INT16: return storeParsed<std::int16_t>(v, dst);
    case Field::UINT16: return storeParsed<std::uint16_t>(v, dst);
    case Field::INT32: return storeParsed<std::int32_t>(v, dst);
    case Field::UINT32: return storeParsed<std::uint32_t>(v, dst);
    default: return Parse::Bad;
  }
}

void appendValue(std::string& out, const std::uint8_t* p, std::uint8_t type, int decimals, bool exponents) {
  switch (type) {
    case Field::INT8: appendInt(out, static_cast<int>(loadAs<std::int8_t>(p))); break;
    case Field::UINT8: appendInt(out, static_cast<unsigned>(loadAs<std::uint8_t>(p))); break;
    case Field::INT16: appendInt(out, loadAs<std::int16_t>(p)); break;
    case Field::UINT16: appendInt(out, loadAs<std::uint16_t>(p)); break;
    case Field::INT32: appendInt(out, loadAs<std::int32_t>(p)); break;
    case Field::UINT32: appendInt(out, loadAs<std::uint32_t>(p)); break;
    case Field::FLOAT32: appendFloat(out, loadAs<float>(p), decimals, exponents); break;
    case Field::FLOAT64: appendFloat(out, loadAs<double>(p), decimals, exponents); break;
    default: break;
  }
}

void putValue(double v, std::uint8_t type, std::vector<std::uint8_t>* bin, std::string* txt) {
  if (txt) {
    if (type == Field::FLOAT32)
      appendFloat(*txt, static_cast<float>(v));
    else if (type == Field::FLOAT64)
      appendFloat(*txt, v);
    else
      appendInt(*txt, static_cast<long long>(v));
    return;
  }
  // Values here were read as `type` (or are counts and indices that fit it): encoded as is.
  const std::uint8_t t = datatypeSize(type) ? type : static_cast<std::uint8_t>(Field::FLOAT64);
  std::uint8_t b[8];
  encodeValue(b, t, v);
  bin->insert(bin->end(), b, b + datatypeSize(t));
}

void swapCloud(pcl::PCLPointCloud2& cloud) {
  const std::size_t n = static_cast<std::size_t>(cloud.width) * cloud.height;
  for (std::size_t i = 0; i < n; ++i) {
    std::uint8_t* pt = cloud.data.data() + i * cloud.point_step;
    for (const auto& f : cloud.fields) {
      const std::size_t sz = datatypeSize(f.datatype);
      if (sz < 2) continue;
      for (std::size_t k = 0; k < fieldCount(f); ++k)
        std::reverse(pt + f.offset + k * sz, pt + f.offset + (k + 1) * sz);
    }
  }
}

bool plyTypeFromName(std::string_view name, std::uint8_t* type) {
  for (const auto& t : kPlyTypes)
    if (name == t.name) {
      *type = t.type;
      return true;
    }
  return false;
}

const char* plyTypeName(std::uint8_t type) {
  for (const auto& t : kPlyTypes)
    if (t.type == type) return t.name;  // the first (classic) spelling
  return "?";
}

std::uint8_t pcdDatatype(char type, std::uint64_t size) {
  if (type == 'I' && size == 1) return Field::INT8;
  if (type == 'I' && size == 2) return Field::INT16;
  if (type == 'I' && size == 4) return Field::INT32;
  if (type == 'U' && size == 1) return Field::UINT8;
  if (type == 'U' && size == 2) return Field::UINT16;
  if (type == 'U' && size == 4) return Field::UINT32;
  if (type == 'F' && size == 4) return Field::FLOAT32;
  if (type == 'F' && size == 8) return Field::FLOAT64;
  return 0;
}

char pcdTypeLetter(std::uint8_t type) {
  if (isFloatType(type)) return 'F';
  return type == Field::INT8 || type == Field::INT16 || type == Field::INT32 ? 'I' : 'U';
}

}  // namespace io_internal
}  // namespace hgd
