// Files written by the tools scan users already have, read by hgdeform and read back by the
// tool that wrote them: PCL's own writers (every encoding, the typed and the PCLPointCloud2
// writers, an organized scan with NaN points), CloudCompare's ASCII exports with wide scalar
// columns, and PCL's packed colours. The expected values come from PCL's own reader and from
// strtod, never from hgdeform's reader.
#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "hgdeform/app/regions.h"
#include "hgdeform/app/scenario.h"
#include "hgdeform/io/fields.h"
#include "hgdeform/io/geometry.h"
#include "hgdeform/io/io.h"
#include "test_util.h"

namespace {

using hgd::Shape;
using hgdtest::slurp;
using hgdtest::TempDir;
using hgdtest::writeText;

double value(const Shape& s, std::size_t point, const std::string& name) {
  const int i = hgd::findField(s.cloud, name);
  if (i < 0) {
    ADD_FAILURE() << "no field " << name;
    return std::numeric_limits<double>::quiet_NaN();
  }
  return hgd::readValue(s.cloud, point, s.cloud.fields[static_cast<std::size_t>(i)]);
}

std::uint8_t datatypeOf(const Shape& s, const std::string& name) {
  const int i = hgd::findField(s.cloud, name);
  return i < 0 ? std::uint8_t{0} : s.cloud.fields[static_cast<std::size_t>(i)].datatype;
}

/// Bits of a float, so that NaN compares equal to NaN and -0 differs from 0.
std::uint32_t bits(float f) {
  std::uint32_t u;
  std::memcpy(&u, &f, 4);
  return u;
}

/// A scan-like cloud of `n` points in random order: a noisy bumpy patch with normals of random
/// sign, colours with alpha `alpha`, intensities and curvatures.
pcl::PointCloud<pcl::PointXYZRGBNormal> scanLike(std::size_t n, unsigned seed, std::uint8_t alpha = 255) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  pcl::PointCloud<pcl::PointXYZRGBNormal> c;
  for (std::size_t i = 0; i < n; ++i) {
    pcl::PointXYZRGBNormal p;
    p.x = 3.f * u(rng);
    p.y = 2.f * u(rng);
    p.z = 0.2f * std::sin(p.x) * std::cos(p.y) + 0.003f * u(rng);
    const float sign = u(rng) < 0 ? -1.f : 1.f;
    Eigen::Vector3f nrm(-0.2f * std::cos(p.x) * std::cos(p.y), 0.2f * std::sin(p.x) * std::sin(p.y), 1.f);
    nrm = sign * nrm.normalized();
    p.normal_x = nrm.x();
    p.normal_y = nrm.y();
    p.normal_z = nrm.z();
    p.r = static_cast<std::uint8_t>(rng() & 255);
    p.g = static_cast<std::uint8_t>(rng() & 255);
    p.b = static_cast<std::uint8_t>(rng() & 255);
    p.a = alpha;
    p.curvature = 0.01f * (u(rng) + 1.f);
    c.push_back(p);
  }
  return c;
}

template <typename PointT>
pcl::PointCloud<PointT> as(const pcl::PointCloud<pcl::PointXYZRGBNormal>& in) {
  pcl::PointCloud<PointT> out;
  pcl::copyPointCloud(in, out);
  return out;
}

/// Every field of `want` (as PCL reads it) is in `got` with the same bits, point for point.
void expectSameCloud(const pcl::PCLPointCloud2& want, const pcl::PCLPointCloud2& got,
                     const std::string& what) {
  ASSERT_EQ(got.width * got.height, want.width * want.height) << what;
  for (const auto& f : want.fields) {
    if (f.name == "_") continue;
    const int k = hgd::findField(got, f.name);
    ASSERT_GE(k, 0) << what << ": field " << f.name << " lost";
    const auto& g = got.fields[static_cast<std::size_t>(k)];
    ASSERT_EQ(g.datatype, f.datatype) << what << ": " << f.name;
    const std::size_t size = hgd::datatypeSize(f.datatype) * (f.count > 1 ? f.count : 1);
    std::size_t differ = 0;
    for (std::size_t i = 0; i < static_cast<std::size_t>(want.width) * want.height; ++i)
      differ += std::memcmp(want.data.data() + i * want.point_step + f.offset,
                            got.data.data() + i * got.point_step + g.offset, size) != 0;
    EXPECT_EQ(differ, 0u) << what << ": " << f.name << " differs at " << differ << " points";
  }
}

class OthersFiles : public ::testing::Test {
 public:
  std::string path(const std::string& name) const { return dir.file(name); }

 protected:
  TempDir dir;
};

/// Writes `cloud` with PCL's writer for encoding `enc`: ascii, binary, binary_compressed, or (3)
/// the PCLPointCloud2 binary writer the pcl_* converters use. PCL's status.
template <typename PointT>
int savePcd(int enc, const std::string& path, const pcl::PointCloud<PointT>& cloud) {
  switch (enc) {
    case 0: return pcl::io::savePCDFileASCII(path, cloud);
    case 1: return pcl::io::savePCDFileBinary(path, cloud);
    case 2: return pcl::io::savePCDFileBinaryCompressed(path, cloud);
    default: {
      pcl::PCLPointCloud2 blob;
      pcl::toPCLPointCloud2(cloud, blob);
      // In offset order, as a cloud the converters read from a PLY is: PCL's header writer
      // gives a negative padding COUNT for PointXYZRGBNormal's declared order (rgb after the
      // normals' bytes), a file its own reader then hangs on.
      std::sort(blob.fields.begin(), blob.fields.end(),
                [](const pcl::PCLPointField& a, const pcl::PCLPointField& b) { return a.offset < b.offset; });
      pcl::PCDWriter w;
      return w.writeBinary(path, blob);
    }
  }
}

// PCL's binary writers: PointT clouds through savePCDFile*, and the PCLPointCloud2 writer that
// pcl_ply2pcd and pcl_convert_pcd_ascii_binary use, which sizes the file to whole pages (zeros
// after the last point). Each reads, and what hgdeform writes back (PCD, and PLY) PCL reads with
// every field and the same bits.
template <typename PointT>
void roundTripThroughPcl(const OthersFiles& t, const std::string& type,
                         const pcl::PointCloud<PointT>& cloud) {
  for (int enc = 0; enc < 4; ++enc) {
    const std::string what = type + " encoding " + std::to_string(enc);
    const std::string in = t.path(type + std::to_string(enc) + ".pcd");
    ASSERT_EQ(savePcd(enc, in, cloud), 0) << what;
    pcl::PCLPointCloud2 ref;
    ASSERT_EQ(pcl::io::loadPCDFile(in, ref), 0) << what;
    Shape s;
    try {
      s = hgd::readShape(in);
    } catch (const std::exception& e) {
      ADD_FAILURE() << what << ": " << e.what();
      continue;
    }
    ASSERT_EQ(s.cloud.width, ref.width) << what;
    ASSERT_EQ(s.cloud.height, ref.height) << what;
    expectSameCloud(ref, s.cloud, what + " read");
    // Written back as PCD: PCL reads the same fields and bits.
    const std::string out = t.path(type + std::to_string(enc) + "_out.pcd");
    hgd::writeShape(out, s);
    pcl::PCLPointCloud2 back;
    ASSERT_EQ(pcl::io::loadPCDFile(out, back), 0) << what;
    expectSameCloud(ref, back, what + " written back as PCD");
    // As PLY: PCL's typed reader finds the same points (names converted: nx, red...).
    const std::string ply = t.path(type + std::to_string(enc) + "_out.ply");
    hgd::writeShape(ply, s);
    pcl::PointCloud<PointT> typed, own;  // own: what PCL reads of its own file (ascii rounds)
    ASSERT_EQ(pcl::io::loadPLYFile(ply, typed), 0) << what;
    ASSERT_EQ(pcl::io::loadPCDFile(in, own), 0) << what;
    ASSERT_EQ(typed.size(), cloud.size()) << what;
    std::size_t differ = 0;
    for (std::size_t i = 0; i < cloud.size(); ++i)
      differ += bits(typed[i].x) != bits(own[i].x) || bits(typed[i].y) != bits(own[i].y) ||
                bits(typed[i].z) != bits(own[i].z);
    EXPECT_EQ(differ, 0u) << what << ": PLY positions";
  }
}

TEST_F(OthersFiles, EveryPclWriterAndEncodingReadsAndPclReadsItBack) {
  // 1,839 points: no PCD of these types ends on a page boundary, so the PCLPointCloud2 writer pads.
  const auto base = scanLike(1839, 7);
  roundTripThroughPcl(*this, "xyz", as<pcl::PointXYZ>(base));
  roundTripThroughPcl(*this, "xyzi", as<pcl::PointXYZI>(base));
  roundTripThroughPcl(*this, "xyzrgb", as<pcl::PointXYZRGB>(base));
  roundTripThroughPcl(*this, "xyzrgbnormal", base);
  roundTripThroughPcl(*this, "pointnormal", as<pcl::PointNormal>(base));
}

// What the PCLPointCloud2 writer leaves after the points is zeros; anything else there is still
// data the header does not declare.
TEST_F(OthersFiles, ZerosAfterTheLastPointArePaddingOtherBytesAreRefused) {
  const auto cloud = as<pcl::PointXYZ>(scanLike(100, 3));
  pcl::PCLPointCloud2 blob;
  pcl::toPCLPointCloud2(cloud, blob);
  pcl::PCDWriter w;
  ASSERT_EQ(w.writeBinary(path("padded.pcd"), blob), 0);
  std::string bytes = slurp(path("padded.pcd"));
  const std::size_t header = bytes.find("DATA binary\n") + 12;
  ASSERT_GT(bytes.size(), header + 1200) << "PCL's writer no longer pads: the case below is not PCL's";
  EXPECT_EQ(hgd::readShape(path("padded.pcd")).size(), 100u);
  writeText(path("more.pcd"), bytes + std::string(10000, '\0'));
  EXPECT_EQ(hgd::readShape(path("more.pcd")).size(), 100u);
  bytes[bytes.size() - 5] = 1;
  writeText(path("junk.pcd"), bytes);
  try {
    hgd::readShape(path("junk.pcd"));
    ADD_FAILURE() << "a non-zero byte after the points was read as padding";
  } catch (const hgd::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("junk.pcd"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("not all zero"), std::string::npos) << e.what();
  }
}

/// A depth camera's 40x30 organized scan: a tilted patch 0.6 units off, NaN points at one pixel
/// in five (random, `seed`; counted into `nans`), colours by row and column.
pcl::PointCloud<pcl::PointXYZRGB> depthCameraScan(unsigned seed, std::size_t* nans) {
  pcl::PointCloud<pcl::PointXYZRGB> scan(40, 30);
  std::mt19937 rng(seed);
  for (std::uint32_t r = 0; r < 30; ++r)
    for (std::uint32_t c = 0; c < 40; ++c) {
      auto& p = scan.at(c, r);
      if (rng() % 5 == 0) {
        p.x = p.y = p.z = std::numeric_limits<float>::quiet_NaN();
        ++*nans;
      } else {
        p.x = 0.01f * static_cast<float>(c) - 0.2f;
        p.y = 0.01f * static_cast<float>(r) - 0.15f;
        p.z = 0.6f + 0.001f * static_cast<float>(rng() % 100);
      }
      p.r = static_cast<std::uint8_t>(c * 6);
      p.g = static_cast<std::uint8_t>(r * 8);
      p.b = 9;
    }
  scan.is_dense = false;
  return scan;
}

// An organized scan (a depth camera's 40x30 grid) with NaN points where nothing returned, as
// PCL writes it in each encoding: the grid and every NaN stay in place through hgdeform.
TEST_F(OthersFiles, AnOrganizedScanWithNanPointsKeepsItsGrid) {
  std::size_t nans = 0;
  const pcl::PointCloud<pcl::PointXYZRGB> scan = depthCameraScan(11, &nans);
  ASSERT_GT(nans, 100u);
  for (int enc = 0; enc < 4; ++enc) {
    const std::string in = path("organized" + std::to_string(enc) + ".pcd");
    ASSERT_EQ(savePcd(enc, in, scan), 0);
    pcl::PointCloud<pcl::PointXYZRGB> ref;  // what PCL reads of its own file (ascii rounds)
    ASSERT_EQ(pcl::io::loadPCDFile(in, ref), 0);
    const Shape s = hgd::readShape(in);
    EXPECT_EQ(s.cloud.width, 40u);
    EXPECT_EQ(s.cloud.height, 30u);
    const std::string out = path("organized" + std::to_string(enc) + "_out.pcd");
    hgd::writeShape(out, s);
    pcl::PointCloud<pcl::PointXYZRGB> back;
    ASSERT_EQ(pcl::io::loadPCDFile(out, back), 0);
    ASSERT_EQ(back.width, 40u);
    ASSERT_EQ(back.height, 30u);
    std::size_t differ = 0;
    std::size_t nan_rows = 0;
    for (std::size_t i = 0; i < scan.size(); ++i) {
      differ += bits(back[i].x) != bits(ref[i].x) || bits(back[i].y) != bits(ref[i].y) ||
                bits(back[i].z) != bits(ref[i].z) || back[i].rgba != ref[i].rgba;
      nan_rows += std::isnan(back[i].x) && std::isnan(scan[i].x);
    }
    EXPECT_EQ(differ, 0u) << "encoding " << enc;
    EXPECT_EQ(nan_rows, nans) << "encoding " << enc << ": the NaN points in their places";
  }
}

// PCL's PLYWriter of an organized scan without a camera element (as `pcl_pcd2ply -use_camera 0`
// writes one): the valid points, then an element range_grid of one list per pixel, empty where
// nothing returned. hgdeform reads the grid PCL's PLYReader reads (it read the valid points
// alone, as an unorganized cloud); written back as PLY or PCD, PCL reads the same grid again.
TEST_F(OthersFiles, PclsOrganizedPlyIsReadAsItsGrid) {
  std::size_t nans = 0;
  const pcl::PointCloud<pcl::PointXYZRGB> scan = depthCameraScan(12, &nans);
  ASSERT_GT(nans, 100u);
  pcl::PCLPointCloud2 blob;
  pcl::toPCLPointCloud2(scan, blob);
  for (const bool binary : {false, true}) {
    const std::string in = path(binary ? "grid_b.ply" : "grid_a.ply");
    pcl::PLYWriter writer;
    ASSERT_EQ(writer.write(in, blob, Eigen::Vector4f::Zero(), Eigen::Quaternionf::Identity(), binary, false),
              0);
    ASSERT_NE(slurp(in).find("element range_grid 1200"), std::string::npos);
    pcl::PointCloud<pcl::PointXYZRGB> ref;  // PCL's reading of its own file
    ASSERT_EQ(pcl::io::loadPLYFile(in, ref), 0);
    ASSERT_EQ(ref.width, 40u);
    ASSERT_EQ(ref.height, 30u);
    const auto same = [&](const pcl::PointCloud<pcl::PointXYZRGB>& got, const std::string& what) {
      ASSERT_EQ(got.width, 40u) << what;
      ASSERT_EQ(got.height, 30u) << what;
      std::size_t differ = 0, nan_pixels = 0;
      for (std::size_t i = 0; i < ref.size(); ++i) {
        differ +=
            bits(got[i].x) != bits(ref[i].x) || bits(got[i].y) != bits(ref[i].y) ||
            bits(got[i].z) != bits(ref[i].z) ||
            (!std::isnan(ref[i].x) && (got[i].r != ref[i].r || got[i].g != ref[i].g || got[i].b != ref[i].b));
        nan_pixels += std::isnan(got[i].x) && std::isnan(scan[i].x);
      }
      EXPECT_EQ(differ, 0u) << what;
      EXPECT_EQ(nan_pixels, nans) << what;
    };
    const Shape s = hgd::readShape(in);
    ASSERT_EQ(s.cloud.width, 40u);
    ASSERT_EQ(s.cloud.height, 30u);
    std::size_t differ = 0;
    for (std::size_t i = 0; i < ref.size(); ++i) {
      const float x = static_cast<float>(value(s, i, "x")), y = static_cast<float>(value(s, i, "y"));
      differ += bits(x) != bits(ref[i].x) || bits(y) != bits(ref[i].y) ||
                (!std::isnan(ref[i].x) && value(s, i, "red") != ref[i].r);
    }
    EXPECT_EQ(differ, 0u) << "hgdeform's reading of " << in;
    for (const char* ext : {".ply", ".pcd"}) {
      const std::string out = path(std::string(binary ? "grid_b_out" : "grid_a_out") + ext);
      hgd::writeShape(out, s);
      pcl::PointCloud<pcl::PointXYZRGB> back;
      ASSERT_EQ(
          std::string(ext) == ".ply" ? pcl::io::loadPLYFile(out, back) : pcl::io::loadPCDFile(out, back), 0);
      same(back, out);
      if (std::string(ext) == ".ply") {
        EXPECT_NE(slurp(out).find("element range_grid 1200"), std::string::npos);
      }
    }
  }
}

// CloudCompare's ASCII export with a header: a GPS time needs double's 16 digits and a point
// count above 2^24 an integer float32 cannot hold. Unmoved, every row comes back as the same
// text; converted to PLY each column is declared a type that holds its values.
TEST_F(OthersFiles, CloudCompareAsciiColumnsKeepEveryDigit) {
  std::string text = "//X Y Z GpsTime Intensity Label\n";
  std::vector<std::string> gps, intensity;
  for (int i = 0; i < 400; ++i) {
    char row[200], g[40], in[40];
    std::snprintf(g, sizeof g, "%.6f", 1634567890.123456 + 0.001731 * i);
    std::snprintf(in, sizeof in, "%d", 16777217 + 2 * i);
    gps.push_back(g);
    intensity.push_back(in);
    std::snprintf(row, sizeof row, "%.6f %.6f %.6f %s %s %d\n", 0.01 * (i % 20), 0.02 * (i / 20),
                  0.001 * (i % 7), g, in, i % 5);
    text += row;
  }
  writeText(path("cc.txt"), text);
  const Shape s = hgd::readShape(path("cc.txt"));
  EXPECT_EQ(datatypeOf(s, "GpsTime"), pcl::PCLPointField::FLOAT64);
  EXPECT_EQ(datatypeOf(s, "Intensity"), pcl::PCLPointField::FLOAT64);
  EXPECT_EQ(datatypeOf(s, "Label"), pcl::PCLPointField::FLOAT32);  // small integers fit a float
  for (std::size_t i = 0; i < gps.size(); ++i) {
    ASSERT_EQ(value(s, i, "GpsTime"), std::strtod(gps[i].c_str(), nullptr)) << i;
    ASSERT_EQ(value(s, i, "Intensity"), std::strtod(intensity[i].c_str(), nullptr)) << i;
  }
  hgd::writeShape(path("back.txt"), s);
  EXPECT_EQ(slurp(path("back.txt")), text);
  for (const bool ascii : {false, true}) {
    hgd::WriteOptions wo;
    wo.encoding = ascii ? hgd::Encoding::Ascii : hgd::Encoding::Binary;
    const std::string ply = path(ascii ? "a.ply" : "b.ply");
    hgd::writeShape(ply, s, wo);
    const std::string head = slurp(ply).substr(0, 400);
    EXPECT_NE(head.find("property double GpsTime\n"), std::string::npos) << head;
    EXPECT_NE(head.find("property double intensity\n"), std::string::npos) << head;  // PCL's name
    pcl::PCLPointCloud2 pcl_back;  // PCL reads the PLY's doubles as doubles
    ASSERT_EQ(pcl::io::loadPLYFile(ply, pcl_back), 0);
    const int g = hgd::findField(pcl_back, "GpsTime");
    ASSERT_GE(g, 0);
    for (std::size_t i = 0; i < gps.size(); ++i)
      ASSERT_EQ(hgd::readValue(pcl_back, i, pcl_back.fields[static_cast<std::size_t>(g)]),
                std::strtod(gps[i].c_str(), nullptr))
          << i;
  }
}

// A file without a row of names: a sixth column of GPS times is a double field too.
TEST_F(OthersFiles, UnnamedWideColumnsAreDoubles) {
  writeText(path("p.xyz"), "0 0 0 0.5 1634567890.25 7\n1 0 0 0.25 1634567891.5 16777217\n0 1 0 1 3 8\n");
  const Shape s = hgd::readShape(path("p.xyz"));
  EXPECT_EQ(datatypeOf(s, "field3"), pcl::PCLPointField::FLOAT32);
  EXPECT_EQ(datatypeOf(s, "field4"), pcl::PCLPointField::FLOAT64);
  EXPECT_EQ(datatypeOf(s, "field5"), pcl::PCLPointField::FLOAT64);
  EXPECT_EQ(value(s, 1, "field5"), 16777217.0);
  hgd::writeShape(path("back.xyz"), s);
  EXPECT_EQ(slurp(path("back.xyz")), slurp(path("p.xyz")));
}

// A number beyond a double's range is an error naming its line and column, not an infinity;
// a spelt "inf" is still read as one.
TEST_F(OthersFiles, XyzNumbersBeyondADoubleAreRefused) {
  writeText(path("big.xyz"), "0 0 0 1\n1 0 0 2\n0 1 0 1e400\n");
  try {
    hgd::readShape(path("big.xyz"));
    ADD_FAILURE() << "1e400 was read";
  } catch (const hgd::IoError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("big.xyz"), std::string::npos) << m;
    EXPECT_NE(m.find("out of range"), std::string::npos) << m;
    EXPECT_NE(m.find("line 3"), std::string::npos) << m;
  }
  writeText(path("inf.xyz"), "0 0 0 1\n1 0 0 2\n0 1 0 inf\n");
  EXPECT_TRUE(std::isinf(value(hgd::readShape(path("inf.xyz")), 2, "field3")));
}

// Leica PTS as Open3D and scanners write it: the point count, then x y z intensity r g b. Read
// with every column, written back as the same text, converted to PLY with its intensity and
// colours, and made from a PLY with the count and the columns a PTS reader expects.
TEST_F(OthersFiles, LeicaPtsKeepsEveryColumn) {
  std::string pts = "300\n";
  std::mt19937 rng(4);
  std::vector<int> intensity, red;
  for (int i = 0; i < 300; ++i) {
    char row[160];
    intensity.push_back(static_cast<int>(rng() % 4096) - 2048);
    red.push_back(static_cast<int>(rng() % 256));
    std::snprintf(row, sizeof row, "%.10f %.10f %.10f %d %d %d %d\n", 0.01 * (i % 30), 0.013 * (i / 30),
                  0.1 * std::sin(0.3 * i), intensity.back(), red.back(), i % 256, 7);
    pts += row;
  }
  writeText(path("scan.pts"), pts);
  const Shape s = hgd::readShape(path("scan.pts"));
  EXPECT_TRUE(s.warnings.empty()) << s.warnings.front();
  ASSERT_EQ(s.size(), 300u);
  EXPECT_EQ(datatypeOf(s, "red"), pcl::PCLPointField::UINT8);
  for (std::size_t i = 0; i < 300; ++i) {
    ASSERT_EQ(value(s, i, "intensity"), intensity[i]) << i;
    ASSERT_EQ(value(s, i, "red"), red[i]) << i;
  }
  hgd::writeShape(path("back.pts"), s);
  EXPECT_EQ(slurp(path("back.pts")), pts);
  hgd::writeShape(path("scan.ply"), s);
  pcl::PointCloud<pcl::PointXYZRGB> coloured;
  ASSERT_EQ(pcl::io::loadPLYFile(path("scan.ply"), coloured), 0);
  pcl::PointCloud<pcl::PointXYZI> with_intensity;
  ASSERT_EQ(pcl::io::loadPLYFile(path("scan.ply"), with_intensity), 0);
  ASSERT_EQ(coloured.size(), 300u);
  for (std::size_t i = 0; i < 300; ++i) {
    ASSERT_EQ(coloured[i].r, red[i]) << i;
    ASSERT_EQ(with_intensity[i].intensity, static_cast<float>(intensity[i])) << i;
  }
  // As XYZ it needs a row of names, else its fourth column would be read as field3.
  hgd::writeShape(path("scan.xyz"), s);
  EXPECT_EQ(value(hgd::readShape(path("scan.xyz")), 5, "intensity"), intensity[5]);
  // From the PLY: the count, then x y z intensity red green blue.
  hgd::writeShape(path("again.pts"), hgd::readShape(path("scan.ply")));
  const std::string again = slurp(path("again.pts"));
  EXPECT_EQ(again.substr(0, 4), "300\n");
  const Shape t = hgd::readShape(path("again.pts"));
  for (std::size_t i = 0; i < 300; ++i) {
    ASSERT_EQ(value(t, i, "intensity"), intensity[i]) << i;
    ASSERT_EQ(value(t, i, "red"), red[i]) << i;
    ASSERT_EQ(value(t, i, "x"), value(s, i, "x")) << i;
  }
  // A count that is not the number of rows is an error naming the line.
  writeText(path("short.pts"), "5\n0 0 0\n1 0 0\n0 1 0\n");
  try {
    hgd::readShape(path("short.pts"));
    ADD_FAILURE() << "a wrong count was read";
  } catch (const hgd::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("line 1 gives the point count 5"), std::string::npos) << e.what();
  }
}

// PCL writes a packed rgb whose alpha byte is 0 (a cloud converted from a PLY without alpha):
// converted to PLY or XYZ that is no alpha column (MeshLab would draw every point transparent).
// Alphas that say something (rgba, or rgb alphas that differ) are kept.
TEST_F(OthersFiles, PclsAlphaOfZeroIsNoAlphaColumn) {
  for (const std::uint8_t alpha : {std::uint8_t{0}, std::uint8_t{255}}) {
    const auto cloud = as<pcl::PointXYZRGB>(scanLike(300, 5, alpha));
    ASSERT_EQ(pcl::io::savePCDFileBinary(path("rgb.pcd"), cloud), 0);
    const Shape s = hgd::readShape(path("rgb.pcd"));
    hgd::writeShape(path("rgb.ply"), s);
    hgd::writeShape(path("rgb.xyz"), s);
    const std::string head = slurp(path("rgb.ply")).substr(0, 400);
    EXPECT_EQ(head.find("alpha"), std::string::npos) << int{alpha} << ": " << head;
    EXPECT_NE(head.find("property uchar red\n"), std::string::npos) << head;
    const std::string xyz = slurp(path("rgb.xyz"));
    EXPECT_EQ(xyz.substr(0, xyz.find('\n')).find("alpha"), std::string::npos) << xyz.substr(0, 80);
    pcl::PointCloud<pcl::PointXYZRGB> back;
    ASSERT_EQ(pcl::io::loadPLYFile(path("rgb.ply"), back), 0);
    ASSERT_EQ(back.size(), cloud.size());
    for (std::size_t i = 0; i < cloud.size(); ++i)
      ASSERT_TRUE(back[i].r == cloud[i].r && back[i].g == cloud[i].g && back[i].b == cloud[i].b) << i;
  }
  auto mixed = as<pcl::PointXYZRGB>(scanLike(300, 5));
  for (std::size_t i = 0; i < mixed.size(); ++i) mixed[i].a = static_cast<std::uint8_t>(i % 3 * 100);
  ASSERT_EQ(pcl::io::savePCDFileBinary(path("mixed.pcd"), mixed), 0);
  hgd::writeShape(path("mixed.ply"), hgd::readShape(path("mixed.pcd")));
  const Shape m = hgd::readShape(path("mixed.ply"));
  for (std::size_t i = 0; i < mixed.size(); ++i) ASSERT_EQ(value(m, i, "alpha"), (i % 3) * 100.0) << i;
}

// A shape made in memory (the Python module's Shape(points, normals), a C++ program's cloud)
// written as PCD gets PCL's names too: PCL's typed reader finds the normals and colours.
TEST_F(OthersFiles, AShapeMadeInMemoryIsWrittenWithPclsNames) {
  const auto ref = scanLike(200, 9);
  pcl::PointCloud<pcl::PointXYZ> xyz = as<pcl::PointXYZ>(ref);
  Shape s;
  pcl::toPCLPointCloud2(xyz, s.cloud);
  const auto add = [&](const char* name, std::uint8_t type) {
    pcl::PCLPointField f;
    f.name = name;
    f.offset = s.cloud.point_step;
    f.datatype = type;
    f.count = 1;
    s.cloud.fields.push_back(f);
    s.cloud.point_step += static_cast<std::uint32_t>(hgd::datatypeSize(type));
  };
  const std::uint32_t old_step = s.cloud.point_step;
  add("nx", pcl::PCLPointField::FLOAT32);
  add("ny", pcl::PCLPointField::FLOAT32);
  add("nz", pcl::PCLPointField::FLOAT32);
  add("red", pcl::PCLPointField::UINT8);
  add("green", pcl::PCLPointField::UINT8);
  add("blue", pcl::PCLPointField::UINT8);
  std::vector<std::uint8_t> data(s.cloud.point_step * ref.size());
  for (std::size_t i = 0; i < ref.size(); ++i) {
    std::uint8_t* d = data.data() + i * s.cloud.point_step;
    std::memcpy(d, s.cloud.data.data() + i * old_step, old_step);
    std::memcpy(d + old_step, &ref[i].normal_x, 4);
    std::memcpy(d + old_step + 4, &ref[i].normal_y, 4);
    std::memcpy(d + old_step + 8, &ref[i].normal_z, 4);
    d[old_step + 12] = ref[i].r;
    d[old_step + 13] = ref[i].g;
    d[old_step + 14] = ref[i].b;
  }
  s.cloud.data = std::move(data);
  s.cloud.row_step = s.cloud.point_step * s.cloud.width;
  ASSERT_TRUE(s.path.empty());
  hgd::writeShape(path("mem.pcd"), s);
  pcl::PointCloud<pcl::PointXYZRGBNormal> back;
  ASSERT_EQ(pcl::io::loadPCDFile(path("mem.pcd"), back), 0);
  ASSERT_EQ(back.size(), ref.size());
  for (std::size_t i = 0; i < ref.size(); ++i) {
    ASSERT_EQ(bits(back[i].normal_y), bits(ref[i].normal_y)) << i;
    ASSERT_TRUE(back[i].r == ref[i].r && back[i].g == ref[i].g && back[i].b == ref[i].b) << i;
  }
}

// A big-endian binary PLY (as SGI-era tools and some scanners write) comes back big-endian,
// every byte of its body the same, and PCL reads it.
TEST_F(OthersFiles, ABigEndianPlyComesBackBigEndian) {
  const auto cloud = as<pcl::PointXYZ>(scanLike(64, 21));
  std::string body;
  const auto be = [&body](const void* p, std::size_t n) {
    const auto* b = static_cast<const char*>(p);
    for (std::size_t k = n; k-- > 0;) body += b[k];
  };
  for (const auto& p : cloud) {
    be(&p.x, 4);
    be(&p.y, 4);
    be(&p.z, 4);
    const std::uint16_t label = static_cast<std::uint16_t>(&p - &cloud[0]) * 1000u;
    be(&label, 2);
  }
  for (std::int32_t f = 0; f + 2 < 64; f += 3) {
    body += '\3';
    for (std::int32_t k = 0; k < 3; ++k) {
      const std::int32_t v = f + k;
      be(&v, 4);
    }
  }
  const std::string head =
      "ply\nformat binary_big_endian 1.0\nelement vertex 64\nproperty float x\nproperty float y\n"
      "property float z\nproperty ushort label\nelement face 21\nproperty list uchar int vertex_indices\n"
      "end_header\n";
  writeText(path("be.ply"), head + body);
  const Shape s = hgd::readShape(path("be.ply"));
  hgd::writeShape(path("back.ply"), s);
  const std::string back = slurp(path("back.ply"));
  EXPECT_NE(back.find("format binary_big_endian 1.0\n"), std::string::npos) << back.substr(0, 200);
  const std::size_t end = back.find("end_header\n");
  ASSERT_NE(end, std::string::npos);
  EXPECT_TRUE(back.substr(end + 11) == body) << "the body differs";
  pcl::PointCloud<pcl::PointXYZ> pcl_back;
  ASSERT_EQ(pcl::io::loadPLYFile(path("back.ply"), pcl_back), 0);
  ASSERT_EQ(pcl_back.size(), cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) ASSERT_EQ(bits(pcl_back[i].y), bits(cloud[i].y)) << i;
}

// A box's faces are compared with the file's own values: a double row at y = 0.3 is in a box
// whose max y is 0.3, wherever the shape lies (here 10 km from the origin, where a float step
// is a millimetre).
TEST_F(OthersFiles, ABoxTestsTheFilesDoubleValues) {
  std::string ply =
      "ply\nformat ascii 1.0\nelement vertex 1100\nproperty double x\nproperty double y\nproperty double z\n"
      "end_header\n";
  std::vector<std::string> ys;
  for (int r = 0; r < 11; ++r)
    for (int c = 0; c < 100; ++c) {
      char y[32];
      std::snprintf(y, sizeof y, "%.1f", 0.1 * r);
      ys.push_back(y);
      ply += std::to_string(10000 + c) + ".25 " + y + " " + std::to_string(c % 3) + "\n";
    }
  writeText(path("rows.ply"), ply);
  const Shape s = hgd::readShape(path("rows.ply"));
  const hgd::Geometry g = hgd::extractGeometry(s);
  for (const char* top : {"0.3", "0.7", "0.6"}) {
    const double max_y = std::strtod(top, nullptr);
    std::size_t want = 0;
    for (const std::string& y : ys) want += std::strtod(y.c_str(), nullptr) <= max_y;
    const hgd::Region box = hgd::Region::box(Eigen::Vector3d(0, -1, -1), Eigen::Vector3d(1e5, max_y, 5));
    EXPECT_EQ(hgd::selectRegion(box, g, s, "test").size(), want) << "max y " << top;
    const hgd::Region low = hgd::Region::box(Eigen::Vector3d(0, max_y, -1), Eigen::Vector3d(1e5, 2, 5));
    std::size_t above = 0;
    for (const std::string& y : ys) above += std::strtod(y.c_str(), nullptr) >= max_y;
    EXPECT_EQ(hgd::selectRegion(low, g, s, "test").size(), above) << "min y " << top;
  }
}

}  // namespace
