// ASPRS LAS: laspy's published test files (../shared/datasets/las, where present) and files this
// test writes itself for every version (1.0-1.4) and point format (0-10), decoded here with the
// test's own reading of the specification, never with hgdeform's.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "hgdeform/app/runner.h"
#include "hgdeform/app/scenario.h"
#include "hgdeform/io/fields.h"
#include "hgdeform/io/io.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;
using hgd::Shape;
using hgdtest::slurp;
using hgdtest::TempDir;
using hgdtest::writeText;

template <typename T>
T at(const std::string& b, std::size_t o) {
  T v;
  std::memcpy(&v, b.data() + o, sizeof v);
  return v;
}

template <typename T>
void put(std::string& b, std::size_t o, T v) {
  std::memcpy(&b[o], &v, sizeof v);
}

double value(const Shape& s, std::size_t point, const std::string& name) {
  const int i = hgd::findField(s.cloud, name);
  if (i < 0) {
    ADD_FAILURE() << "no field " << name;
    return std::numeric_limits<double>::quiet_NaN();
  }
  return hgd::readValue(s.cloud, point, s.cloud.fields[static_cast<std::size_t>(i)]);
}

/// A LAS file as the specification lays it out, read by the test.
struct Las {
  std::string bytes;
  int minor = 0, format = 0;
  std::size_t header_size = 0, point_offset = 0, record_length = 0, points = 0;
  double scale[3], offset[3];

  explicit Las(std::string b) : bytes(std::move(b)) {
    minor = static_cast<unsigned char>(bytes[25]);
    header_size = at<std::uint16_t>(bytes, 94);
    point_offset = at<std::uint32_t>(bytes, 96);
    format = static_cast<unsigned char>(bytes[104]);
    record_length = at<std::uint16_t>(bytes, 105);
    points = at<std::uint32_t>(bytes, 107);
    if (minor >= 4 && at<std::uint64_t>(bytes, 247) != 0) points = at<std::uint64_t>(bytes, 247);
    for (int a = 0; a < 3; ++a) {
      scale[a] = at<double>(bytes, 131 + 8 * a);
      offset[a] = at<double>(bytes, 155 + 8 * a);
    }
  }
  std::string record(std::size_t i) const {
    return bytes.substr(point_offset + i * record_length, record_length);
  }
  std::string records() const { return bytes.substr(point_offset, points * record_length); }
  std::string vlrs() const { return bytes.substr(header_size, point_offset - header_size); }
  std::string tail() const { return bytes.substr(point_offset + points * record_length); }
  std::int32_t raw(std::size_t i, int axis) const {
    return at<std::int32_t>(bytes, point_offset + i * record_length + 4 * static_cast<std::size_t>(axis));
  }
  double coord(std::size_t i, int axis) const { return raw(i, axis) * scale[axis] + offset[axis]; }
  double gpsTime(std::size_t i) const {
    const std::size_t o = format >= 6 ? 22 : 20;
    return at<double>(bytes, point_offset + i * record_length + o);
  }
  int returnNumber(std::size_t i) const {
    const auto b = static_cast<unsigned char>(bytes[point_offset + i * record_length + 14]);
    return format >= 6 ? (b & 15) : (b & 7);
  }
  int classification(std::size_t i) const {
    const std::size_t r = point_offset + i * record_length;
    return format >= 6 ? static_cast<unsigned char>(bytes[r + 16])
                       : (static_cast<unsigned char>(bytes[r + 15]) & 31);
  }
};

/// The header of `out` is `in`'s but for its bounds and counts, which are the written points'
/// own (bounds from their integers; points by return counting a return number of 0 as a first
/// return; the legacy counts where the file had them or its points are of formats 0-5).
void expectTrueHeader(const Las& in, const Las& out, const std::string& what) {
  ASSERT_EQ(out.header_size, in.header_size) << what;
  EXPECT_EQ(out.bytes.substr(0, 107), in.bytes.substr(0, 107)) << what << ": header before the counts";
  EXPECT_EQ(out.bytes.substr(131, 48), in.bytes.substr(131, 48)) << what << ": scales and offsets";
  if (in.header_size > 227) {
    const std::size_t upto = in.minor >= 4 ? 247 : in.header_size;
    EXPECT_EQ(out.bytes.substr(227, upto - 227), in.bytes.substr(227, upto - 227))
        << what << ": waveform, EVLRs";
    if (in.header_size > 375) {
      EXPECT_EQ(out.bytes.substr(375, in.header_size - 375), in.bytes.substr(375, in.header_size - 375));
    }
  }
  for (int a = 0; a < 3; ++a) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (std::size_t i = 0; i < out.points; ++i) {
      lo = std::min(lo, out.coord(i, a));
      hi = std::max(hi, out.coord(i, a));
    }
    EXPECT_EQ(at<double>(out.bytes, 179 + 16 * static_cast<std::size_t>(a)), hi) << what << " max " << a;
    EXPECT_EQ(at<double>(out.bytes, 187 + 16 * static_cast<std::size_t>(a)), lo) << what << " min " << a;
  }
  std::uint64_t by_return[15] = {};
  for (std::size_t i = 0; i < out.points; ++i) ++by_return[std::max(out.returnNumber(i), 1) - 1];
  const bool legacy = in.format < 6 || at<std::uint32_t>(in.bytes, 107) != 0;
  EXPECT_EQ(at<std::uint32_t>(out.bytes, 107), legacy ? out.points : 0u) << what;
  for (int k = 0; k < 5; ++k)
    EXPECT_EQ(at<std::uint32_t>(out.bytes, 111 + 4 * static_cast<std::size_t>(k)), legacy ? by_return[k] : 0u)
        << what << " return " << k + 1;
  if (in.minor >= 4) {
    EXPECT_EQ(at<std::uint64_t>(out.bytes, 247), out.points) << what;
    for (int k = 0; k < 15; ++k)
      EXPECT_EQ(at<std::uint64_t>(out.bytes, 255 + 8 * static_cast<std::size_t>(k)), by_return[k])
          << what << " return " << k + 1;
  }
}

std::vector<std::string> laspyFiles() {
  std::vector<std::string> out;
  const fs::path dir = fs::path(hgdtest::sharedDatasetsDir()) / "las";
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec))
    if (e.path().extension() == ".las") out.push_back(e.path().string());
  std::sort(out.begin(), out.end());
  return out;
}

// laspy's files: each reads with the points the test decodes, and written back with no move its
// point records, VLRs and EVLRs are the same bytes and its header is true.
TEST(Las, LaspysFilesReadAndComeBackByteForByte) {
  const std::vector<std::string> files = laspyFiles();
  if (files.empty()) GTEST_SKIP() << "no ../shared/datasets/las here";
  EXPECT_GE(files.size(), 9u);
  TempDir dir;
  for (const std::string& file : files) {
    SCOPED_TRACE(file);
    const Las in(slurp(file));
    const Shape s = hgd::readShape(file);
    ASSERT_EQ(s.format, hgd::FileFormat::Las);
    ASSERT_EQ(s.size(), in.points);
    for (std::size_t i = 0; i < in.points; i += 7) {
      for (int a = 0; a < 3; ++a) ASSERT_EQ(value(s, i, std::string(1, "xyz"[a])), in.coord(i, a)) << i;
      ASSERT_EQ(value(s, i, "return_number"), in.returnNumber(i)) << i;
      ASSERT_EQ(value(s, i, "classification"), in.classification(i)) << i;
      if (in.format != 0 && in.format != 2) {
        ASSERT_EQ(value(s, i, "gps_time"), in.gpsTime(i)) << i;
      }
    }
    const std::string out = dir.file(fs::path(file).filename().string());
    hgd::writeShape(out, s);
    const Las back(slurp(out));
    EXPECT_TRUE(back.records() == in.records()) << "point records differ";
    EXPECT_TRUE(back.vlrs() == in.vlrs()) << "VLRs differ";
    EXPECT_TRUE(back.tail() == in.tail()) << "EVLRs / waveform data differ";
    expectTrueHeader(in, back, file);
  }
}

// The extra bytes of extrabytes.las are fields named as its VLR describes them.
TEST(Las, ExtraBytesAreFieldsNamedByTheirDescriptions) {
  const std::string file = hgdtest::sharedDatasetsDir() + "/las/extrabytes.las";
  if (!hgdtest::exists(file)) GTEST_SKIP() << "no " << file;
  const Las in(slurp(file));
  const Shape s = hgd::readShape(file);
  // The descriptors, read here: 192 bytes each in the LASF_Spec record 4.
  std::size_t v = in.header_size, found = 0;
  for (std::uint32_t k = 0; k < at<std::uint32_t>(in.bytes, 100); ++k) {
    const std::string user = in.bytes.substr(v + 2, 16).c_str();
    const std::uint16_t id = at<std::uint16_t>(in.bytes, v + 18), len = at<std::uint16_t>(in.bytes, v + 20);
    if (user == "LASF_Spec" && id == 4)
      for (std::size_t d = 0; d + 192 <= len; d += 192) {
        const std::string name = in.bytes.substr(v + 54 + d + 4, 32).c_str();
        EXPECT_GE(hgd::findField(s.cloud, name), 0) << name;
        ++found;
      }
    v += 54 + len;
  }
  EXPECT_GT(found, 3u);
}

// A file of every version and point format, written by the test from the specification with
// random values in every field and 3 extra bytes: read with each value, written back the same.
TEST(Las, EveryVersionAndPointFormat) {
  TempDir dir;
  std::mt19937 rng(17);
  const std::size_t standard[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
  for (int minor = 0; minor <= 4; ++minor)
    for (int format = 0; format <= 10; ++format) {
      if ((minor < 3 && format > 3) || (minor == 3 && format > 5)) continue;  // as the versions allow
      SCOPED_TRACE("LAS 1." + std::to_string(minor) + " format " + std::to_string(format));
      const std::size_t header = minor >= 4   ? 375
                                 : minor == 3 ? 235
                                              : 227,
                        length = standard[format] + 3, n = 50;
      std::string b(header + n * length, '\0');
      b.replace(0, 4, "LASF");
      b[24] = 1;
      b[25] = static_cast<char>(minor);
      put<std::uint16_t>(b, 94, static_cast<std::uint16_t>(header));
      put<std::uint32_t>(b, 96, static_cast<std::uint32_t>(header));
      b[104] = static_cast<char>(format);
      put<std::uint16_t>(b, 105, static_cast<std::uint16_t>(length));
      put<std::uint32_t>(b, 107, format < 6 ? static_cast<std::uint32_t>(n) : 0u);
      if (minor >= 4) put<std::uint64_t>(b, 247, n);
      const double scale[3] = {0.01, 0.001, 0.0001}, offset[3] = {500000, 4000000, -20};
      for (int a = 0; a < 3; ++a) {
        put<double>(b, 131 + 8 * static_cast<std::size_t>(a), scale[a]);
        put<double>(b, 155 + 8 * static_cast<std::size_t>(a), offset[a]);
      }
      for (std::size_t i = 0; i < n; ++i)
        for (std::size_t k = 0; k < length; ++k) b[header + i * length + k] = static_cast<char>(rng() & 255);
      // NaN GPS times and wave locations would not compare: give the doubles and floats values.
      for (std::size_t i = 0; i < n; ++i) {
        const std::size_t r = header + i * length;
        for (int a = 0; a < 3; ++a)
          put<std::int32_t>(b, r + 4 * static_cast<std::size_t>(a),
                            static_cast<std::int32_t>(rng() % 200000) - 100000);
        if (format == 1 || format == 3 || format == 4 || format == 5)
          put<double>(b, r + 20, 1e5 + 0.25 * static_cast<double>(i));
        if (format >= 6) put<double>(b, r + 22, 2e8 + 0.125 * static_cast<double>(i));
        const std::size_t wave = format == 4    ? 28
                                 : format == 5  ? 34
                                 : format == 9  ? 30
                                 : format == 10 ? 38
                                                : 0;
        if (wave) {
          put<std::uint64_t>(b, r + wave + 1, rng() % 100000);  // a byte offset
          for (int k = 0; k < 4; ++k)
            put<float>(b, r + wave + 13 + 4 * static_cast<std::size_t>(k), 0.5f * static_cast<float>(k + i));
        }
      }
      Las in(b);
      put<double>(in.bytes, 179, 0.0);  // bounds: the writer makes them true
      const std::string path = dir.file("f.las");
      writeText(path, in.bytes);
      const Shape s = hgd::readShape(path);
      ASSERT_EQ(s.size(), n);
      EXPECT_GE(hgd::findField(s.cloud, "extra_bytes"), 0);
      if (format == 2 || format == 3 || format == 5 || format == 7 || format == 8 || format == 10) {
        EXPECT_GE(hgd::findField(s.cloud, "red"), 0);
        if (format == 8 || format == 10) {
          EXPECT_GE(hgd::findField(s.cloud, "nir"), 0);
        }
      }
      if (format >= 6) {
        EXPECT_GE(hgd::findField(s.cloud, "scanner_channel"), 0);
      }
      for (std::size_t i = 0; i < n; ++i) {
        for (int a = 0; a < 3; ++a) ASSERT_EQ(value(s, i, std::string(1, "xyz"[a])), in.coord(i, a));
        ASSERT_EQ(value(s, i, "return_number"), in.returnNumber(i));
        ASSERT_EQ(value(s, i, "classification"), in.classification(i));
        ASSERT_EQ(value(s, i, "intensity"), at<std::uint16_t>(in.bytes, header + i * length + 12));
      }
      const std::string out = dir.file("g.las");
      hgd::writeShape(out, s);
      const Las back(slurp(out));
      EXPECT_TRUE(back.records() == in.records());
      // The counts by return, computed here.
      std::uint64_t by_return[15] = {};
      for (std::size_t i = 0; i < n; ++i)
        ++by_return[std::max(in.returnNumber(i), 1) - 1];  // 0 counts as a first return
      if (format < 6) {
        for (int k = 0; k < 5; ++k)
          EXPECT_EQ(at<std::uint32_t>(back.bytes, 111 + 4 * static_cast<std::size_t>(k)), by_return[k]);
      }
      if (minor >= 4) {
        for (int k = 0; k < 15; ++k)
          EXPECT_EQ(at<std::uint64_t>(back.bytes, 255 + 8 * static_cast<std::size_t>(k)), by_return[k]);
      }
    }
}

// A drag on a LAS scan: moved points are requantised with the file's scale and offset, the
// fixed ones come back as the same record bytes, the header's bounds are the new points'.
TEST(Las, ADeformedScanKeepsItsUnmovedRecordsAndATrueHeader) {
  const std::string file = hgdtest::sharedDatasetsDir() + "/las/simple.las";
  if (!hgdtest::exists(file)) GTEST_SKIP() << "no " << file;
  const Las in(slurp(file));
  double lo = 1e300, hi = -1e300;
  for (std::size_t i = 0; i < in.points; ++i) {
    lo = std::min(lo, in.coord(i, 0));
    hi = std::max(hi, in.coord(i, 0));
  }
  TempDir dir;
  const double cut = lo + 0.2 * (hi - lo), grab = hi - 0.2 * (hi - lo);
  char json[600];
  std::snprintf(json, sizeof json,
                R"({"fixed": [{"box": {"min": [-1e9, -1e9, -1e9], "max": [%.6f, 1e9, 1e9]}}],
                    "manipulated": {"box": {"min": [%.6f, -1e9, -1e9], "max": [1e9, 1e9, 1e9]}},
                    "clusters": 8, "move": {"frame": {"translate": [0, 0, 25]}}})",
                cut, grab);
  writeText(dir.file("s.json"), json);
  const hgdtest::CommandResult r = hgdtest::shell(
      hgdtest::quote(HGD_TOOL) + " deform " + hgdtest::quote(file) + " -s " +
      hgdtest::quote(dir.file("s.json")) + " -o " + hgdtest::quote(dir.file("out.las")) + " -q");
  ASSERT_EQ(r.code, 0) << r.err;
  const Las out(slurp(dir.file("out.las")));
  ASSERT_EQ(out.points, in.points);
  std::size_t fixed = 0, moved = 0;
  for (std::size_t i = 0; i < in.points; ++i) {
    if (in.coord(i, 0) <= cut) {
      ++fixed;
      ASSERT_TRUE(out.record(i) == in.record(i)) << "fixed point " << i << " was rewritten";
    } else if (in.coord(i, 0) >= grab) {
      ++moved;
      ASSERT_NEAR(out.coord(i, 2) - in.coord(i, 2), 25.0, in.scale[2]) << i;
      // Everything but the coordinates is the same bytes.
      ASSERT_TRUE(out.record(i).substr(12) == in.record(i).substr(12)) << i;
    }
  }
  EXPECT_GT(fixed, 100u);
  EXPECT_GT(moved, 100u);
  EXPECT_TRUE(out.vlrs() == in.vlrs());
  expectTrueHeader(in, out, "deformed");
}

// A point moved past what the header's offset and a 32-bit integer hold: the offset moves by a
// whole number of scale steps, said; nothing wraps, and the other points keep their places.
TEST(Las, AnOffsetMovesRatherThanAnIntegerWrapping) {
  TempDir dir;
  std::string b(227 + 3 * 20, '\0');
  b.replace(0, 4, "LASF");
  b[24] = 1;
  b[25] = 2;
  put<std::uint16_t>(b, 94, 227);
  put<std::uint32_t>(b, 96, 227);
  put<std::uint16_t>(b, 105, 20);
  put<std::uint32_t>(b, 107, 3);
  for (int a = 0; a < 3; ++a) put<double>(b, 131 + 8 * static_cast<std::size_t>(a), 0.001);
  for (std::size_t i = 0; i < 3; ++i) put<std::int32_t>(b, 227 + i * 20, static_cast<std::int32_t>(1000 * i));
  writeText(dir.file("a.las"), b);
  Shape s = hgd::readShape(dir.file("a.las"));
  const int x = hgd::findField(s.cloud, "x");
  hgd::writeValue(s.cloud, 2, s.cloud.fields[static_cast<std::size_t>(x)], 3.0e6);  // 3e9 steps
  const std::string said = hgd::extrasLost(s, hgd::FileFormat::Las);
  EXPECT_NE(said.find("offset moves"), std::string::npos) << said;
  hgd::writeShape(dir.file("b.las"), s);
  const Las back(slurp(dir.file("b.las")));
  EXPECT_NE(back.offset[0], 0.0);
  EXPECT_NEAR(back.coord(2, 0), 3.0e6, 0.0005);
  EXPECT_NEAR(back.coord(0, 0), 0.0, 1e-6);
  EXPECT_NEAR(back.coord(1, 0), 1.0, 1e-6);
}

// LASzip-compressed files are refused naming the file and saying what to do.
TEST(Las, LazIsRefusedWithTheReason) {
  const std::string file = hgdtest::sharedDatasetsDir() + "/las/simple.laz";
  if (!hgdtest::exists(file)) GTEST_SKIP() << "no " << file;
  try {
    hgd::readShape(file);
    ADD_FAILURE() << "a LAZ was read";
  } catch (const hgd::IoError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("simple.laz"), std::string::npos) << m;
    EXPECT_NE(m.find("LASzip-compressed"), std::string::npos) << m;
    EXPECT_NE(m.find("decompress"), std::string::npos) << m;
  }
}

// Another shape written as LAS: coordinates within half a scale step, intensity and colours in
// their LAS places, every other field as extra bytes under its own name.
TEST(Las, APlyBecomesALasWithEveryField) {
  TempDir dir;
  std::string ply =
      "ply\nformat ascii 1.0\nelement vertex 200\nproperty double x\nproperty double y\nproperty double z\n"
      "property ushort intensity\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
      "property float nx\nproperty float ny\nproperty float nz\nproperty float quality\nend_header\n";
  std::mt19937 rng(3);
  for (int i = 0; i < 200; ++i) {
    char row[256];
    std::snprintf(row, sizeof row, "%.6f %.6f %.6f %d %d %d %d 0 0 1 %.3f\n", 651000.0 + 0.01 * i,
                  4.2e6 + 0.02 * (i % 13), 120.0 + 0.001 * (i % 7), i * 3, i % 256, (i * 7) % 256, 9,
                  0.5 * i);
    ply += row;
  }
  writeText(dir.file("a.ply"), ply);
  const Shape s = hgd::readShape(dir.file("a.ply"));
  EXPECT_EQ(hgd::extrasLost(s, hgd::FileFormat::Las), "");
  hgd::writeShape(dir.file("a.las"), s);
  const Las las(slurp(dir.file("a.las")));
  EXPECT_EQ(las.format, 7);
  EXPECT_EQ(las.minor, 4);
  const Shape back = hgd::readShape(dir.file("a.las"));
  ASSERT_EQ(back.size(), 200u);
  for (std::size_t i = 0; i < 200; ++i) {
    for (int a = 0; a < 3; ++a)
      ASSERT_NEAR(las.coord(i, a), value(s, i, std::string(1, "xyz"[a])), las.scale[a] / 2) << i;
    ASSERT_EQ(value(back, i, "intensity"), value(s, i, "intensity"));
    ASSERT_EQ(value(back, i, "red"), 257 * value(s, i, "red"));  // LAS colours are 16 bits
    ASSERT_EQ(value(back, i, "quality"), value(s, i, "quality"));
    ASSERT_EQ(value(back, i, "nz"), 1.0);
  }
}

}  // namespace
