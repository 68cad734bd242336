// The layout of a LAS file (internal; las.cpp reads the points, las_write.cpp writes them): the
// public header block, the VLRs, and the parts of a point record (the standard fields of each
// point format, then the extra bytes as their VLR describes them).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "io/internal.h"

namespace hgd::io_internal::las {

inline constexpr std::size_t kLasStandardSize[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};

template <typename T>
inline T le(const std::uint8_t* p) {
  std::uint8_t b[sizeof(T)];
  std::memcpy(b, p, sizeof b);
  if (kHostBigEndian) std::reverse(b, b + sizeof b);
  T v;
  std::memcpy(&v, b, sizeof v);
  return v;
}

template <typename T>
inline void putLe(std::uint8_t* p, T v) {
  std::uint8_t b[sizeof(T)];
  std::memcpy(b, &v, sizeof b);
  if (kHostBigEndian) std::reverse(b, b + sizeof b);
  std::memcpy(p, b, sizeof b);
}

/// What a part of a point record is and where the cloud keeps it.
enum class Kind {
  Coord,   ///< a scaled int32 coordinate (axis 0-2) -> FLOAT64 x/y/z
  Scalar,  ///< a value of `type` (count values) stored as it is
  Bits,    ///< `width` bits from `shift` of the byte at `offset` -> UINT8
  Wide,    ///< a uint64 or int64 -> FLOAT64 (exact below 2^53; larger refused)
};

struct Part {
  std::string name;
  Kind kind = Kind::Scalar;
  std::uint8_t type = Field::UINT8;  ///< the cloud's field type
  std::uint32_t offset = 0;          ///< in the record
  std::uint32_t count = 1;
  int axis = 0, shift = 0, width = 8;
  bool is_signed = false;  ///< Wide: int64
};

struct LasHeader {
  std::uint8_t major = 1, minor = 2, format = 0;
  std::uint16_t header_size = 0, record_length = 0;
  std::uint32_t point_offset = 0, vlr_count = 0;
  std::uint64_t points = 0;
  std::uint64_t evlr_start = 0;
  std::uint32_t evlr_count = 0;
  double scale[3] = {0.01, 0.01, 0.01}, offset[3] = {0, 0, 0};
};

/// The header block's fields (`h`, its first `size` bytes); fails on a version other than
/// 1.0-1.4, a header shorter than its version's, or a scale or offset 0 or not finite.
LasHeader parseHeader(const std::string& path, const std::uint8_t* h, std::size_t size);

/// The standard fields of point format `f`, in record order.
std::vector<Part> standardParts(int f);

/// The VLRs of a LAS: (user id, record id, data) of each.
struct Vlr {
  std::string user;
  std::uint16_t record = 0;
  const std::uint8_t* data = nullptr;
  std::size_t size = 0;
};

/// The `count` VLRs in `block`; fails when one runs past its end (the start of the points).
std::vector<Vlr> parseVlrs(const std::string& path, const std::vector<std::uint8_t>& block,
                           std::uint32_t count);

/// Every part of a record: the standard fields of `format`, then the extra bytes as the
/// extra-bytes VLR describes them, then any undescribed bytes as `extra_bytes`.
std::vector<Part> recordParts(const std::string& path, int format, std::size_t record_length,
                              const std::vector<Vlr>& vlrs);

}  // namespace hgd::io_internal::las
