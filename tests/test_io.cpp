// Tests of hgdeform's PLY / PCD / OBJ readers and writers. Every file is written by the test
// itself into a fresh temporary directory.
#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "hgdeform/io/fields.h"
#include "hgdeform/io/io.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;
using hgd::IoError;
using hgd::Shape;
using hgdtest::put;
using Field = pcl::PCLPointField;

// --- helpers ---------------------------------------------------------------------------------

class IoTest : public ::testing::Test {
 public:
  void SetUp() override {
    std::random_device rd;
    dir_ = fs::temp_directory_path() /
           ("hgd_test_io_" + std::to_string(::getpid()) + "_" + std::to_string(rd()) + std::to_string(rd()));
    ASSERT_TRUE(fs::create_directories(dir_));
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  std::string write(const std::string& name, const std::string& bytes) const {
    const std::string p = path(name);
    std::ofstream out(p, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.close();
    EXPECT_TRUE(out.good());
    return p;
  }

  std::string slurp(const std::string& p) const {
    std::ifstream in(p, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }

  std::set<std::string> listing() const {
    std::set<std::string> names;
    for (const auto& e : fs::directory_iterator(dir_)) names.insert(e.path().filename().string());
    return names;
  }

  fs::path dir_;
};

/// Runs f and checks it throws an IoError whose message names `path` and contains `phrase`.
void expectIoError(const std::function<void()>& f, const std::string& path, const std::string& phrase) {
  try {
    f();
    ADD_FAILURE() << "no IoError thrown; expected '" << phrase << "' for " << path;
  } catch (const IoError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find(path), std::string::npos) << m;
    EXPECT_NE(m.find(phrase), std::string::npos) << "expected '" << phrase << "' in: " << m;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "unexpected exception type: " << e.what();
  }
}

void expectReadError(const std::string& path, const std::string& phrase) {
  expectIoError([&] { hgd::readShape(path); }, path, phrase);
}

const Field& field(const Shape& s, const std::string& name) {
  const int i = hgd::findField(s.cloud, name);
  EXPECT_GE(i, 0) << "no field " << name;
  return s.cloud.fields.at(static_cast<std::size_t>(std::max(i, 0)));
}

double value(const Shape& s, std::size_t point, const std::string& name, std::size_t element = 0) {
  return hgd::readValue(s.cloud, point, field(s, name), element);
}

bool sameValue(double a, double b) {
  return (std::isnan(a) && std::isnan(b)) || a == b;
}

/// Same fields (name, type, count, order), same layout and the same values (NaN == NaN).
void expectSameCloud(const Shape& a, const Shape& b, bool compare_offsets = true) {
  ASSERT_EQ(a.cloud.width, b.cloud.width);
  ASSERT_EQ(a.cloud.height, b.cloud.height);
  ASSERT_EQ(a.cloud.fields.size(), b.cloud.fields.size());
  for (std::size_t k = 0; k < a.cloud.fields.size(); ++k) {
    const Field& fa = a.cloud.fields[k];
    const Field& fb = b.cloud.fields[k];
    EXPECT_EQ(fa.name, fb.name);
    EXPECT_EQ(fa.datatype, fb.datatype) << fa.name;
    EXPECT_EQ(fa.count, fb.count) << fa.name;
    if (compare_offsets) {
      EXPECT_EQ(fa.offset, fb.offset) << fa.name;
    }
  }
  if (compare_offsets) {
    EXPECT_EQ(a.cloud.point_step, b.cloud.point_step);
  }
  for (std::size_t i = 0; i < a.size(); ++i)
    for (std::size_t k = 0; k < a.cloud.fields.size(); ++k) {
      if (a.cloud.fields[k].name == "_") continue;
      for (std::size_t e = 0; e < std::max<std::uint32_t>(a.cloud.fields[k].count, 1); ++e) {
        const double va = hgd::readValue(a.cloud, i, a.cloud.fields[k], e);
        const double vb = hgd::readValue(b.cloud, i, b.cloud.fields[k], e);
        EXPECT_TRUE(sameValue(va, vb))
            << "point " << i << " field " << a.cloud.fields[k].name << ": " << va << " vs " << vb;
      }
    }
}

void expectSamePolygons(const Shape& a, const Shape& b) {
  ASSERT_EQ(a.polygons.size(), b.polygons.size());
  for (std::size_t i = 0; i < a.polygons.size(); ++i)
    EXPECT_EQ(a.polygons[i].vertices, b.polygons[i].vertices);
}

// --- the sample PLY: float xyz, uchar colour, float intensity, int label -------------------------

struct Vert {
  float x, y, z;
  std::uint8_t r, g, b;
  float intensity;
  std::int32_t label;
};
const std::vector<Vert> kVerts = {
    {0.5f, -1.25f, 3.f, 255, 0, 17, 0.75f, -3},
    {1e-3f, 2.5e10f, -0.f, 1, 2, 3, 100.125f, 2147483647},
    {0.1f, 0.2f, 0.3f, 10, 20, 30, -5.5f, std::numeric_limits<std::int32_t>::min()},
    {1.f, 2.f, 3.f, 0, 0, 0, 0.f, 0},
};

std::string plyHeader(const std::string& format, std::size_t n, const std::string& extra = "") {
  return "ply\nformat " + format + " 1.0\ncomment test file\nobj_info hgdeform\nelement vertex " +
         std::to_string(n) +
         "\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar green\n"
         "property uchar blue\nproperty float intensity\nproperty int label\n" +
         extra + "end_header\n";
}

std::string samplePlyAscii() {
  std::ostringstream s;
  s.precision(9);
  s << plyHeader("ascii", kVerts.size());
  for (const auto& v : kVerts)
    s << v.x << ' ' << v.y << ' ' << v.z << ' ' << int(v.r) << ' ' << int(v.g) << ' ' << int(v.b) << ' '
      << v.intensity << ' ' << v.label << '\n';
  return s.str();
}

std::string samplePlyBinary(bool big) {
  std::string s = plyHeader(big ? "binary_big_endian" : "binary_little_endian", kVerts.size());
  for (const auto& v : kVerts) {
    put(s, v.x, big);
    put(s, v.y, big);
    put(s, v.z, big);
    put(s, v.r, big);
    put(s, v.g, big);
    put(s, v.b, big);
    put(s, v.intensity, big);
    put(s, v.label, big);
  }
  return s;
}

void checkSample(const Shape& s) {
  ASSERT_EQ(s.size(), kVerts.size());
  EXPECT_EQ(s.cloud.height, 1u);
  const std::vector<std::string> names = {"x", "y", "z", "red", "green", "blue", "intensity", "label"};
  const std::vector<std::uint8_t> types = {Field::FLOAT32, Field::FLOAT32, Field::FLOAT32, Field::UINT8,
                                           Field::UINT8,   Field::UINT8,   Field::FLOAT32, Field::INT32};
  ASSERT_EQ(s.cloud.fields.size(), names.size());
  std::uint32_t off = 0;
  for (std::size_t k = 0; k < names.size(); ++k) {
    EXPECT_EQ(s.cloud.fields[k].name, names[k]);
    EXPECT_EQ(s.cloud.fields[k].datatype, types[k]) << names[k];
    EXPECT_EQ(s.cloud.fields[k].count, 1u);
    EXPECT_EQ(s.cloud.fields[k].offset, off);
    off += static_cast<std::uint32_t>(hgd::datatypeSize(types[k]));
  }
  EXPECT_EQ(s.cloud.point_step, off);
  EXPECT_TRUE(s.cloud.is_dense);
  for (std::size_t i = 0; i < kVerts.size(); ++i) {
    const Vert& v = kVerts[i];
    EXPECT_EQ(value(s, i, "x"), v.x);
    EXPECT_EQ(value(s, i, "y"), v.y);
    EXPECT_EQ(value(s, i, "z"), v.z);
    EXPECT_EQ(value(s, i, "red"), v.r);
    EXPECT_EQ(value(s, i, "green"), v.g);
    EXPECT_EQ(value(s, i, "blue"), v.b);
    EXPECT_EQ(value(s, i, "intensity"), v.intensity);
    EXPECT_EQ(value(s, i, "label"), v.label);
  }
}

/// Reads `p`, checks it, and checks that binary and ascii PLY and PCD rewrites read back equal.
void roundTrip(const IoTest& t, const std::string& p, const std::function<void(const Shape&)>& check,
               const std::vector<std::string>& exts = {".ply", ".pcd"}) {
  const Shape s = hgd::readShape(p);
  check(s);
  for (const std::string& ext : exts)
    for (const auto enc : {hgd::Encoding::Binary, hgd::Encoding::Ascii}) {
      SCOPED_TRACE(ext + (enc == hgd::Encoding::Ascii ? " ascii" : " binary"));
      const std::string out = t.path(std::string("rt") + (enc == hgd::Encoding::Ascii ? "_a" : "_b") + ext);
      hgd::writeShape(out, s, {enc});
      Shape back = hgd::readShape(out);
      // Another format has its own names for some fields (a PLY's red green blue are a PCD's
      // packed rgb): written back in the shape's own format, they are what they were.
      if (back.format != s.format) {
        const std::string again = t.path(std::string("again") + fs::path(p).extension().string());
        hgd::writeShape(again, back, {enc});
        back = hgd::readShape(again);
        back.path = out;
      }
      check(back);
      expectSameCloud(s, back);
      if (ext == ".ply") expectSamePolygons(s, back);
      EXPECT_EQ(back.path, out);
    }
}

// --- PLY -------------------------------------------------------------------------------------

TEST_F(IoTest, PlyAsciiRoundTrip) {
  const std::string p = write("a.ply", samplePlyAscii());
  const Shape s = hgd::readShape(p);
  EXPECT_EQ(s.path, p);
  EXPECT_EQ(s.format, hgd::FileFormat::Ply);
  EXPECT_FALSE(s.isMesh());
  roundTrip(*this, p, checkSample);
}

TEST_F(IoTest, PlyBinaryLittleEndianRoundTrip) {
  roundTrip(*this, write("le.ply", samplePlyBinary(false)), checkSample);
}

TEST_F(IoTest, PlyBinaryBigEndianRoundTrip) {
  roundTrip(*this, write("be.ply", samplePlyBinary(true)), checkSample);
}

// Written in the byte order it was read in (issue 48: a big-endian PLY came back little-endian).
TEST_F(IoTest, PlyWrittenBinaryKeepsItsByteOrderAndOwnTypes) {
  const Shape le = hgd::readShape(write("le.ply", samplePlyBinary(false)));
  hgd::writeShape(path("le_out.ply"), le);
  EXPECT_NE(slurp(path("le_out.ply")).find("format binary_little_endian 1.0"), std::string::npos);
  const Shape s = hgd::readShape(write("in.ply", samplePlyBinary(true)));
  const std::string out = path("out.ply");
  hgd::writeShape(out, s);
  const std::string text = slurp(out);
  EXPECT_NE(text.find("format binary_big_endian 1.0"), std::string::npos);
  EXPECT_NE(text.find("property uchar red\n"), std::string::npos);
  EXPECT_NE(text.find("property int label\n"), std::string::npos);
  EXPECT_EQ(text.find("element face"), std::string::npos);
  // Header + 4 records of 23 bytes, nothing else.
  EXPECT_EQ(text.size(), text.find("end_header\n") + 11 + 4 * 23);
  hgd::writeShape(path("out_a.ply"), s, {hgd::Encoding::Ascii});
  EXPECT_NE(slurp(path("out_a.ply")).find("format ascii 1.0"), std::string::npos);
}

TEST_F(IoTest, PlyCrlfAndAlternativeTypeNames) {
  std::string text =
      "ply\r\nformat ascii 1.0\r\ncomment made on windows\r\nelement vertex 2\r\nproperty float32 x\r\n"
      "property float32 y\r\nproperty float64 z\r\nproperty uint8 flags\r\nproperty int16 s\r\n"
      "end_header\r\n1.5 2.5 3.25 7 -12\r\n-1 -2 -3 255 32767\r\n";
  const Shape s = hgd::readShape(write("crlf.ply", text));
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(field(s, "x").datatype, Field::FLOAT32);
  EXPECT_EQ(field(s, "z").datatype, Field::FLOAT64);
  EXPECT_EQ(field(s, "flags").datatype, Field::UINT8);
  EXPECT_EQ(field(s, "s").datatype, Field::INT16);
  EXPECT_EQ(value(s, 0, "z"), 3.25);
  EXPECT_EQ(value(s, 0, "s"), -12);
  EXPECT_EQ(value(s, 1, "flags"), 255);
  EXPECT_EQ(value(s, 1, "s"), 32767);
}

TEST_F(IoTest, PlyDoubleCoordinatesKeepTheirValues) {
  const double xs[3][3] = {{1234567.125, -9876543.0625, 0.1}, {1e-300, 4503599627370497.0, -2.5}, {0, 1, 2}};
  std::string s =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
      "property double z\nend_header\n";
  for (const auto& v : xs)
    for (const double c : v) put(s, c);
  const auto check = [&](const Shape& shape) {
    ASSERT_EQ(shape.size(), 3u);
    for (const char* n : {"x", "y", "z"}) EXPECT_EQ(field(shape, n).datatype, Field::FLOAT64);
    for (std::size_t i = 0; i < 3; ++i) {
      EXPECT_EQ(value(shape, i, "x"), xs[i][0]);
      EXPECT_EQ(value(shape, i, "y"), xs[i][1]);
      EXPECT_EQ(value(shape, i, "z"), xs[i][2]);
    }
  };
  roundTrip(*this, write("d.ply", s), check);
  const Shape shape = hgd::readShape(path("d.ply"));
  EXPECT_EQ(value(shape, 0, "x"), 1234567.125);
  hgd::writeShape(path("d_a.ply"), shape, {hgd::Encoding::Ascii});
  EXPECT_NE(slurp(path("d_a.ply")).find("property double x"), std::string::npos);
}

std::string meshPly(const std::string& format, bool big) {
  // 4 vertices with a list property in the vertex element (skipped), a face element with an extra
  // scalar before the index list and a list after it, and an edge element (skipped).
  std::string h =
      "ply\nformat " + format +
      " 1.0\nelement vertex 4\nproperty float x\nproperty list uchar int junk\nproperty float y\n"
      "property float z\nelement face 2\nproperty uchar flags\nproperty list uchar int vertex_indices\n"
      "property list uchar float texcoord\nelement edge 1\nproperty int vertex1\nproperty int vertex2\n"
      "end_header\n";
  const float v[4][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0.5f}};
  if (format == "ascii") {
    return h +
           "0 2 7 8 0 0\n1 0 0 0\n1 1 7 1 0\n0 0 1 0.5\n"
           "9 3 0 1 2 2 0.5 0.5\n0 4 0 1 2 3 0\n0 3\n";
  }
  for (int i = 0; i < 4; ++i) {
    put(h, v[i][0], big);
    const std::uint8_t n = static_cast<std::uint8_t>(i % 3);
    put(h, n, big);
    for (int k = 0; k < n; ++k) put(h, std::int32_t{k + 7}, big);
    put(h, v[i][1], big);
    put(h, v[i][2], big);
  }
  put(h, std::uint8_t{9}, big);
  put(h, std::uint8_t{3}, big);
  for (const std::int32_t i : {0, 1, 2}) put(h, i, big);
  put(h, std::uint8_t{2}, big);
  put(h, 0.5f, big);
  put(h, 0.5f, big);
  put(h, std::uint8_t{0}, big);
  put(h, std::uint8_t{4}, big);
  for (const std::int32_t i : {0, 1, 2, 3}) put(h, i, big);
  put(h, std::uint8_t{0}, big);
  put(h, std::int32_t{0}, big);
  put(h, std::int32_t{3}, big);
  return h;
}

void checkMesh(const Shape& s) {
  ASSERT_EQ(s.size(), 4u);
  ASSERT_EQ(s.cloud.fields.size(), 3u);
  EXPECT_EQ(s.cloud.fields[0].name, "x");
  EXPECT_EQ(s.cloud.fields[1].name, "y");
  EXPECT_EQ(s.cloud.fields[2].name, "z");
  EXPECT_EQ(value(s, 2, "x"), 1.0);
  EXPECT_EQ(value(s, 2, "y"), 1.0);
  EXPECT_EQ(value(s, 3, "z"), 0.5);
  ASSERT_EQ(s.polygons.size(), 2u);
  EXPECT_EQ(s.polygons[0].vertices, (pcl::Indices{0, 1, 2}));
  EXPECT_EQ(s.polygons[1].vertices, (pcl::Indices{0, 1, 2, 3}));
  EXPECT_TRUE(s.isMesh());
}

TEST_F(IoTest, PlyMeshAsciiRoundTripKeepsFaces) {
  roundTrip(*this, write("m.ply", meshPly("ascii", false)), checkMesh, {".ply"});
}

TEST_F(IoTest, PlyMeshBinaryLittleEndianRoundTripKeepsFaces) {
  roundTrip(*this, write("m.ply", meshPly("binary_little_endian", false)), checkMesh, {".ply"});
}

TEST_F(IoTest, PlyMeshBinaryBigEndianRoundTripKeepsFaces) {
  roundTrip(*this, write("m.ply", meshPly("binary_big_endian", true)), checkMesh, {".ply"});
}

TEST_F(IoTest, MeshWrittenAsPcdKeepsPointsOnly) {
  const Shape s = hgd::readShape(write("m.ply", meshPly("binary_little_endian", false)));
  hgd::writeShape(path("m.pcd"), s);
  const Shape back = hgd::readShape(path("m.pcd"));
  EXPECT_FALSE(back.isMesh());
  expectSameCloud(s, back);
}

TEST_F(IoTest, PlyWriterExpandsMultiValueFieldsAndSkipsPadding) {
  // A cloud with a COUNT 3 field and a padding field, as read from a PCD.
  std::string pcd =
      "VERSION 0.7\nFIELDS x y z normal _\nSIZE 4 4 4 4 1\nTYPE F F F F U\nCOUNT 1 1 1 3 2\nWIDTH 1\nHEIGHT "
      "1\n"
      "POINTS 1\nDATA binary\n";
  for (const float f : {1.f, 2.f, 3.f, 0.f, 0.6f, 0.8f}) put(pcd, f);
  put(pcd, std::uint16_t{0});
  const Shape s = hgd::readShape(write("n.pcd", pcd));
  hgd::writeShape(path("n.ply"), s, {hgd::Encoding::Ascii});
  const std::string text = slurp(path("n.ply"));
  EXPECT_NE(text.find("property float normal_0\nproperty float normal_1\nproperty float normal_2\n"),
            std::string::npos);
  EXPECT_EQ(text.find("property uchar _"), std::string::npos);
  const Shape back = hgd::readShape(path("n.ply"));
  EXPECT_EQ(value(back, 0, "normal_1"), 0.6f);
  EXPECT_EQ(value(back, 0, "normal_2"), 0.8f);
  EXPECT_EQ(value(back, 0, "z"), 3.f);
}

// --- PCD -------------------------------------------------------------------------------------

struct PcdPoint {
  float x, y, z;
  std::uint32_t rgb;
  float normal[3];
  std::int16_t label;
};
const std::vector<PcdPoint> kPcd = {
    {0.5f, 1.5f, -2.f, 0xff0000u, {0, 0, 1}, -7},     {1e-7f, 3e8f, 0.1f, 0x00ff00u, {0.6f, 0.8f, 0}, 32767},
    {-1.f, -2.f, -3.f, 0x0000ffu, {1, 0, 0}, -32768}, {4.f, 5.f, 6.f, 0xffffffffu, {0, 1, 0}, 0},
    {7.25f, 8.5f, 9.75f, 0u, {0.f, 0.f, -1.f}, 12},
};
// Fields: x y z rgb normal[3] _[2] label  -> 4+4+4+4+12+2+2 = 32 bytes.
const char* kPcdFields =
    "FIELDS x y z rgb normal _ label\nSIZE 4 4 4 4 4 1 2\nTYPE F F F U F U I\nCOUNT 1 1 1 1 3 2 1\n";

std::string pcdHeader(const std::string& data, std::size_t n) {
  return "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n" + std::string(kPcdFields) + "WIDTH " +
         std::to_string(n) + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + std::to_string(n) + "\nDATA " +
         data + "\n";
}

std::string pcdRecord(const PcdPoint& p) {
  std::string s;
  put(s, p.x);
  put(s, p.y);
  put(s, p.z);
  put(s, p.rgb);
  for (const float n : p.normal) put(s, n);
  put(s, std::uint16_t{0});
  put(s, p.label);
  return s;
}

std::string pcdBinary() {
  std::string s = pcdHeader("binary", kPcd.size());
  for (const auto& p : kPcd) s += pcdRecord(p);
  return s;
}

std::string pcdAscii() {
  std::ostringstream s;
  s.precision(9);
  s << pcdHeader("ascii", kPcd.size());
  for (const auto& p : kPcd)  // no values for the padding field, as PCL writes
    s << p.x << ' ' << p.y << ' ' << p.z << ' ' << p.rgb << ' ' << p.normal[0] << ' ' << p.normal[1] << ' '
      << p.normal[2] << ' ' << p.label << '\n';
  return s.str();
}

/// A small LZF encoder (literal runs and back references), so that the test does not need
/// PCL's io library: the reader decompresses with pcl::lzfDecompress.
std::string lzfEncode(const std::string& in) {
  std::string out, lit;
  const auto flush = [&] {
    for (std::size_t b = 0; b < lit.size(); b += 32) {
      const std::size_t n = std::min<std::size_t>(32, lit.size() - b);
      out += static_cast<char>(n - 1);
      out.append(lit, b, n);
    }
    lit.clear();
  };
  std::size_t i = 0;
  while (i < in.size()) {
    std::size_t best = 0, best_off = 0;
    for (std::size_t j = i > 8191 ? i - 8191 : 0; j < i; ++j) {
      std::size_t l = 0;
      while (i + l < in.size() && j + l < i && l < 264 && in[j + l] == in[i + l]) ++l;
      if (l > best) {
        best = l;
        best_off = i - j - 1;
      }
    }
    if (best < 3) {
      lit += in[i++];
      continue;
    }
    flush();
    const std::size_t len = best - 2;
    if (len < 7) {
      out += static_cast<char>((len << 5) | (best_off >> 8));
    } else {
      out += static_cast<char>((7 << 5) | (best_off >> 8));
      out += static_cast<char>(len - 7);
    }
    out += static_cast<char>(best_off & 0xff);
    i += best;
  }
  flush();
  return out;
}

/// binary_compressed: sizes, then LZF of the structure-of-arrays layout.
std::string pcdCompressed(bool with_padding_data) {
  std::string soa;
  for (const auto& p : kPcd) put(soa, p.x);
  for (const auto& p : kPcd) put(soa, p.y);
  for (const auto& p : kPcd) put(soa, p.z);
  for (const auto& p : kPcd) put(soa, p.rgb);
  for (const auto& p : kPcd)
    for (const float n : p.normal) put(soa, n);
  if (with_padding_data)
    for (std::size_t i = 0; i < kPcd.size(); ++i) put(soa, std::uint16_t{0});
  for (const auto& p : kPcd) put(soa, p.label);
  const std::string packed = lzfEncode(soa);
  EXPECT_LT(packed.size(), soa.size());  // back references were used
  std::string s = pcdHeader("binary_compressed", kPcd.size());
  put(s, static_cast<std::uint32_t>(packed.size()));
  put(s, static_cast<std::uint32_t>(soa.size()));
  return s + packed;
}

void checkPcd(const Shape& s) {
  ASSERT_EQ(s.size(), kPcd.size());
  const std::vector<std::string> names = {"x", "y", "z", "rgb", "normal", "_", "label"};
  const std::vector<std::uint8_t> types = {Field::FLOAT32, Field::FLOAT32, Field::FLOAT32, Field::UINT32,
                                           Field::FLOAT32, Field::UINT8,   Field::INT16};
  const std::vector<std::uint32_t> counts = {1, 1, 1, 1, 3, 2, 1};
  ASSERT_EQ(s.cloud.fields.size(), names.size());
  for (std::size_t k = 0; k < names.size(); ++k) {
    EXPECT_EQ(s.cloud.fields[k].name, names[k]);
    EXPECT_EQ(s.cloud.fields[k].datatype, types[k]);
    EXPECT_EQ(s.cloud.fields[k].count, counts[k]);
  }
  EXPECT_EQ(s.cloud.point_step, 32u);
  for (std::size_t i = 0; i < kPcd.size(); ++i) {
    const PcdPoint& p = kPcd[i];
    EXPECT_EQ(value(s, i, "x"), p.x);
    EXPECT_EQ(value(s, i, "y"), p.y);
    EXPECT_EQ(value(s, i, "z"), p.z);
    EXPECT_EQ(value(s, i, "rgb"), p.rgb);
    for (std::size_t k = 0; k < 3; ++k) EXPECT_EQ(value(s, i, "normal", k), p.normal[k]);
    EXPECT_EQ(value(s, i, "label"), p.label);
  }
}

TEST_F(IoTest, PcdAsciiBinaryAndCompressedLoadIdenticalValues) {
  const Shape a = hgd::readShape(write("a.pcd", pcdAscii()));
  const Shape b = hgd::readShape(write("b.pcd", pcdBinary()));
  const Shape c = hgd::readShape(write("c.pcd", pcdCompressed(true)));
  const Shape d = hgd::readShape(write("d.pcd", pcdCompressed(false)));
  for (const Shape* s : {&a, &b, &c, &d}) {
    SCOPED_TRACE(s->path);
    EXPECT_EQ(s->format, hgd::FileFormat::Pcd);
    checkPcd(*s);
    expectSameCloud(b, *s);
    EXPECT_EQ(s->cloud.data, b.cloud.data);  // padding bytes are zero everywhere
  }
}

TEST_F(IoTest, PcdRoundTrips) {
  const Shape s = hgd::readShape(write("c.pcd", pcdCompressed(true)));
  // Compressed as it was read, and every byte of the data back, padding included.
  hgd::writeShape(path("z.pcd"), s);
  EXPECT_NE(slurp(path("z.pcd")).find("DATA binary_compressed\n"), std::string::npos);
  const Shape z = hgd::readShape(path("z.pcd"));
  checkPcd(z);
  EXPECT_EQ(s.cloud.data, z.cloud.data);
  EXPECT_TRUE(z.extras.pcd_compressed);
  // Binary keeps everything, padding included, byte for byte.
  Shape plain = s;
  plain.extras.pcd_compressed = false;
  hgd::writeShape(path("b.pcd"), plain);
  const Shape b = hgd::readShape(path("b.pcd"));
  checkPcd(b);
  expectSameCloud(s, b);
  EXPECT_EQ(s.cloud.data, b.cloud.data);
  EXPECT_EQ(slurp(path("b.pcd")).find("DATA binary\n") + 12 + 5 * 32, slurp(path("b.pcd")).size());
  // Ascii drops the padding field and keeps all the others.
  hgd::writeShape(path("a.pcd"), s, {hgd::Encoding::Ascii});
  EXPECT_NE(slurp(path("a.pcd")).find("DATA ascii\n"), std::string::npos);
  const Shape a = hgd::readShape(path("a.pcd"));
  ASSERT_EQ(a.cloud.fields.size(), 6u);
  EXPECT_EQ(hgd::findField(a.cloud, "_"), -1);
  for (std::size_t i = 0; i < kPcd.size(); ++i) {
    for (const char* n : {"x", "y", "z", "rgb", "label"}) EXPECT_EQ(value(a, i, n), value(s, i, n));
    for (std::size_t k = 0; k < 3; ++k) EXPECT_EQ(value(a, i, "normal", k), kPcd[i].normal[k]);
  }
  // PLY expands normal into normal_0.. and drops the padding.
  hgd::writeShape(path("p.ply"), s);
  const Shape p = hgd::readShape(path("p.ply"));
  EXPECT_EQ(value(p, 1, "normal_1"), 0.8f);
  EXPECT_EQ(field(p, "label").datatype, Field::INT16);
  EXPECT_EQ(value(p, 2, "label"), -32768);
}

TEST_F(IoTest, PcdAsciiAcceptsPaddingValuesNanAndInf) {
  std::string text = pcdHeader("ascii", 2);
  text += "nan NaN inf 1 0 0 1 5\n1 2 -inf 2 0 1 0 9 9 -5\n";  // second line carries padding values
  const Shape s = hgd::readShape(write("n.pcd", text));
  EXPECT_TRUE(std::isnan(value(s, 0, "x")));
  EXPECT_TRUE(std::isnan(value(s, 0, "y")));
  EXPECT_EQ(value(s, 0, "z"), std::numeric_limits<double>::infinity());
  EXPECT_EQ(value(s, 1, "z"), -std::numeric_limits<double>::infinity());
  EXPECT_EQ(value(s, 0, "label"), 5);
  EXPECT_EQ(value(s, 1, "label"), -5);
  EXPECT_FALSE(s.cloud.is_dense);
}

std::string organizedPcd(std::vector<std::size_t>* nan_points) {
  std::string s =
      "# organized\nVERSION .7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 4\n"
      "HEIGHT 3\nVIEWPOINT 1 2 3 0.70710677 0 0.70710677 0\nPOINTS 12\nDATA binary\n";
  *nan_points = {1, 6, 11};
  for (std::size_t i = 0; i < 12; ++i) {
    const bool nan = std::find(nan_points->begin(), nan_points->end(), i) != nan_points->end();
    const float q = std::numeric_limits<float>::quiet_NaN();
    put(s, nan ? q : static_cast<float>(i % 4));
    put(s, nan ? q : static_cast<float>(i / 4));
    put(s, nan ? q : 1.5f);
    put(s, static_cast<float>(i) * 10);
  }
  return s;
}

TEST_F(IoTest, OrganizedPcdKeepsWidthHeightNanAndViewpoint) {
  std::vector<std::size_t> nans;
  const Shape s = hgd::readShape(write("o.pcd", organizedPcd(&nans)));
  for (const auto enc : {hgd::Encoding::Binary, hgd::Encoding::Ascii}) {
    const std::string out = path(enc == hgd::Encoding::Ascii ? "oa.pcd" : "ob.pcd");
    hgd::writeShape(out, s, {enc});
    for (const Shape& t : {s, hgd::readShape(out)}) {
      SCOPED_TRACE(t.path);
      EXPECT_EQ(t.cloud.width, 4u);
      EXPECT_EQ(t.cloud.height, 3u);
      EXPECT_TRUE(t.isOrganized());
      EXPECT_EQ(t.size(), 12u);
      EXPECT_FALSE(t.cloud.is_dense);
      for (std::size_t i = 0; i < 12; ++i) {
        const bool nan = std::find(nans.begin(), nans.end(), i) != nans.end();
        EXPECT_EQ(std::isnan(value(t, i, "x")), nan) << i;
        EXPECT_EQ(std::isnan(value(t, i, "z")), nan) << i;
        EXPECT_EQ(value(t, i, "intensity"), static_cast<float>(i) * 10);
        if (!nan) {
          EXPECT_EQ(value(t, i, "y"), static_cast<float>(i / 4));
        }
      }
      EXPECT_EQ(t.sensor_origin, Eigen::Vector4f(1, 2, 3, 0));
      EXPECT_FLOAT_EQ(t.sensor_orientation.w(), 0.70710677f);
      EXPECT_FLOAT_EQ(t.sensor_orientation.y(), 0.70710677f);
      EXPECT_EQ(t.sensor_orientation.x(), 0.f);
    }
  }
}

// --- OBJ -------------------------------------------------------------------------------------

const char* kObj =
    "# a quad\nmtllib quad.mtl\no quad\nv 0 0 0\nv 1234567.123456789 0 0\nv 1 1 0 1.0\nv 0 1 -0.25\n"
    "vt 0 0\nvn 0 0 1\ng group\nusemtl m\ns off\n"
    "f 1/1/1 2/2/2 3/3/3\nf -4 -3 -2 -1\nf 1//1 3//1 4//1\nf 1/1 2/1 3/1\r\nl 1 2\n";

TEST_F(IoTest, ObjFacesInAllFormsAndNegativeIndices) {
  const Shape s = hgd::readShape(write("q.obj", kObj));
  EXPECT_EQ(s.format, hgd::FileFormat::Obj);
  ASSERT_EQ(s.size(), 4u);
  ASSERT_EQ(s.cloud.fields.size(), 3u);
  for (const char* n : {"x", "y", "z"}) EXPECT_EQ(field(s, n).datatype, Field::FLOAT64);
  EXPECT_EQ(value(s, 1, "x"), 1234567.123456789);
  EXPECT_EQ(value(s, 3, "z"), -0.25);
  ASSERT_EQ(s.polygons.size(), 4u);
  EXPECT_EQ(s.polygons[0].vertices, (pcl::Indices{0, 1, 2}));
  EXPECT_EQ(s.polygons[1].vertices, (pcl::Indices{0, 1, 2, 3}));
  EXPECT_EQ(s.polygons[2].vertices, (pcl::Indices{0, 2, 3}));
  EXPECT_EQ(s.polygons[3].vertices, (pcl::Indices{0, 1, 2}));
}

TEST_F(IoTest, ObjRoundTripAndConversionToPly) {
  const Shape s = hgd::readShape(write("q.obj", kObj));
  hgd::writeShape(path("q2.obj"), s);
  const Shape back = hgd::readShape(path("q2.obj"));
  expectSameCloud(s, back);
  expectSamePolygons(s, back);
  hgd::writeShape(path("q.ply"), s);
  const Shape ply = hgd::readShape(path("q.ply"));
  expectSameCloud(s, ply);
  expectSamePolygons(s, ply);
  // And a PLY with float coordinates written as OBJ reads back with the same values.
  const Shape f = hgd::readShape(write("f.ply", samplePlyBinary(false)));
  hgd::writeShape(path("f.obj"), f);
  const Shape fo = hgd::readShape(path("f.obj"));
  for (std::size_t i = 0; i < f.size(); ++i)
    for (const char* n : {"x", "y", "z"})  // written with the shortest digits that round-trip a float
      EXPECT_EQ(static_cast<float>(value(fo, i, n)), value(f, i, n));
}

TEST_F(IoTest, ObjColoursOnlyWhenEveryVertexHasThem) {
  const Shape c = hgd::readShape(write("c.obj", "v 0 0 0 1 0 0.5\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n"));
  ASSERT_EQ(c.cloud.fields.size(), 6u);
  EXPECT_EQ(field(c, "red").datatype, Field::FLOAT32);
  EXPECT_EQ(value(c, 0, "blue"), 0.5);
  EXPECT_EQ(value(c, 1, "green"), 1.0);
  const Shape m = hgd::readShape(write("m.obj", "v 0 0 0 1 0 0.5\nv 1 0 0\nv 0 1 0 0 0 1\n"));
  EXPECT_EQ(m.cloud.fields.size(), 3u);
  EXPECT_FALSE(m.isMesh());
}

// --- read errors -----------------------------------------------------------------------------

TEST_F(IoTest, MissingFile) {
  for (const char* name : {"missing.ply", "missing.pcd", "missing.obj"}) {
    expectReadError(path(name), "cannot open");
    expectReadError(path(name), "No such file or directory");
  }
  fs::create_directory(path("dir.ply"));
  expectReadError(path("dir.ply"), "cannot open");
}

TEST_F(IoTest, EmptyFile) {
  for (const char* name : {"e.ply", "e.pcd", "e.obj"}) expectReadError(write(name, ""), "empty file");
}

TEST_F(IoTest, UnsupportedExtension) {
  // An unknown extension is read by its content (tests/test_formats.cpp); content of no format
  // is refused.
  expectReadError(write("x.e57", "ASTM-E57 not a format hgdeform reads\n"), "matches no format");
  Shape s = hgd::readShape(write("a.ply", samplePlyAscii()));
  expectIoError([&] { hgd::writeShape(path("out.e57"), s); }, path("out.e57"), "unsupported");
  EXPECT_EQ(hgd::formatFromPath("A.PLY"), hgd::FileFormat::Ply);
  EXPECT_EQ(hgd::formatFromPath("dir.x/a.Pcd"), hgd::FileFormat::Pcd);
  EXPECT_EQ(hgd::formatFromPath("a.obj"), hgd::FileFormat::Obj);
}

TEST_F(IoTest, MalformedHeader) {
  expectReadError(write("h1.ply", "plx\nformat ascii 1.0\nend_header\n"), "malformed header");
  expectReadError(write("h2.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"),
                  "malformed header");
  expectReadError(write("h3.ply", "ply\nformat ascii 1.0\nelement vertex abc\nend_header\n"),
                  "malformed header");
  expectReadError(write("h4.ply", "ply\nformat ascii 1.0\nproperty float x\nend_header\n"),
                  "malformed header");
  expectReadError(write("h5.ply", "ply\nelement vertex 1\nproperty float x\nend_header\n1\n"),
                  "malformed header");
  expectReadError(write("h6.ply", "ply\nformat ascii 1.0\nbogus line\nend_header\n"), "malformed header");
  expectReadError(
      write("h7.pcd", "FIELDS x y z\nSIZE 4 4\nTYPE F F F\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2 3\n"),
      "malformed header");
  expectReadError(write("h8.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nBOGUS 1\nDATA ascii\n1 2 3\n"),
                  "malformed header");
  expectReadError(
      write("h9.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nPOINTS 1\nDATA ascii\n1 2 3\n"),
      "malformed header");
  expectReadError(write("h10.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\n"), "malformed header");
  expectReadError(write("h11.pcd", std::string("\x89PNG\r\n\x1a\n\0\0\0", 11)), "malformed header");
  // The message quotes the offending line.
  expectReadError(path("h6.ply"), "bogus line");
}

TEST_F(IoTest, UnsupportedFormatVersionAndType) {
  expectReadError(write("u1.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n"), "unsupported");
  expectReadError(write("u2.ply", "ply\nformat ascii 2.0\nend_header\n"), "unsupported");
  expectReadError(write("u3.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n"),
                  "unsupported");
  expectReadError(write("u4.pcd", "FIELDS x y z\nSIZE 8 8 8\nTYPE I I I\nWIDTH 1\nDATA ascii\n1 2 3\n"),
                  "unsupported");
  expectReadError(write("u5.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA zip\n1 2 3\n"),
                  "unsupported");
  expectReadError(
      write("u6.pcd", "VERSION 9.9\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n"),
      "unsupported");
}

TEST_F(IoTest, TruncatedBinaryData) {
  std::string ply = samplePlyBinary(false);
  expectReadError(write("t1.ply", ply.substr(0, ply.size() - 5)), "truncated data");
  std::string mesh = meshPly("binary_little_endian", false);
  expectReadError(write("t2.ply", mesh.substr(0, mesh.size() - 9)), "truncated data");
  std::string pcd = pcdBinary();
  expectReadError(write("t3.pcd", pcd.substr(0, pcd.size() - 1)), "truncated data");
  std::string cpcd = pcdCompressed(true);
  expectReadError(write("t4.pcd", cpcd.substr(0, cpcd.size() - 3)), "truncated data");
  // The message gives the expected and the actual amount.
  expectReadError(path("t3.pcd"), "5 points of 32 bytes (160 bytes)");
  expectReadError(path("t3.pcd"), "159");
  std::string ascii = samplePlyAscii();
  expectReadError(write("t5.ply", ascii.substr(0, ascii.rfind("1 2 3"))), "truncated data");
}

TEST_F(IoTest, HugeDeclaredCountsAreTruncatedNotAllocated) {
  const std::string n = "1000000000000";
  expectReadError(write("g1.ply", "ply\nformat binary_little_endian 1.0\nelement vertex " + n +
                                      "\nproperty float x\nproperty float y\nproperty float z\nend_header\n" +
                                      std::string(24, '\0')),
                  "truncated data");
  expectReadError(
      write("g2.ply", "ply\nformat ascii 1.0\nelement vertex " + n +
                          "\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n"),
      "truncated data");
  expectReadError(
      write("g3.ply",
            "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n"
            "property float y\nproperty float z\nelement face " +
                n + "\nproperty list uchar int vertex_indices\nend_header\n" + std::string(12, '\0')),
      "truncated data");
  const std::string fields = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n";
  expectReadError(write("g4.pcd", fields + "WIDTH " + n + "\nHEIGHT 1\nPOINTS " + n + "\nDATA binary\n" +
                                      std::string(12, '\0')),
                  "truncated data");
  expectReadError(
      write("g5.pcd", fields + "WIDTH " + n + "\nHEIGHT 1\nPOINTS " + n + "\nDATA ascii\n1 2 3\n"),
      "truncated data");
  std::string c = fields + "WIDTH " + n + "\nHEIGHT 1\nPOINTS " + n + "\nDATA binary_compressed\n";
  put(c, std::uint32_t{4});
  put(c, std::uint32_t{0xffffffffu});
  c += "abcd";
  expectReadError(write("g6.pcd", c), "truncated data");
  // Counts whose byte size overflows 64 bits.
  expectReadError(write("g7.ply",
                        "ply\nformat binary_little_endian 1.0\nelement vertex 18446744073709551615\n"
                        "property double x\nproperty double y\nproperty double z\nend_header\n0"),
                  "truncated data");
  expectReadError(write("g8.pcd", fields + "WIDTH 4294967295\nHEIGHT 4294967295\nDATA binary\n0"),
                  "truncated data");
}

TEST_F(IoTest, NonNumericAsciiValue) {
  std::string ply = samplePlyAscii();
  ply.replace(ply.find("100.125"), 7, "1OO.125");
  const std::string p1 = write("n1.ply", ply);
  expectReadError(p1, "non-numeric value");
  expectReadError(p1, "line 16");  // 14 header lines, then the second vertex
  std::string pcd = pcdAscii();
  pcd.replace(pcd.rfind("7.25"), 4, "7,25");
  const std::string p2 = write("n2.pcd", pcd);
  expectReadError(p2, "non-numeric value");
  expectReadError(p2, "point 4");
  const std::string p3 = write("n3.obj", "v 0 0 0\nv 1 0 zero\n");
  expectReadError(p3, "non-numeric value");
  expectReadError(p3, "line 2");
}

TEST_F(IoTest, NoPoints) {
  expectReadError(write("p1.ply",
                        "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
                        "property float z\nend_header\n"),
                  "no points");
  expectReadError(write("p2.ply", "ply\nformat ascii 1.0\nend_header\n"), "no points");
  expectReadError(
      write("p3.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 0\nHEIGHT 1\nPOINTS 0\nDATA binary\n"),
      "no points");
  expectReadError(write("p4.obj", "# nothing\nvn 0 0 1\n"), "no points");
}

TEST_F(IoTest, NoXyzFields) {
  expectReadError(write("x1.ply",
                        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float a\nproperty float b\n"
                        "property float c\nend_header\n1 2 3\n"),
                  "no x/y/z fields");
  expectReadError(write("x2.pcd", "FIELDS a b c\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n"),
                  "no x/y/z fields");
}

TEST_F(IoTest, BadFaceIndex) {
  std::string ascii = meshPly("ascii", false);
  ascii.replace(ascii.find("0 4 0 1 2 3"), 11, "0 4 0 1 2 4");
  expectReadError(write("f1.ply", ascii), "bad face index");
  std::string bin = meshPly("binary_little_endian", false);
  const std::size_t at = bin.size() - 8 - 1 - 4;  // the quad's last index (before texcoord and edge)
  std::int32_t idx;
  std::memcpy(&idx, &bin[at], 4);
  ASSERT_EQ(idx, 3);
  idx = -1;
  std::memcpy(&bin[at], &idx, 4);
  expectReadError(write("f2.ply", bin), "bad face index");
  expectReadError(write("f3.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n"), "bad face index");
  expectReadError(write("f4.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"), "bad face index");
  expectReadError(write("f5.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n"), "bad face index");
  expectReadError(write("f6.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf a b c\n"), "bad face index");
}

TEST_F(IoTest, GarbageNeverCrashes) {
  // Every prefix of valid binary files is an error, never a crash.
  for (const auto& [name, bytes] :
       std::vector<std::pair<std::string, std::string>>{{"tp.ply", meshPly("binary_big_endian", true)},
                                                        {"tp.pcd", pcdBinary()},
                                                        {"tc.pcd", pcdCompressed(true)}}) {
    for (std::size_t n = 0; n < bytes.size(); ++n) {
      const std::string p = write(name, bytes.substr(0, n));
      EXPECT_THROW(hgd::readShape(p), IoError) << name << " cut at " << n;
    }
  }
  // Random corruption of valid files and plain random bytes: a shape or an IoError.
  std::mt19937 rng(42);
  const std::vector<std::pair<std::string, std::string>> seeds = {
      {"r.ply", meshPly("binary_little_endian", false)},
      {"r2.ply", meshPly("ascii", false)},
      {"r.pcd", pcdCompressed(true)},
      {"r2.pcd", pcdAscii()},
      {"r.obj", kObj}};
  for (int iter = 0; iter < 600; ++iter) {
    const auto& seed = seeds[static_cast<std::size_t>(iter) % seeds.size()];
    std::string bytes = seed.second;
    const int flips = 1 + static_cast<int>(rng() % 4);
    for (int k = 0; k < flips; ++k) bytes[rng() % bytes.size()] = static_cast<char>(rng() & 0xff);
    if (iter % 10 == 0) {
      bytes.resize(rng() % 200);
      for (char& c : bytes) c = static_cast<char>(rng() & 0xff);
    }
    const std::string p = write(seed.first, bytes);
    try {
      const Shape s = hgd::readShape(p);
      EXPECT_EQ(s.cloud.data.size(), s.size() * s.cloud.point_step);
      for (const auto& poly : s.polygons)
        for (const auto i : poly.vertices) EXPECT_LT(static_cast<std::size_t>(i), s.size());
    } catch (const IoError& e) {
      EXPECT_NE(std::string(e.what()).find(p), std::string::npos);
    }
  }
}

// --- writing ---------------------------------------------------------------------------------

TEST_F(IoTest, WritingOverTheInputIsRefused) {
  const std::string p = write("in.ply", samplePlyAscii());
  const Shape s = hgd::readShape(p);
  const std::string before = slurp(p);
  expectIoError([&] { hgd::writeShape(p, s); }, p, "refusing to overwrite the input");
  const std::string other = (dir_ / "." / "in.ply").string();
  expectIoError([&] { hgd::writeShape(other, s); }, other, "refusing to overwrite the input");
  EXPECT_EQ(slurp(p), before);
  EXPECT_EQ(listing(), (std::set<std::string>{"in.ply"}));
  // A different target is fine, and so is an existing file that is not the input.
  hgd::writeShape(path("other.ply"), s);
  hgd::writeShape(path("other.ply"), s, {hgd::Encoding::Ascii});
  EXPECT_EQ(listing(), (std::set<std::string>{"in.ply", "other.ply"}));
  checkSample(hgd::readShape(path("other.ply")));
}

TEST_F(IoTest, WriteIntoMissingDirectoryThrowsAndLeavesNothing) {
  const Shape s = hgd::readShape(write("in.ply", samplePlyAscii()));
  const std::string target = path("nope/out.ply");
  expectIoError([&] { hgd::writeShape(target, s); }, target, "cannot write");
  EXPECT_FALSE(fs::exists(path("nope")));
  EXPECT_EQ(listing(), (std::set<std::string>{"in.ply"}));
}

TEST_F(IoTest, FailedWriteLeavesNoTemporaryFile) {
  const Shape s = hgd::readShape(write("in.ply", samplePlyAscii()));
  // The target is a non-empty directory: the rename fails after the data was written.
  fs::create_directory(path("out.pcd"));
  write("out.pcd/keep", "x");
  for (const auto enc : {hgd::Encoding::Binary, hgd::Encoding::Ascii})
    expectIoError([&] { hgd::writeShape(path("out.pcd"), s, {enc}); }, path("out.pcd"), "cannot write");
  EXPECT_EQ(listing(), (std::set<std::string>{"in.ply", "out.pcd"}));
  // An inconsistent shape is refused before anything is created.
  Shape bad = s;
  bad.cloud.data.resize(3);
  expectIoError([&] { hgd::writeShape(path("bad.ply"), bad); }, path("bad.ply"), "cannot write");
  Shape bad_face = s;
  bad_face.polygons.push_back(pcl::Vertices());
  bad_face.polygons.back().vertices = {0, 1, 4};
  expectIoError([&] { hgd::writeShape(path("bad.obj"), bad_face); }, path("bad.obj"), "bad face index");
  EXPECT_EQ(listing(), (std::set<std::string>{"in.ply", "out.pcd"}));
}

TEST_F(IoTest, WriterHandlesUnpackedLayoutsLikePclPointXyz) {
  // x, y, z at offsets 0, 4, 8 in a 16-byte point with undeclared padding, as pcl::PointXYZ.
  Shape s;
  s.cloud.width = 2;
  s.cloud.height = 1;
  s.cloud.point_step = 16;
  s.cloud.row_step = 32;
  for (const auto& [n, o] :
       std::vector<std::pair<const char*, std::uint32_t>>{{"x", 0}, {"y", 4}, {"z", 8}}) {
    Field f;
    f.name = n;
    f.offset = o;
    f.datatype = Field::FLOAT32;
    f.count = 1;
    s.cloud.fields.push_back(f);
  }
  s.cloud.data.assign(32, 0xee);
  for (std::size_t i = 0; i < 2; ++i)
    for (std::size_t k = 0; k < 3; ++k)
      hgd::writeValue(s.cloud, i, s.cloud.fields[k], double(i * 3 + k) + 0.5);
  for (const char* name : {"p.ply", "p.pcd", "p.obj"})
    for (const auto enc : {hgd::Encoding::Binary, hgd::Encoding::Ascii}) {
      hgd::writeShape(path(name), s, {enc});
      const Shape back = hgd::readShape(path(name));
      ASSERT_EQ(back.size(), 2u);
      for (std::size_t i = 0; i < 2; ++i) {
        EXPECT_EQ(value(back, i, "x"), double(i * 3) + 0.5);
        EXPECT_EQ(value(back, i, "z"), double(i * 3 + 2) + 0.5);
      }
    }
  EXPECT_EQ(listing(), (std::set<std::string>{"p.ply", "p.pcd", "p.obj"}));
}

}  // namespace

// A colour packed into a float field (PCL's rgb) is an unsigned integer in ascii PCDs, as PCL
// writes it: fully opaque colours are NaNs as floats, and "nan" would lose them. Files whose
// rgb column holds floats (older writers) still read as floats.
TEST(PcdAsciiColour, PackedRgbIsTheIntegerOfItsBits) {
  hgdtest::TempDir dir;
  const std::string header =
      "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n"
      "WIDTH 3\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n";
  float old_style = 0;
  const std::uint32_t green = 0x0000FF00u;
  std::memcpy(&old_style, &green, 4);
  std::ostringstream body;
  body.precision(9);
  body << "0 0 0 4294901760\n1 0 0 4278190335\n2 0 0 " << old_style << "\n";
  hgdtest::writeText(dir.file("pcl.pcd"), header + body.str());
  const Shape s = hgd::readShape(dir.file("pcl.pcd"));
  const hgd::ColourFields cf = hgd::findColourFields(s.cloud);
  ASSERT_TRUE(cf.any());
  EXPECT_EQ(hgd::readColour(s.cloud, 0, cf), Eigen::Vector3f(1, 0, 0));
  EXPECT_EQ(hgd::readColour(s.cloud, 1, cf), Eigen::Vector3f(0, 0, 1));
  EXPECT_EQ(hgd::readColour(s.cloud, 2, cf), Eigen::Vector3f(0, 1, 0));
  // Written back in ascii: the same integers, and the same bits when read again.
  hgd::WriteOptions ascii;
  ascii.encoding = hgd::Encoding::Ascii;
  hgd::writeShape(dir.file("out.pcd"), s, ascii);
  const std::string text = hgdtest::slurp(dir.file("out.pcd"));
  EXPECT_NE(text.find(" 4294901760\n"), std::string::npos) << text;
  EXPECT_NE(text.find(" 4278190335\n"), std::string::npos) << text;
  EXPECT_EQ(text.find("nan"), std::string::npos) << text;
  const Shape back = hgd::readShape(dir.file("out.pcd"));
  EXPECT_EQ(back.cloud.data, s.cloud.data);
}

// --- conversions between formats (issue 28 items 5, 5b, 7, 8, 10, 11) -------------------------

namespace {

/// Random points with normals, curvature and opaque colours (alpha 255: PCL's default, a NaN
/// as a float), as PCL's PointXYZRGBNormal holds them.
pcl::PointCloud<pcl::PointXYZRGBNormal> colouredNormals(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  std::uniform_int_distribution<int> byte(0, 255);
  pcl::PointCloud<pcl::PointXYZRGBNormal> c;
  for (std::size_t i = 0; i < n; ++i) {
    pcl::PointXYZRGBNormal p;
    p.x = u(rng);
    p.y = u(rng);
    p.z = u(rng);
    const Eigen::Vector3f nrm = Eigen::Vector3f(u(rng), u(rng), u(rng) + 2.f).normalized();
    p.normal_x = nrm.x();
    p.normal_y = nrm.y();
    p.normal_z = nrm.z();
    p.curvature = u(rng) + 1.f;
    p.r = static_cast<std::uint8_t>(byte(rng));
    p.g = static_cast<std::uint8_t>(byte(rng));
    p.b = static_cast<std::uint8_t>(byte(rng));
    p.a = 255;
    c.push_back(p);
  }
  return c;
}

void expectSamePoints(const pcl::PointCloud<pcl::PointXYZRGBNormal>& a,
                      const pcl::PointCloud<pcl::PointXYZRGBNormal>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].getVector3fMap(), b[i].getVector3fMap()) << i;
    EXPECT_EQ(a[i].getNormalVector3fMap(), b[i].getNormalVector3fMap()) << i;
    EXPECT_EQ(a[i].curvature, b[i].curvature) << i;
    EXPECT_EQ(a[i].r, b[i].r) << i;
    EXPECT_EQ(a[i].g, b[i].g) << i;
    EXPECT_EQ(a[i].b, b[i].b) << i;
  }
}

/// An ascii PLY header of `n` vertices with x y z and these further property lines.
std::string plyWith(std::size_t n, const std::string& props) {
  return "ply\nformat ascii 1.0\nelement vertex " + std::to_string(n) +
         "\nproperty float x\nproperty float y\nproperty float z\n" + props + "end_header\n";
}

// A PCD scan written as PLY gets PLY's names (nx ny nz, uchar red green blue), as PCL's
// pcl_pcd2ply writes them: PCL's PLY reader (like Open3D, MeshLab, CloudCompare) finds the
// normals and the colours again. Both encodings.
TEST_F(IoTest, PcdWrittenAsPlyUsesPlyNamesThatPclReads) {
  const auto ref = colouredNormals(50, 1);
  ASSERT_EQ(pcl::io::savePCDFileBinary(path("scan.pcd"), ref), 0);
  const Shape s = hgd::readShape(path("scan.pcd"));
  for (const bool ascii : {false, true}) {
    hgd::WriteOptions wo;
    wo.encoding = ascii ? hgd::Encoding::Ascii : hgd::Encoding::Binary;
    const std::string out = path(ascii ? "a.ply" : "b.ply");
    hgd::writeShape(out, s, wo);
    const std::string text = slurp(out);
    const std::string header = text.substr(0, text.find("end_header"));
    for (const char* p :
         {"property float nx\n", "property float ny\n", "property float nz\n", "property uchar red\n",
          "property uchar green\n", "property uchar blue\n", "property float curvature\n"})
      EXPECT_NE(header.find(p), std::string::npos) << p << " in " << header;
    EXPECT_EQ(header.find("normal_x"), std::string::npos) << header;
    EXPECT_EQ(header.find("rgb"), std::string::npos) << header;
    pcl::PointCloud<pcl::PointXYZRGBNormal> back;
    ASSERT_EQ(pcl::io::loadPLYFile(out, back), 0);
    expectSamePoints(ref, back);
    EXPECT_EQ(hgd::extrasLost(s, hgd::FileFormat::Ply), "");
  }
  // Written as PCD again (its own format) it stays byte for byte what PCL wrote.
  hgd::writeShape(path("again.pcd"), s);
  EXPECT_EQ(slurp(path("again.pcd")), slurp(path("scan.pcd")));
}

// The other way: a PLY's nx ny nz and red green blue (alpha) become PCD's normal_x normal_y
// normal_z and a packed rgb (rgba), CloudCompare's scalar_intensity PCD's intensity: PCL's
// typed clouds find them.
TEST_F(IoTest, PlyWrittenAsPcdUsesPcdNamesThatPclReads) {
  const auto ref = colouredNormals(40, 2);
  std::string ply = plyWith(ref.size(),
                            "property float nx\nproperty float ny\nproperty float nz\n"
                            "property uchar red\nproperty uchar green\nproperty uchar blue\n"
                            "property float curvature\nproperty float scalar_intensity\n");
  for (std::size_t i = 0; i < ref.size(); ++i) {
    const auto& p = ref[i];
    std::ostringstream row;
    row.precision(9);
    row << p.x << ' ' << p.y << ' ' << p.z << ' ' << p.normal_x << ' ' << p.normal_y << ' ' << p.normal_z
        << ' ' << int{p.r} << ' ' << int{p.g} << ' ' << int{p.b} << ' ' << p.curvature << ' '
        << 0.5 * static_cast<double>(i) << '\n';
    ply += row.str();
  }
  const Shape s = hgd::readShape(write("scan.ply", ply));
  for (const bool ascii : {false, true}) {
    hgd::WriteOptions wo;
    wo.encoding = ascii ? hgd::Encoding::Ascii : hgd::Encoding::Binary;
    const std::string out = path(ascii ? "a.pcd" : "b.pcd");
    hgd::writeShape(out, s, wo);
    const std::string text = slurp(out);
    EXPECT_NE(text.find("FIELDS x y z normal_x normal_y normal_z rgb curvature intensity\n"),
              std::string::npos)
        << text.substr(0, 200);
    pcl::PointCloud<pcl::PointXYZRGBNormal> back;
    ASSERT_EQ(pcl::io::loadPCDFile(out, back), 0);
    expectSamePoints(ref, back);
    for (const auto& p : back.points) EXPECT_EQ(p.a, 255);
    pcl::PointCloud<pcl::PointXYZI> with_intensity;
    ASSERT_EQ(pcl::io::loadPCDFile(out, with_intensity), 0);
    ASSERT_EQ(with_intensity.size(), ref.size());
    for (std::size_t i = 0; i < ref.size(); ++i)
      EXPECT_EQ(with_intensity[i].intensity, 0.5f * static_cast<float>(i));
  }
  // With alpha: a packed rgba, as PointXYZRGBA reads it.
  std::string rgba =
      plyWith(3, "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n");
  rgba += "0 0 0 10 20 30 40\n1 0 0 255 0 0 128\n0 1 0 0 0 255 0\n";
  hgd::writeShape(path("rgba.pcd"), hgd::readShape(write("rgba.ply", rgba)));
  pcl::PointCloud<pcl::PointXYZRGBA> back;
  ASSERT_EQ(pcl::io::loadPCDFile(path("rgba.pcd"), back), 0);
  ASSERT_EQ(back.size(), 3u);
  const int want[3][4] = {{10, 20, 30, 40}, {255, 0, 0, 128}, {0, 0, 255, 0}};
  for (std::size_t i = 0; i < 3; ++i)
    EXPECT_EQ((std::array<int, 4>{back[i].r, back[i].g, back[i].b, back[i].a}),
              (std::array<int, 4>{want[i][0], want[i][1], want[i][2], want[i][3]}))
        << i;
  // And back to PLY: red green blue alpha again, the values the first PLY had.
  const Shape from_pcd = hgd::readShape(path("rgba.pcd"));
  hgd::writeShape(path("rgba2.ply"), from_pcd);
  const Shape again = hgd::readShape(path("rgba2.ply"));
  const char* const channels[4] = {"red", "green", "blue", "alpha"};
  for (std::size_t i = 0; i < 3; ++i)
    for (int k = 0; k < 4; ++k) EXPECT_EQ(value(again, i, channels[k]), want[i][k]) << i << channels[k];
}

// PCL's packed rgb with alpha 255 is a NaN as a float: written to XYZ or ascii PLY as a float
// many such colours came back as "nan". Written as red green blue, all 400 come back (and in
// OFF and OBJ, which had no place for a packed colour).
TEST_F(IoTest, PackedColoursBecomeRedGreenBlueInTextFormats) {
  const auto ref = colouredNormals(400, 3);
  ASSERT_EQ(pcl::io::savePCDFileBinary(path("scan.pcd"), ref), 0);
  const Shape s = hgd::readShape(path("scan.pcd"));
  hgd::WriteOptions ascii;
  ascii.encoding = hgd::Encoding::Ascii;
  for (const char* name : {"out.xyz", "out.ply", "out.off", "out.obj"}) {
    hgd::writeShape(path(name), s, ascii);
    EXPECT_EQ(slurp(path(name)).find("nan"), std::string::npos) << name;
    const Shape back = hgd::readShape(path(name));
    ASSERT_EQ(back.size(), ref.size()) << name;
    const hgd::ColourFields cf = hgd::findColourFields(back.cloud);
    ASSERT_TRUE(cf.any()) << name;
    for (std::size_t i = 0; i < ref.size(); ++i) {
      const Eigen::Vector3f want(ref[i].r / 255.f, ref[i].g / 255.f, ref[i].b / 255.f);
      EXPECT_LT((hgd::readColour(back.cloud, i, cf) - want).norm(), 1e-6f) << name << " point " << i;
    }
  }
}

// What a target format cannot hold is said (the runner prints it and puts it in the report):
// faces written as PCD or XYZ, fields OBJ and OFF have no place for, vertices STL has none for.
TEST_F(IoTest, ConversionsSayWhatTheyDrop) {
  const Shape mesh =
      hgd::readShape(write("m.off", "OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 1 3 2\n"));
  EXPECT_EQ(hgd::extrasLost(mesh, hgd::FileFormat::Pcd), "PCD holds points only: the 2 faces are dropped");
  EXPECT_EQ(hgd::extrasLost(mesh, hgd::FileFormat::Xyz), "XYZ holds points only: the 2 faces are dropped");
  EXPECT_EQ(hgd::extrasLost(mesh, hgd::FileFormat::Ply), "");
  const Shape stl = hgd::readShape(write("m.stl",
                                         "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n"
                                         "vertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n"));
  EXPECT_EQ(hgd::extrasLost(stl, hgd::FileFormat::Pcd), "PCD holds points only: the 1 faces are dropped");
  EXPECT_EQ(hgd::extrasLost(stl, hgd::FileFormat::Stl), "");  // welded already: it comes back whole
  EXPECT_EQ(hgd::extrasLost(mesh, hgd::FileFormat::Stl), "");
  // STL holds triangles, not vertices: a vertex on no face is dropped, and two vertices at one
  // position (a seam; -0 and 0) come back as one. The count read back is what the warning says.
  const Shape loose = hgd::readShape(
      write("loose.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nv -0 0 0\nv 1 1 0\nf 1 2 3\nf 5 2 6\n"));
  EXPECT_EQ(
      hgd::extrasLost(loose, hgd::FileFormat::Stl),
      "STL holds triangles only: the 1 of 6 points on no face are dropped; STL has no shared vertices: 1 "
      "points at the position of another come back as one with it");
  hgd::writeShape(path("loose.stl"), loose);
  EXPECT_EQ(hgd::readShape(path("loose.stl")).size(), 4u);  // 6 - 1 - 1
  // rgb to OBJ: the colours are written (as red green blue in 0..1); intensity is named.
  pcl::PointCloud<pcl::PointXYZRGB> rgb;
  for (const auto& c3 : {std::array<std::uint8_t, 3>{10, 20, 30}, std::array<std::uint8_t, 3>{255, 0, 0}}) {
    pcl::PointXYZRGB q(c3[0], c3[1], c3[2]);
    q.x = static_cast<float>(rgb.size());
    rgb.push_back(q);
  }
  ASSERT_EQ(pcl::io::savePCDFileBinary(path("rgb.pcd"), rgb), 0);
  const Shape c = hgd::readShape(path("rgb.pcd"));
  EXPECT_EQ(hgd::extrasLost(c, hgd::FileFormat::Obj), "");
  hgd::writeShape(path("rgb.obj"), c);
  const Shape o = hgd::readShape(path("rgb.obj"));
  EXPECT_FLOAT_EQ(static_cast<float>(value(o, 0, "green")), 20.f / 255.f);
  EXPECT_FLOAT_EQ(static_cast<float>(value(o, 1, "red")), 1.f);
  pcl::PointCloud<pcl::PointXYZI> xyzi;
  pcl::PointXYZI pi;
  pi.x = pi.y = pi.z = 1;
  pi.intensity = 0.25f;
  xyzi.push_back(pi);
  ASSERT_EQ(pcl::io::savePCDFileBinary(path("i.pcd"), xyzi), 0);
  const Shape i = hgd::readShape(path("i.pcd"));
  EXPECT_EQ(hgd::extrasLost(i, hgd::FileFormat::Obj), "OBJ cannot hold the fields intensity");
  EXPECT_EQ(hgd::extrasLost(i, hgd::FileFormat::Ply), "");
  // Normals and colours to OFF: both kept (the colour split), only curvature is named.
  ASSERT_EQ(pcl::io::savePCDFileBinary(path("n.pcd"), colouredNormals(5, 4)), 0);
  EXPECT_EQ(hgd::extrasLost(hgd::readShape(path("n.pcd")), hgd::FileFormat::Off),
            "OFF cannot hold the fields curvature");
}

// PLY comments and obj_info lines are written back whether or not the file has other elements.
TEST_F(IoTest, PlyCommentsAreKeptWithoutOtherElements) {
  const std::string in =
      "ply\nformat ascii 1.0\ncomment scanned by someone\nobj_info a scanner\nelement vertex 1\n"
      "property float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n";
  const std::string p = write("c.ply", in);
  for (const bool ascii : {false, true}) {
    hgd::WriteOptions wo;
    wo.encoding = ascii ? hgd::Encoding::Ascii : hgd::Encoding::Binary;
    hgd::writeShape(path("out.ply"), hgd::readShape(p), wo);
    const std::string text = slurp(path("out.ply"));
    EXPECT_NE(text.find("\ncomment scanned by someone\nobj_info a scanner\n"), std::string::npos) << text;
    // Read and written again: the same lines once, not twice.
    hgd::writeShape(path("out2.ply"), hgd::readShape(path("out.ply")), wo);
    EXPECT_EQ(slurp(path("out2.ply")), text);
  }
}

// OBJ vertices with a weight (v x y z w), and colours on some vertices only, are written back
// as they were; colours on every vertex are fields and are written back too.
TEST_F(IoTest, ObjWeightsAndColoursAreWrittenBack) {
  const std::string weighted = "v 0 0 0 0.5\nv 1 0 0 2\nv 0 1 0 1\nf 1 2 3\n";
  hgd::writeShape(path("w_out.obj"), hgd::readShape(write("w.obj", weighted)));
  EXPECT_EQ(slurp(path("w_out.obj")), weighted);
  const std::string mixed = "v 0 0 0 1 0 0.5\nv 1 0 0\nv 0 1 0 0 0 1\nf 1 2 3\n";
  hgd::writeShape(path("m_out.obj"), hgd::readShape(write("m.obj", mixed)));
  EXPECT_EQ(slurp(path("m_out.obj")), mixed);
  const Shape c =
      hgd::readShape(write("c.obj", "v 0 0 0 1 0 0.5\nv 1 0 0 0 1 0\nv 0 1 0 0.25 0 1\nf 1 2 3\n"));
  hgd::writeShape(path("c_out.obj"), c);
  const Shape back = hgd::readShape(path("c_out.obj"));
  for (std::size_t i = 0; i < 3; ++i)
    for (const char* n : {"red", "green", "blue"}) EXPECT_EQ(value(back, i, n), value(c, i, n)) << i << n;
  EXPECT_EQ(value(back, 2, "red"), 0.25);
}

// A binary PLY's bad face index is printed as the integer it is, with the face and the range.
TEST_F(IoTest, BinaryPlyBadFaceIndexIsAnInteger) {
  std::string bin = meshPly("binary_little_endian", false);
  const std::size_t at = bin.size() - 8 - 1 - 4;  // the quad's last index (as in BadFaceIndex)
  const std::int32_t idx = 144;
  std::memcpy(&bin[at], &idx, 4);
  const std::string p = write("f.ply", bin);
  try {
    hgd::readShape(p);
    ADD_FAILURE() << "no error";
  } catch (const IoError& e) {
    const std::string m = e.what();
    EXPECT_EQ(m.find("144.0"), std::string::npos) << m;
    EXPECT_NE(m.find(p + ": bad face index 144 in face "), std::string::npos) << m;
    EXPECT_NE(m.find("vertices, indices 0 to "), std::string::npos) << m;
  }
}

// Headers with very many names are read in linear time: 100,000 PLY properties and 200,000
// XYZ columns (the quadratic checks of repeated names took 6 s and 55 s; linear reads take 0.1 s
// and 0.3 s, about 1.5 s and 2.5 s under AddressSanitizer on a loaded machine). The bound is 2 s,
// 8 s in the sanitizer build: a quadratic read is there 30 s and more. (The growth from a quarter
// of the names is no cleaner a measure: 6x-10x when linear, from the caches alone.)
TEST_F(IoTest, HugeHeadersReadInLinearTime) {
#ifdef HGD_SANITIZED
  constexpr double kBound = 8.0;
#else
  constexpr double kBound = 2.0;
#endif
  const std::size_t nprops = 100000;
  std::string ply = "ply\nformat ascii 1.0\nelement vertex 1\n";
  std::string row;
  for (std::size_t k = 0; k < nprops; ++k) {
    ply += "property float " + (k < 3 ? std::string(1, "xyz"[k]) : "p" + std::to_string(k)) + "\n";
    row += (k ? " " : "") + std::to_string(k % 7);
  }
  ply += "end_header\n" + row + "\n";
  const std::string ply_path = write("wide.ply", ply);
  const std::size_t ncols = 200000;
  std::string names = "x y z", values = "1 2 3";
  for (std::size_t k = 3; k < ncols; ++k) {
    names += " c" + std::to_string(k);
    values += " " + std::to_string(k % 7);
  }
  const std::string xyz_path = write("wide.xyz", names + "\n" + values + "\n");
  const auto t0 = std::chrono::steady_clock::now();
  const Shape a = hgd::readShape(ply_path);
  const auto t1 = std::chrono::steady_clock::now();
  const Shape b = hgd::readShape(xyz_path);
  const auto t2 = std::chrono::steady_clock::now();
  ASSERT_EQ(a.cloud.fields.size(), nprops);
  EXPECT_EQ(value(a, 0, "p99999"), 99999 % 7);
  ASSERT_EQ(b.cloud.fields.size(), ncols);
  EXPECT_EQ(value(b, 0, "c199999"), 199999 % 7);
  const double ply_s = std::chrono::duration<double>(t1 - t0).count();
  const double xyz_s = std::chrono::duration<double>(t2 - t1).count();
  std::printf("100k-property PLY: %.3f s, 200k-column XYZ: %.3f s\n", ply_s, xyz_s);
  EXPECT_LT(ply_s, kBound);
  EXPECT_LT(xyz_s, kBound);
}

}  // namespace
