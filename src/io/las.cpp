// ASPRS LAS 1.0-1.4, point formats 0-10, uncompressed.
//
// Reading: every field of the point records becomes a field of the cloud, named as laspy names
// them: x y z (double: the scaled integers times the header's scale plus its offset), intensity,
// return_number, number_of_returns, scan_direction_flag, edge_of_flight_line, classification,
// synthetic, key_point, withheld, (formats 6-10: overlap, scanner_channel), scan_angle_rank
// (formats 0-5) or scan_angle (6-10), user_data, point_source_id, gps_time, red green blue
// (uint16), nir, the waveform packet's wavepacket_index, wavepacket_offset (a double: a byte
// offset, exact below 2^53), wavepacket_size, return_point_wave_location, x_t, y_t, z_t, and the
// extra bytes under the names their VLR descriptions give (raw values; undescribed bytes as the
// uint8 array extra_bytes). The header, the VLRs and everything after the points (waveform
// data, EVLRs) are kept as bytes (FileExtras::las_*).
//
// Writing back as LAS: the same header, point format, record length, VLRs and tail; each record
// from the fields. Coordinates are requantised with the file's scale and offset: an unmoved
// point gets back its exact integers (X * scale + offset, then (x - offset) / scale rounds back
// to X). When a moved point leaves what a 32-bit integer holds about the offset, the offset moves
// by a whole number of scale steps (extrasLost says so), never wraps. The header's bounds, point
// counts and points by return are recomputed from what is written.
//
// Writing another shape as LAS: version 1.4, point format 6 (7 with red green blue, 8 with nir),
// x y z quantised at a power of ten about the box's centre (a billion steps across), intensity,
// gps_time, the flags and colours where the shape has fields of those names and integer values
// that fit, and every other scalar field as extra bytes with their descriptions.
//
// LAZ (LASzip-compressed) is refused with the reason: Debian has no LASzip decoder.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "hgdeform/version.h"
#include "io/internal.h"
#include "io/las_layout.h"

namespace hgd::io_internal {

using las::Kind;
using las::LasHeader;
using las::le;
using las::parseHeader;
using las::parseVlrs;
using las::Part;
using las::recordParts;
using las::Vlr;

bool isLaz(const std::string& path) {
  const std::string e = lower(path.size() >= 4 ? path.substr(path.size() - 4) : path);
  return e == ".laz";
}

Shape readLas(const std::string& path) {
  InputFile in(path);
  const std::uint64_t size = in.size();
  if (size < 227) fail(path, "truncated data: a LAS header takes 227 bytes, the file holds " + num(size));
  std::vector<std::uint8_t> head(227);
  in.read(head.data(), head.size(), "LAS header");
  if (std::memcmp(head.data(), "LASF", 4) != 0) fail(path, "not a LAS file (no LASF signature)");
  // A header as long as it says (LAS 1.3 and 1.4 have more of it).
  const std::uint16_t header_size = le<std::uint16_t>(head.data() + 94);
  if (header_size > 227) {
    if (header_size > size) fail(path, "truncated data: the LAS header says " + num(header_size) + " bytes");
    head.resize(header_size);
    in.read(head.data() + 227, header_size - 227, "LAS header");
  }
  const LasHeader h = parseHeader(path, head.data(), head.size());
  if ((h.format & 0xC0) != 0)
    fail(path, "LASzip-compressed (LAZ, point format " + num(h.format) +
                   "): hgdeform reads uncompressed LAS only; decompress it first (laszip -i " + path +
                   " -o OUT.las, or pdal translate)");
  if (h.format > 10) fail(path, "unsupported LAS point format " + num(h.format) + " (0-10 are read)");
  if (h.point_offset < h.header_size || h.point_offset > size)
    fail(path, "malformed LAS header: the points start at byte " + num(h.point_offset) +
                   ", the header ends at " + num(h.header_size) + " and the file at " + num(size));
  std::vector<std::uint8_t> vlr_block(h.point_offset - h.header_size);
  in.read(vlr_block.data(), vlr_block.size(), "LAS VLRs");
  const std::vector<Vlr> vlrs = parseVlrs(path, vlr_block, h.vlr_count);
  for (const Vlr& v : vlrs)
    if (v.user == "laszip encoded")
      fail(path,
           "LASzip-compressed (LAZ): hgdeform reads uncompressed LAS only; decompress it first "
           "(laszip -i " +
               path + " -o OUT.las, or pdal translate)");
  const std::vector<Part> parts = recordParts(path, h.format, h.record_length, vlrs);

  std::uint64_t bytes = 0;
  if (!mulOk(h.points, h.record_length, &bytes) || bytes > in.remaining())
    fail(path, "truncated data: the header declares " + num(h.points) + " points of " + num(h.record_length) +
                   " bytes, the file holds " + num(in.remaining()) + " bytes after the VLRs");
  if (h.points == 0) fail(path, "no points: the LAS header declares 0 points");
  if (h.points > std::numeric_limits<std::uint32_t>::max())
    fail(path, "unsupported: more than 4294967295 points");
  const std::size_t n = static_cast<std::size_t>(h.points);

  Shape shape;
  pcl::PCLPointCloud2& c = shape.cloud;
  std::uint32_t step = 0;
  for (const Part& p : parts) {
    Field f;
    f.name = p.name;
    f.datatype = p.type;
    f.count = p.count;
    f.offset = step;
    step += static_cast<std::uint32_t>(datatypeSize(p.type) * p.count);
    c.fields.push_back(f);
  }
  c.width = static_cast<std::uint32_t>(n);
  c.height = 1;
  c.point_step = step;
  c.row_step = step * c.width;
  c.is_bigendian = false;
  c.data.assign(static_cast<std::size_t>(step) * n, 0);
  const std::uint8_t* records = in.take(static_cast<std::size_t>(bytes), "point records");
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* r = records + i * h.record_length;
    std::uint8_t* out = c.data.data() + i * step;
    for (std::size_t k = 0; k < parts.size(); ++k) {
      const Part& p = parts[k];
      std::uint8_t* d = out + c.fields[k].offset;
      switch (p.kind) {
        case Kind::Coord: {
          const double v = le<std::int32_t>(r + p.offset) * h.scale[p.axis] + h.offset[p.axis];
          std::memcpy(d, &v, 8);
          break;
        }
        case Kind::Bits:
          *d = static_cast<std::uint8_t>((r[p.offset] >> p.shift) & ((1u << p.width) - 1));
          break;
        case Kind::Wide: {
          const double v = p.is_signed ? static_cast<double>(le<std::int64_t>(r + p.offset))
                                       : static_cast<double>(le<std::uint64_t>(r + p.offset));
          std::memcpy(d, &v, 8);
          break;
        }
        case Kind::Scalar: {
          const std::size_t sz = datatypeSize(p.type);
          for (std::uint32_t j = 0; j < p.count; ++j) {
            std::memcpy(d + j * sz, r + p.offset + j * sz, sz);
            if (kHostBigEndian) std::reverse(d + j * sz, d + (j + 1) * sz);
          }
          break;
        }
      }
    }
  }
  shape.extras.las_header = std::move(head);
  shape.extras.las_vlrs = std::move(vlr_block);
  const std::uint64_t rest = in.remaining();
  shape.extras.las_tail.resize(static_cast<std::size_t>(rest));
  if (rest) in.read(shape.extras.las_tail.data(), shape.extras.las_tail.size(), "LAS data after the points");
  shape.format = FileFormat::Las;
  c.is_dense = true;
  return shape;
}

}  // namespace hgd::io_internal
