// A shape larger than memory is refused before it is read: the header probe's counts (against
// what the readers find, in files the project wrote and files PCL wrote), the estimate of a
// deform's peak (against the peak measured), and `--memory` in `deform` and `batch`.
#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>

#include "hgdeform/app/memory.h"
#include "hgdeform/io/io.h"
#include "support/shapes.h"
#include "test_util.h"

namespace {

using hgdtest::contains;
using hgdtest::quote;
using hgdtest::shell;
using hgdtest::TempDir;

const std::string kTool = HGD_TOOL;

// The bumpy sphere's top fixed, its bottom pulled down and turned.
const char* const kScenario = R"({
  "format": "hgdeform-scenario/1",
  "fixed": [ { "box": { "min": [-2, -2, 0.8], "max": [2, 2, 2] } } ],
  "manipulated": { "box": { "min": [-2, -2, -2], "max": [2, 2, -0.8] } },
  "move": { "frame": { "translate": [0, 0, -0.2], "rotate": { "axis": [1, 0, 0], "degrees": 10 } } }
})";

/// The bumpy sphere of about n points, its points shuffled (as a merged or resampled scan comes).
hgd::Shape shuffledSphere(std::size_t n) {
  hgd::Shape s = hgd::shapes::bumpySphere(n);
  const std::size_t m = s.size(), step = s.cloud.point_step;
  std::vector<std::size_t> order(m);
  for (std::size_t i = 0; i < m; ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), std::mt19937(7));
  std::vector<std::uint8_t> data(s.cloud.data.size());
  for (std::size_t i = 0; i < m; ++i)
    std::memcpy(data.data() + i * step, s.cloud.data.data() + order[i] * step, step);
  s.cloud.data.swap(data);
  return s;
}

TEST(Probe, HeaderCountsAreWhatTheReadersFind) {
  TempDir dir;
  const hgd::Shape cloud = shuffledSphere(5000);
  const hgd::Shape mesh = hgd::shapes::barMesh();
  ASSERT_GT(mesh.polygons.size(), 0u);
  struct Case {
    std::string name;
    const hgd::Shape* shape;
    hgd::Encoding encoding;
  };
  const Case cases[] = {{"c.ply", &cloud, hgd::Encoding::Binary}, {"ca.ply", &cloud, hgd::Encoding::Ascii},
                        {"c.pcd", &cloud, hgd::Encoding::Binary}, {"ca.pcd", &cloud, hgd::Encoding::Ascii},
                        {"c.las", &cloud, hgd::Encoding::Binary}, {"m.ply", &mesh, hgd::Encoding::Binary},
                        {"m.off", &mesh, hgd::Encoding::Ascii}};
  for (const Case& c : cases) {
    const std::string path = dir.file(c.name);
    hgd::WriteOptions wo;
    wo.encoding = c.encoding;
    hgd::writeShape(path, *c.shape, wo);
    const hgd::Shape read = hgd::readShape(path);
    const hgd::ShapeSize size = hgd::probeShapeSize(path);
    EXPECT_TRUE(size.exact) << c.name;
    EXPECT_EQ(size.points, read.size()) << c.name;
    EXPECT_EQ(size.faces, read.polygons.size()) << c.name;
    EXPECT_EQ(size.file_bytes, std::filesystem::file_size(path)) << c.name;
    if (c.name == "c.las") {  // (its coordinates are integers in the file, doubles when read)
      EXPECT_NEAR(static_cast<double>(size.record_bytes) + 20, read.cloud.point_step, 4) << c.name;
    } else if (c.name != "m.off") {
      EXPECT_EQ(size.record_bytes, read.cloud.point_step) << c.name;
    }
  }
  // Text rows: an upper estimate from the size, never below the count.
  const std::string xyz = dir.file("c.xyz");
  hgd::writeShape(xyz, cloud);
  const hgd::ShapeSize text = hgd::probeShapeSize(xyz);
  EXPECT_FALSE(text.exact);
  EXPECT_GE(text.points, cloud.size());
  EXPECT_LE(text.points, 4 * cloud.size());
}

TEST(Probe, PclsBinaryPcdWithPagePaddingAndAnOrganisedCloud) {
  // PCL's own binary writer pads its header to a page; an organised cloud declares WIDTH and
  // HEIGHT, and its NaN points are records like any other.
  TempDir dir;
  pcl::PointCloud<pcl::PointXYZRGBNormal> cloud(64, 48);
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    auto& p = cloud[i];
    p.x = static_cast<float>(i % 64);
    p.y = static_cast<float>(i / 64);
    p.z = i % 7 == 0 ? NAN : 1.0f;
  }
  cloud.is_dense = false;
  const std::string path = dir.file("pcl.pcd");
  ASSERT_EQ(pcl::io::savePCDFileBinary(path, cloud), 0);
  const hgd::ShapeSize size = hgd::probeShapeSize(path);
  const hgd::Shape read = hgd::readShape(path);
  EXPECT_TRUE(size.exact);
  EXPECT_EQ(size.points, 64u * 48u);
  EXPECT_EQ(size.points, read.size());
  EXPECT_EQ(size.record_bytes, read.cloud.point_step);
}

TEST(Probe, AMalformedMissingOrUnknownFileIsLeftToTheReader) {
  TempDir dir;
  const std::string bad = dir.file("bad.ply");
  hgdtest::writeText(bad, "ply\nformat binary_little_endian 1.0\nelement vertex lots\nend_header\n");
  const hgd::ShapeSize size = hgd::probeShapeSize(bad);
  EXPECT_EQ(size.points, 0u);
  EXPECT_FALSE(size.exact);
  // A count the data cannot hold (a corrupt or truncated file) is no size either.
  const std::string claims = dir.file("claims.ply");
  hgdtest::writeText(claims,
                     "ply\nformat binary_little_endian 1.0\nelement vertex 1000\nproperty float x\n"
                     "property float y\nproperty float z\nend_header\n" +
                         std::string(11988, 'x'));
  EXPECT_EQ(hgd::probeShapeSize(claims).points, 0u);
  hgdtest::writeText(claims,
                     "ply\nformat binary_little_endian 1.0\nelement vertex 1000\nproperty float x\n"
                     "property float y\nproperty float z\nend_header\n" +
                         std::string(12000, 'x'));
  EXPECT_EQ(hgd::probeShapeSize(claims).points, 1000u);
  // A missing file, or one of no format, is left to the reader too (its error names the file).
  EXPECT_EQ(hgd::probeShapeSize(dir.file("missing.ply")).points, 0u);
  hgdtest::writeText(bad, "\x89PNG\r\n\x1a\n");
  EXPECT_EQ(hgd::probeShapeSize(bad).points, 0u);
}

TEST(Memory, ByteCountsAsUsersWriteThem) {
  std::uint64_t b = 0;
  ASSERT_TRUE(hgd::parseByteCount("1500000000", &b));
  EXPECT_EQ(b, 1500000000u);
  ASSERT_TRUE(hgd::parseByteCount("1.5G", &b));
  EXPECT_EQ(b, 1610612736u);
  ASSERT_TRUE(hgd::parseByteCount("800m", &b));
  EXPECT_EQ(b, 800u << 20);
  ASSERT_TRUE(hgd::parseByteCount("64KiB", &b));
  EXPECT_EQ(b, 64u << 10);
  ASSERT_TRUE(hgd::parseByteCount("2TB", &b));
  EXPECT_EQ(b, std::uint64_t{2} << 40);
  for (const char* bad : {"", "G", "-1", "0", "1.5X", "1..5G", "1e9", "12 G", "0.5"})
    EXPECT_FALSE(hgd::parseByteCount(bad, &b)) << bad;
  EXPECT_EQ(hgd::byteText(1610612736), "1.5 GB");
  EXPECT_EQ(hgd::byteText(512), "512 bytes");
}

TEST(Memory, TheMachineSaysWhatItHasAvailable) {
  const std::uint64_t available = hgd::availableMemory();
  // Between 16 MB and 16 TB on any machine this runs on (read from /proc/meminfo).
  EXPECT_GT(available, std::uint64_t{16} << 20);
  EXPECT_LT(available, std::uint64_t{16} << 40);
}

/// The peak a deform reports (its resident set), in bytes; -1 when it failed.
double deformPeak(const std::string& in, const std::string& scenario, const std::string& out,
                  const std::string& extra = "") {
  const std::string report = out + ".json";
  const auto r = shell(quote(kTool) + " deform " + quote(in) + " -s " + quote(scenario) + " -o " +
                       quote(out) + " -q -r " + quote(report) + " " + extra);
  if (r.code != 0) {
    ADD_FAILURE() << r.err;
    return -1;
  }
  return nlohmann::json::parse(hgdtest::slurp(report)).at("peak_rss_mb").get<double>() * 1048576.0;
}

TEST(Memory, TheEstimateIsNearTheMeasuredPeak) {
#ifdef HGD_TEST_ASAN
  GTEST_SKIP() << "the sanitizer's shadow memory and quarantine are no peak of the program's";
#endif
  // The multi-resolution build (300k points) and the full-resolution graph (60k): the estimate
  // the refusal rests on stays within 0.7x-1.5x of the peak measured (0.9x-1.3x when written).
  TempDir dir;
  const std::string scenario = dir.file("s.json");
  hgdtest::writeText(scenario, kScenario);
  for (const std::size_t n : {std::size_t{300000}, std::size_t{60000}}) {
    const std::string in = dir.file("in" + std::to_string(n) + ".ply");
    hgd::writeShape(in, shuffledSphere(n));
    const double peak = deformPeak(in, scenario, dir.file("out.ply"));
    const hgd::ShapeSize size = hgd::probeShapeSize(in);
    const double estimate = static_cast<double>(hgd::deformMemoryEstimate(size, n <= 131072));
    std::printf("[ memory   ] %zu points: estimate %.1f MB, peak %.1f MB (%.2fx)\n", n, estimate / 1048576,
                peak / 1048576, estimate / peak);
    EXPECT_GT(estimate, 0.7 * peak) << n << " points: estimate " << estimate << ", peak " << peak;
    EXPECT_LT(estimate, 1.5 * peak) << n << " points: estimate " << estimate << ", peak " << peak;
  }
}

// A shape over the memory is refused before it is read when its file cannot be streamed (an
// ascii PLY), and streamed when it can (the same scan in binary): the output then is the one the
// run in memory writes, byte for byte.
TEST(Memory, DeformRefusesAShapeOverItsMemoryBeforeReadingIt) {
  TempDir dir;
  const std::string scenario = dir.file("s.json");
  hgdtest::writeText(scenario, kScenario);
  const std::string in = dir.file("scan.ply"), out = dir.file("out.ply");
  hgd::WriteOptions ascii;
  ascii.encoding = hgd::Encoding::Ascii;
  const hgd::Shape sphere = shuffledSphere(300000);
  hgd::writeShape(in, sphere, ascii);
  const std::string base =
      quote(kTool) + " deform " + quote(in) + " -s " + quote(scenario) + " -o " + quote(out);
  // About 75 MB for 300,000 points of 24 bytes: refused under 40 MB, with the reason.
  auto r = shell(base + " --memory 40M");
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_TRUE(contains(r.err, in)) << r.err;
  EXPECT_TRUE(contains(r.err, "300000 points")) << r.err;
  EXPECT_TRUE(contains(r.err, "more than the 40 MB that --memory allows")) << r.err;
  EXPECT_FALSE(std::filesystem::exists(out));
  EXPECT_EQ(dir.list().size(), 2u);  // nothing left behind
  // --full-field: the full-resolution graph's estimate, far above the coarse build's.
  r = shell(base + " --memory 100M --full-field");
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_TRUE(contains(r.err, "at full resolution")) << r.err;
  EXPECT_TRUE(contains(r.err, "without --full-field")) << r.err;
  r = shell(base + " --memory 100M -q");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(std::filesystem::exists(out));
  r = shell(base + " --memory 12X");
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_TRUE(contains(r.err, "--memory")) << r.err;
  // In binary: streamed under 40 MB, said, and the output the run in memory writes.
  const std::string bin = dir.file("scan_binary.ply"), out_memory = dir.file("memory.ply"),
                    out_streamed = dir.file("streamed.ply");
  hgd::writeShape(bin, sphere);
  const std::string bin_base = quote(kTool) + " deform " + quote(bin) + " -s " + quote(scenario) + " -q -o ";
  r = shell(bin_base + quote(out_memory));
  ASSERT_EQ(r.code, 0) << r.err;
  r = shell(bin_base + quote(out_streamed) + " --memory 40M");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(contains(r.err, "streamed")) << r.err;
  EXPECT_TRUE(hgdtest::slurp(out_memory) == hgdtest::slurp(out_streamed));
}

// In a batch, a scan over the memory is streamed when its file allows (a binary PCD: the bytes
// `hgdeform deform` writes holding it), and fails with the reason when it does not (ascii); the
// others are deformed.
TEST(Memory, BatchStreamsTheScanOverItsMemoryOrFailsItAndDeformsTheOthers) {
  TempDir dir;
  const std::filesystem::path scans = dir.path() / "scans", outs = dir.path() / "out";
  std::filesystem::create_directories(scans);
  const std::string scenario = dir.file("s.json");
  hgdtest::writeText(scenario, kScenario);
  hgd::writeShape((scans / "small.ply").string(), shuffledSphere(4000));
  const hgd::Shape large = shuffledSphere(300000);
  hgd::writeShape((scans / "large.pcd").string(), large);
  hgd::WriteOptions ascii;
  ascii.encoding = hgd::Encoding::Ascii;
  hgd::writeShape((scans / "large_ascii.ply").string(), large, ascii);
  const auto r = shell(quote(kTool) + " batch " + quote(scans.string()) + " -s " + quote(scenario) + " -o " +
                       quote(outs.string()) + " --memory 40M");
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_TRUE(contains(r.err, "large_ascii.ply")) << r.err;
  EXPECT_TRUE(contains(r.err, "that --memory allows")) << r.err;
  EXPECT_TRUE(contains(r.err, "large.pcd: note: streamed")) << r.err;
  EXPECT_TRUE(std::filesystem::exists(outs / "small.ply"));
  EXPECT_FALSE(std::filesystem::exists(outs / "large_ascii.ply"));
  const std::string memory = dir.file("memory.pcd");
  const auto m = shell(quote(kTool) + " deform " + quote((scans / "large.pcd").string()) + " -s " +
                       quote(scenario) + " -q -o " + quote(memory));
  ASSERT_EQ(m.code, 0) << m.err;
  EXPECT_TRUE(hgdtest::slurp(memory) == hgdtest::slurp((outs / "large.pcd").string()));
}

}  // namespace
