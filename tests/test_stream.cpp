// Scans larger than memory: a file's points read in place as records (readRecordLayout,
// RecordReader), and the coarse level built by passes over them (streamCoarseLevel), which
// must be the one extractGeometry and coarsen build in memory, point for point.
#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "hgdeform/deformer/deformer.h"
#include "hgdeform/deformer/streamed.h"
#include "hgdeform/io/fields.h"
#include "hgdeform/io/geometry.h"
#include "hgdeform/io/io.h"
#include "hgdeform/io/records.h"
#include "hgdeform/multires/multires.h"
#include "hgdeform/multires/streamed.h"
#include "stream_fixtures.h"
#include "support/shapes.h"

namespace {

using hgd_test::fileBytes;
using hgd_test::recordHandles;
using hgd_test::TempDir;
using hgd_test::userScan;

/// The same handles as geometry indices.
hgd::Handles geometryHandles(const hgd::RecordHandles& r, const hgd::Geometry& g) {
  const auto map = [&](const std::vector<std::uint64_t>& records) {
    std::vector<int> out;
    for (const std::uint64_t i : records) {
      const int k = g.finite_index[static_cast<std::size_t>(i)];
      if (k >= 0) out.push_back(k);
    }
    std::sort(out.begin(), out.end());
    return out;
  };
  hgd::Handles h;
  for (const auto& f : r.fixed) h.fixed.push_back(map(f));
  h.manipulated = map(r.manipulated);
  for (const auto& j : r.joints) h.joints.push_back(map(j));
  return h;
}

/// Compares the streamed level of `path` with extractGeometry + coarsen of the file read whole.
void expectSameLevel(const std::string& path, const hgd::RecordHandles& handles, std::size_t coarse_points) {
  SCOPED_TRACE(path);
  const hgd::Shape shape = hgd::readShape(path);
  const hgd::Geometry g = hgd::extractGeometry(shape);
  const std::size_t records = shape.size();
  const std::size_t target = std::min(coarse_points, g.size() / 10);
  const hgd::Handles gh = geometryHandles(handles, g);
  const hgd::CoarseLevel level = hgd::coarsen(*g.points, gh, target, true, &g.raw_index, records);
  ASSERT_FALSE(level.empty());

  const hgd::RecordLayout layout = hgd::readRecordLayout(path);
  hgd::StreamedLevelOptions options;
  options.coarse_points = coarse_points;
  options.block = 4096;  // many blocks
  const hgd::StreamedLevel s = hgd::streamCoarseLevel(layout, handles, options);

  // The frame.
  EXPECT_EQ(s.origin, g.origin);
  EXPECT_EQ(s.body.min(), g.body.min());
  EXPECT_EQ(s.body.max(), g.body.max());
  EXPECT_EQ(s.points, g.size());
  EXPECT_EQ(s.far_points, g.far_points);
  EXPECT_EQ(s.warnings, g.warnings);
  EXPECT_EQ(s.warnings.size(), g.warnings.size());
  EXPECT_FALSE(s.warnings.empty());  // far points (and zeros) were set apart
  EXPECT_EQ(s.file_normals, g.hasFileNormals());
  // The level: its cell, its points (their records, positions, normals, weights, order).
  EXPECT_EQ(s.cell, level.cell);
  ASSERT_EQ(s.coarse.size(), level.points.size());
  std::size_t differ = 0;
  for (std::size_t a = 0; a < level.points.size(); ++a) {
    const auto k = static_cast<std::size_t>(level.points[a]);
    differ += s.coarse_record[a] != static_cast<std::uint64_t>(g.raw_index[k]);
    differ += s.coarse[a].getVector3fMap() != (*g.points)[k].getVector3fMap();
    if (g.hasFileNormals())
      differ += s.normals[a].getNormalVector3fMap() != (*g.file_normals)[k].getNormalVector3fMap();
  }
  EXPECT_EQ(differ, 0u) << "coarse points that differ";
  EXPECT_EQ(s.weight, level.weight);
  const hgd::Handles ch = hgd::coarseHandles(gh, level);
  EXPECT_EQ(s.coarse_fixed, ch.fixed);
  EXPECT_EQ(s.coarse_manipulated, ch.manipulated);
  EXPECT_EQ(s.coarse_joints, ch.joints);
  EXPECT_FALSE(s.coarse_manipulated.empty());
  std::size_t order_differs = 0;  // Geometry's order among the coarse points
  for (std::size_t a = 0; a + 1 < level.points.size(); ++a)
    order_differs += (s.morton_rank[a] < s.morton_rank[a + 1]) != (level.points[a] < level.points[a + 1]);
  EXPECT_EQ(order_differs, 0u);
  std::vector<std::uint64_t> strays;
  for (const int i : level.strays)
    strays.push_back(static_cast<std::uint64_t>(g.raw_index[static_cast<std::size_t>(i)]));
  std::sort(strays.begin(), strays.end());
  EXPECT_EQ(s.strays, strays);
  EXPECT_FALSE(strays.empty());
  // Every kept point's anchor, as the streamed level finds it from its record and position.
  std::size_t anchors_differ = 0;
  for (std::size_t k = 0; k < g.size(); ++k) {
    const auto i = static_cast<std::uint64_t>(g.raw_index[k]);
    anchors_differ += s.anchorOf(i, (*g.points)[k].getVector3fMap(), s.classOf(i)) != level.anchor[k];
  }
  EXPECT_EQ(anchors_differ, 0u);
  // What Geometry set apart is what the streamed level does not keep.
  std::size_t kept_differ = 0;
  const hgd::XyzFields f = hgd::findXyzFields(shape.cloud);
  for (std::size_t i = 0; i < records; ++i) {
    const Eigen::Vector3d w(
        hgd::readValue(shape.cloud, i, shape.cloud.fields[static_cast<std::size_t>(f.x)]),
        hgd::readValue(shape.cloud, i, shape.cloud.fields[static_cast<std::size_t>(f.y)]),
        hgd::readValue(shape.cloud, i, shape.cloud.fields[static_cast<std::size_t>(f.z)]));
    const bool kept = w.allFinite() && s.kept(i, w);
    kept_differ += kept != (g.finite_index[i] >= 0);
  }
  EXPECT_EQ(kept_differ, 0u);
}

}  // namespace

// The records of a binary PLY (hgdeform's, with a comment and an element after the vertices)
// and of PCL's binary PCD (page-padded) are where the layout says, byte for byte what readShape
// reads; files whose points are not such records are refused, naming the file and why.
TEST(Stream, LayoutPlacesTheRecordsOfBinaryPlyAndPclsPcd) {
  TempDir tmp;
  const hgd::Shape scan = userScan(3000, 3, Eigen::Vector3d(0, 0, 0), false);
  const std::string ply = tmp / "scan.ply";
  hgd::writeShape(ply, scan);
  pcl::PointCloud<pcl::PointNormal> pn;
  for (int i = 0; i < 1234; ++i) {
    pcl::PointNormal q;
    q.x = static_cast<float>(i) * 0.5f;
    q.y = static_cast<float>(i % 7);
    q.z = -static_cast<float>(i % 13);
    q.normal_x = 1;
    q.normal_y = q.normal_z = 0;
    pn.push_back(q);
  }
  const std::string pcd = tmp / "pcl.pcd";
  ASSERT_EQ(pcl::io::savePCDFileBinary(pcd, pn), 0);
  for (const std::string& path : {ply, pcd}) {
    SCOPED_TRACE(path);
    const hgd::Shape whole = hgd::readShape(path);
    const hgd::RecordLayout layout = hgd::readRecordLayout(path);
    EXPECT_EQ(layout.count, whole.size());
    EXPECT_EQ(layout.bytes, whole.cloud.point_step);
    EXPECT_TRUE(layout.shape.cloud.data.empty());
    EXPECT_EQ(layout.shape.cloud.fields.size(), whole.cloud.fields.size());
    EXPECT_GT(layout.offset, 100u);  // after the header
    const hgd::RecordReader reader(layout);
    std::vector<std::uint8_t> all(whole.cloud.data.size());
    const std::size_t half = whole.size() / 2;
    reader.read(0, half, all.data());
    reader.read(half, whole.size() - half, all.data() + half * layout.bytes);
    EXPECT_TRUE(all == whole.cloud.data);
    std::vector<std::uint8_t> one(layout.bytes);
    EXPECT_THROW(reader.read(whole.size(), 1, one.data()), hgd::IoError);
  }
  // Not records in place: ascii PLY, compressed PCD, a text format.
  const std::string ascii = tmp / "ascii.ply", compressed = tmp / "c.pcd", xyz = tmp / "s.xyz";
  hgd::WriteOptions text;
  text.encoding = hgd::Encoding::Ascii;
  hgd::writeShape(ascii, scan, text);
  ASSERT_EQ(pcl::io::savePCDFileBinaryCompressed(compressed, pn), 0);
  hgd::writeShape(xyz, scan);
  for (const std::string& path : {ascii, compressed, xyz}) {
    try {
      hgd::readRecordLayout(path);
      ADD_FAILURE() << path << " was not refused";
    } catch (const hgd::IoError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(path), std::string::npos) << what;
      EXPECT_NE(what.find("cannot read the points in place"), std::string::npos) << what;
    }
  }
}

// The streamed level of a scan as users' files hold it is the one built in memory: the frame
// (origin, body, what is set apart and the warnings), the coarse points (records, positions,
// normals, weights, Geometry's order among them), the strays and every point's anchor. In a
// binary PLY of double coordinates at a georeferenced offset with 'no return' zeros, and in
// PCL's binary PCD of floats.
TEST(Stream, CoarseLevelIsTheOneBuiltInMemory) {
  TempDir tmp;
  {
    const Eigen::Vector3d offset(512345.25, 4187654.5, 312.0);
    const hgd::Shape scan = userScan(60000, 5, offset, true);
    const std::string ply = tmp / "survey.ply";
    hgd::writeShape(ply, scan);
    expectSameLevel(ply, recordHandles(scan, offset), 3000);
  }
  {
    const hgd::Shape scan = userScan(60000, 7, Eigen::Vector3d::Zero(), false);
    const pcl::PointCloud<pcl::PointNormal> pn = hgd_test::asPointNormals(scan);
    const std::string pcd = tmp / "pcl.pcd";
    ASSERT_EQ(pcl::io::savePCDFileBinary(pcd, pn), 0);
    const hgd::Shape read = hgd::readShape(pcd);
    expectSameLevel(pcd, recordHandles(read, Eigen::Vector3d::Zero()), 6000);
  }
}

// The Deformer on the streamed level (holding the coarse points and the manipulated handle's,
// a fraction of the scan) solves what the Deformer on the whole file read into memory solves at
// the same resolution, bit for bit: the same clusters, the same field and handle centre, and
// after a frame move (a turn about the handle's centre and a shift) the same transforms and
// positions. On the georeferenced scan of doubles with NaN records, zeros and far strays.
TEST(Stream, DeformerOnTheStreamedLevelSolvesAsInMemory) {
  TempDir tmp;
  const Eigen::Vector3d offset(512345.25, 4187654.5, 312.0);
  const hgd::Shape scan = userScan(60000, 11, offset, true);
  const std::string ply = tmp / "survey.ply";
  hgd::writeShape(ply, scan);
  const hgd::RecordHandles rh = recordHandles(scan, offset);
  hgd::DeformOptions options;
  options.multires_above = 1;
  options.coarse_points = 3000;
  options.points_per_coarse = 10;

  auto g = std::make_shared<const hgd::Geometry>(hgd::extractGeometry(hgd::readShape(ply)));
  hgd::Deformer whole(g, geometryHandles(rh, *g), options);
  ASSERT_FALSE(whole.coarseLevel().empty());

  const hgd::RecordLayout layout = hgd::readRecordLayout(ply);
  hgd::StreamedLevelOptions level_options;
  level_options.coarse_points = options.coarse_points;
  level_options.points_per_coarse = options.points_per_coarse;
  const hgd::StreamedLevel level = hgd::streamCoarseLevel(layout, rh, level_options);
  hgd::StreamedDeformer s = hgd::streamedDeformer(layout, level, rh, options);
  hgd::Deformer& d = *s.deformer;
  EXPECT_LT(s.geometry->size(), g->size() / 5);

  // The build: clusters (kinds, barycentres), the field at the held points.
  const auto& ca = whole.clustering().clusters;
  const auto& cb = d.clustering().clusters;
  ASSERT_EQ(ca.size(), cb.size());
  for (std::size_t k = 0; k < ca.size(); ++k) {
    EXPECT_EQ(ca[k].kind, cb[k].kind) << "cluster " << k;
    EXPECT_EQ(ca[k].barycentre, cb[k].barycentre) << "cluster " << k;
  }
  const auto wholeIndex = [&](std::size_t k) {
    return static_cast<std::size_t>(g->finite_index[static_cast<std::size_t>(s.geometry->raw_index[k])]);
  };
  std::size_t phi_differ = 0;
  for (std::size_t k = 0; k < s.geometry->size(); ++k)
    phi_differ += d.field()[k] != whole.field()[wholeIndex(k)];
  EXPECT_EQ(phi_differ, 0u);
  EXPECT_EQ(d.unreachablePoints(), whole.unreachablePoints());
  const Eigen::Vector3d centre = whole.handleCentre();
  EXPECT_EQ(d.handleCentre(), centre);

  // A frame move.
  const Eigen::Affine3d motion =
      Eigen::Translation3d(Eigen::Vector3d(0.3, -0.1, 0.25)) * Eigen::Translation3d(centre) *
      Eigen::AngleAxisd(0.6, Eigen::Vector3d(0.2, 1, 0.3).normalized()) * Eigen::Translation3d(-centre);
  const hgd::SolveStats sa = whole.moveHandle(motion), sb = d.moveHandle(motion);
  EXPECT_EQ(sa.iterations, sb.iterations);
  EXPECT_EQ(sa.energy.total(), sb.energy.total());
  const std::vector<Eigen::Affine3d> ta = whole.worldTransforms(), tb = d.worldTransforms();
  ASSERT_EQ(ta.size(), tb.size());
  std::size_t transforms_differ = 0;
  for (std::size_t k = 0; k < ta.size(); ++k) transforms_differ += ta[k].matrix() != tb[k].matrix();
  EXPECT_EQ(transforms_differ, 0u);
  EXPECT_GT(
      (ta[static_cast<std::size_t>(whole.clustering().manipulated)].matrix() - Eigen::Matrix4d::Identity())
          .norm(),
      0.1);  // it moved
  std::size_t points_differ = 0;
  for (std::size_t k = 0; k < s.geometry->size(); ++k)
    points_differ += d.deformedPoints()[k] != whole.deformedPoints()[wholeIndex(k)];
  EXPECT_EQ(points_differ, 0u);
}

namespace {

/// The file deformed in memory (readShape, extractGeometry, a Deformer at the streamed build's
/// resolution, writeDeformed, writeShape) and streamed (streamCoarseLevel, streamedDeformer,
/// writeStreamedDeformed), both by the same frame move; the two outputs' bytes compared.
void expectSameOutput(const std::string& in, const hgd::RecordHandles& rh, const std::string& out_memory,
                      const std::string& out_streamed) {
  SCOPED_TRACE(in);
  hgd::DeformOptions options;
  options.multires_above = 1;
  options.coarse_points = 3000;
  options.points_per_coarse = 10;
  hgd::Shape shape = hgd::readShape(in);
  auto g = std::make_shared<const hgd::Geometry>(hgd::extractGeometry(shape));
  hgd::Deformer whole(g, geometryHandles(rh, *g), options);
  const Eigen::Vector3d centre = whole.handleCentre();
  const Eigen::Affine3d motion =
      Eigen::Translation3d(Eigen::Vector3d(0.2, 0.1, 0.3)) * Eigen::Translation3d(centre) *
      Eigen::AngleAxisd(0.5, Eigen::Vector3d(1, 0.3, 0.2).normalized()) * Eigen::Translation3d(-centre);
  whole.moveHandle(motion);
  const std::vector<std::string> wa = whole.writeDeformed(shape);
  hgd::writeShape(out_memory, shape);

  const hgd::RecordLayout layout = hgd::readRecordLayout(in);
  hgd::StreamedLevelOptions lo;
  lo.coarse_points = options.coarse_points;
  lo.points_per_coarse = options.points_per_coarse;
  const hgd::StreamedLevel level = hgd::streamCoarseLevel(layout, rh, lo);
  const hgd::StreamedDeformer s = hgd::streamedDeformer(layout, level, rh, options);
  s.deformer->moveHandle(motion);
  const std::vector<std::string> wb = hgd::writeStreamedDeformed(out_streamed, layout, level, s, 5000);
  EXPECT_EQ(wa, wb);
  const std::string a = fileBytes(out_memory), b = fileBytes(out_streamed), input = fileBytes(in);
  ASSERT_EQ(a.size(), b.size());
  std::size_t differ = 0;
  for (std::size_t k = 0; k < a.size(); ++k) differ += a[k] != b[k];
  EXPECT_EQ(differ, 0u) << "bytes that differ";
  // It did deform (else the comparison proves little).
  std::size_t moved = 0;
  for (std::size_t k = 0; k < std::min(a.size(), input.size()); ++k) moved += a[k] != input[k];
  EXPECT_GT(moved, a.size() / 20);
}

}  // namespace

// The whole streamed run writes what the in-memory run writes, byte for byte: the deformed
// georeferenced PLY of doubles (NaN records, zeros, far strays, an intensity, normals of random
// signs) and PCL's binary PCD of floats (page-padded, organized as PCL writes it: NaN points).
// In blocks of 5,000 records.
TEST(Stream, StreamedRunWritesTheInMemoryRunsBytes) {
  TempDir tmp;
  {
    const Eigen::Vector3d offset(512345.25, 4187654.5, 312.0);
    const hgd::Shape scan = userScan(60000, 13, offset, true);
    const std::string ply = tmp / "survey.ply";
    hgd::writeShape(ply, scan);
    expectSameOutput(ply, recordHandles(scan, offset), tmp / "memory.ply", tmp / "streamed.ply");
  }
  {
    const hgd::Shape scan = userScan(60000, 17, Eigen::Vector3d::Zero(), false);
    const pcl::PointCloud<pcl::PointNormal> pn = hgd_test::asPointNormals(scan);
    const std::string pcd = tmp / "pcl.pcd";
    ASSERT_EQ(pcl::io::savePCDFileBinary(pcd, pn), 0);
    expectSameOutput(pcd, recordHandles(hgd::readShape(pcd), Eigen::Vector3d::Zero()), tmp / "memory.pcd",
                     tmp / "streamed.pcd");
  }
}

// `hgdeform deform --stream` writes what `hgdeform deform` writes, byte for byte, on a scan of
// 170,000 points (above the multi-resolution threshold: both build on a coarse level) with a
// scenario of a box fixed, a sphere dragged and a frame move; the report says it streamed.
TEST(Stream, CliStreamWritesTheInMemoryRunsBytes) {
  TempDir tmp;
  const Eigen::Vector3d offset(512345.25, 4187654.5, 312.0);
  const hgd::Shape scan = userScan(140000, 19, offset, true);
  ASSERT_GT(scan.size(), 131072u);
  const std::string in = tmp / "survey.ply", scenario = tmp / "s.json";
  hgd::writeShape(in, scan);
  {
    std::ofstream s(scenario);
    char buf[1024];
    std::snprintf(buf, sizeof buf,
                  R"({"fixed": [{"box": {"min": [%.3f, %.3f, %.3f], "max": [%.3f, %.3f, %.3f]}}],
                      "manipulated": {"sphere": {"center": [%.3f, %.3f, %.3f], "radius": 0.35}},
                      "move": [{"drag": {"from": [%.3f, %.3f, %.3f], "to": [%.3f, %.3f, %.3f]}},
                               {"frame": {"translate": [0.05, 0, 0.1], "rotate": {"axis": [0, 0, 1], "degrees": 20}}}]})",
                  offset.x() - 2, offset.y() - 2, offset.z() - 2, offset.x() + 2, offset.y() + 2,
                  offset.z() - 0.7, offset.x() + 1, offset.y(), offset.z(), offset.x() + 1, offset.y(),
                  offset.z(), offset.x() + 1.2, offset.y() + 0.1, offset.z() + 0.3);
    s << buf;
  }
  const std::string tool = HGD_TOOL;
  const std::string a = tmp / "memory.ply", b = tmp / "streamed.ply", report = tmp / "r.json";
  ASSERT_EQ(std::system((tool + " deform " + in + " -s " + scenario + " -o " + a + " -q").c_str()), 0);
  ASSERT_EQ(std::system(
                (tool + " deform --stream " + in + " -s " + scenario + " -o " + b + " -q --report " + report)
                    .c_str()),
            0);
  const std::string x = fileBytes(a), y = fileBytes(b), input = fileBytes(in);
  ASSERT_EQ(x.size(), y.size());
  std::size_t differ = 0, moved = 0;
  for (std::size_t k = 0; k < x.size(); ++k) {
    differ += x[k] != y[k];
    moved += k < input.size() && x[k] != input[k];
  }
  EXPECT_EQ(differ, 0u) << "bytes that differ";
  EXPECT_GT(moved, x.size() / 50);
  EXPECT_NE(fileBytes(report).find("streamed"), std::string::npos);
}
