// `hgdeform deform --stream` as a user meets it: a run that moves nothing gives every record back
// bit for bit; what it cannot stream (a mesh, a small shape, ascii) and an output that is the
// input are refused by name with nothing written; a failed run leaves the file that was at the
// output; the progress line's passes, rate and time left.
#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "hgdeform/io/fields.h"
#include "hgdeform/io/io.h"
#include "hgdeform/io/records.h"
#include "stream_fixtures.h"
#include "stream_progress.h"
#include "support/shapes.h"

namespace {

using hgd_test::fileBytes;
using hgd_test::TempDir;
using hgd_test::userScan;

const Eigen::Vector3d kOffset(512345.25, 4187654.5, 312.0);

struct CliRun {
  int status = -1;
  std::string err;
};

/// `hgdeform deform --stream IN -s S -o OUT -q EXTRA`, its exit status and stderr.
CliRun deformStreamed(const TempDir& tmp, const std::string& in, const std::string& scenario,
                      const std::string& out, const std::string& extra = "") {
  const std::string err = tmp / "stderr.txt";
  const std::string cmd = std::string(HGD_TOOL) + " deform --stream '" + in + "' -s '" + scenario + "' -o '" +
                          out + "' -q " + extra + " 2> '" + err + "'";
  const int raw = std::system(cmd.c_str());
  CliRun r;
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  r.err = fileBytes(err);
  return r;
}

/// A scenario on userScan's shape at `offset`: below z -0.7 fixed, a sphere at x 1 manipulated,
/// and `move` (JSON).
std::string writeScenario(const TempDir& tmp, const Eigen::Vector3d& offset, const std::string& move,
                          const std::string& name = "s.json") {
  const std::string path = tmp / name;
  std::ofstream s(path);
  char buf[1024];
  std::snprintf(buf, sizeof buf,
                R"({"fixed": [{"box": {"min": [%.3f, %.3f, %.3f], "max": [%.3f, %.3f, %.3f]}}],
                    "manipulated": {"sphere": {"center": [%.3f, %.3f, %.3f], "radius": 0.35}},
                    "move": %s})",
                offset.x() - 2, offset.y() - 2, offset.z() - 2, offset.x() + 2, offset.y() + 2,
                offset.z() - 0.7, offset.x() + 1, offset.y(), offset.z(), move.c_str());
  s << buf;
  return path;
}

/// The bytes of a file's records (readRecordLayout's place).
std::string recordBytes(const std::string& path) {
  const hgd::RecordLayout layout = hgd::readRecordLayout(path);
  return fileBytes(path).substr(layout.offset, layout.count * layout.bytes);
}

}  // namespace

/// The records of `in` and `out` (the same layout) compared: how many differ, and how many of
/// those `unmoved(i)` names differ (which must not: what did not move comes back bit for bit).
struct RecordDiff {
  std::size_t moved = 0, unmoved_changed = 0, unmoved = 0;
};
template <typename Unmoved>
RecordDiff diffRecords(const std::string& in, const std::string& out, Unmoved&& unmoved) {
  const hgd::RecordLayout layout = hgd::readRecordLayout(in);
  const std::string a = recordBytes(in), b = recordBytes(out);
  RecordDiff d;
  EXPECT_EQ(a.size(), b.size());
  if (a.size() != b.size()) return d;
  for (std::size_t i = 0; i < layout.count; ++i) {
    const bool same = a.compare(i * layout.bytes, layout.bytes, b, i * layout.bytes, layout.bytes) == 0;
    if (unmoved(i)) {
      ++d.unmoved;
      d.unmoved_changed += !same;
    } else {
      d.moved += !same;
    }
  }
  return d;
}

// A frame move of the handle: the fixed region's records (pinned to a cluster that does not
// move), the NaN records and the far strays come back byte for byte, though the writer computes
// the moved points' x, y, z in double and turns their normals (random signs); the others move.
// A georeferenced PLY of doubles and PCL's page-padded PCD of floats.
TEST(StreamCli, WhatDidNotMoveComesBackBitForBit) {
  TempDir tmp;
  const std::string lift =
      R"({"frame": {"translate": [0, 0, 0.3], "rotate": {"axis": [0, 1, 0], "degrees": 25}}})";
  for (const bool pcd : {false, true}) {
    SCOPED_TRACE(pcd ? "PCL's PCD" : "PLY of doubles");
    const Eigen::Vector3d offset = pcd ? Eigen::Vector3d::Zero() : kOffset;
    const hgd::Shape scan = userScan(140000, pcd ? 29 : 23, offset, !pcd);
    ASSERT_GT(scan.size(), 131072u);  // above the multi-resolution threshold: streamable
    const std::string in = tmp / (pcd ? "pcl.pcd" : "survey.ply"), out = tmp / (pcd ? "out.pcd" : "out.ply");
    if (pcd)
      ASSERT_EQ(pcl::io::savePCDFileBinary(in, hgd_test::asPointNormals(scan, 7)), 0);
    else
      hgd::writeShape(in, scan);
    const CliRun r = deformStreamed(tmp, in, writeScenario(tmp, offset, lift), out);
    ASSERT_EQ(r.status, 0) << r.err;
    // The fixed box (writeScenario's, a margin inside it), NaN records, points 100 away or more.
    const hgd::Shape read = hgd::readShape(in);
    const hgd::XyzFields f = hgd::findXyzFields(read.cloud);
    const auto at = [&](std::size_t i, int field) {
      return hgd::readValue(read.cloud, i, read.cloud.fields[static_cast<std::size_t>(field)]);
    };
    const RecordDiff d = diffRecords(in, out, [&](std::size_t i) {
      const Eigen::Vector3d w = Eigen::Vector3d(at(i, f.x), at(i, f.y), at(i, f.z)) - offset;
      if (!w.allFinite()) return true;
      if (w.norm() > 100) return true;
      return w.z() < -0.75 && std::abs(w.x()) < 1.9 && std::abs(w.y()) < 1.9;
    });
    EXPECT_GT(d.unmoved, 2000u);
    EXPECT_EQ(d.unmoved_changed, 0u) << "of " << d.unmoved << " records that did not move";
    EXPECT_GT(d.moved, 20000u);  // the handle and the part between moved
  }
}

// What --stream cannot do is refused by name, with a non-zero exit and nothing at the output
// (another format than the input's too, before the passes); an output that is the input,
// however spelled, is refused and the input left as it was; a run that fails, before the output
// is written or after (its report), leaves the file that was there.
TEST(StreamCli, RefusesWhatItCannotStreamAndLeavesNoOutput) {
  TempDir tmp;
  const std::string drag = R"({"frame": {"translate": [0, 0, 0.2]}})";
  const std::string scenario = writeScenario(tmp, Eigen::Vector3d::Zero(), drag);
  const auto refused = [&](const std::string& in, const std::string& why) {
    SCOPED_TRACE(in);
    const std::string out = tmp / "out.ply";
    const CliRun r = deformStreamed(tmp, in, scenario, out);
    EXPECT_NE(r.status, 0);
    EXPECT_NE(r.err.find(in), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(why), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(out));
  };
  {
    const std::string mesh = tmp / "bar.ply";
    hgd::writeShape(mesh, hgd::shapes::barMesh(2.0f, 0.2f, 0.004f));
    refused(mesh, "mesh");
  }
  {
    const std::string small = tmp / "small.ply";
    hgd::writeShape(small, userScan(20000, 31, Eigen::Vector3d::Zero(), false));
    refused(small, "full resolution");
  }
  const hgd::Shape scan = userScan(140000, 37, Eigen::Vector3d::Zero(), true);
  {
    const std::string ascii = tmp / "ascii.ply";
    hgd::WriteOptions wo;
    wo.encoding = hgd::Encoding::Ascii;
    hgd::writeShape(ascii, scan, wo);
    refused(ascii, "ascii");
  }
  const std::string in = tmp / "scan.ply";
  hgd::writeShape(in, scan);
  const std::string before = fileBytes(in);
  {
    const std::string other = tmp / "out.pcd";
    const CliRun r = deformStreamed(tmp, in, scenario, other);
    EXPECT_NE(r.status, 0);
    EXPECT_NE(r.err.find("into another format"), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(other));
  }
  std::filesystem::create_symlink("scan.ply", tmp / "link.ply");
  for (const std::string& out : {in, tmp / "./scan.ply", tmp / "link.ply"}) {
    SCOPED_TRACE(out);
    const CliRun r = deformStreamed(tmp, in, scenario, out);
    EXPECT_NE(r.status, 0);
    EXPECT_NE(r.err.find("refusing to overwrite the input"), std::string::npos) << r.err;
    EXPECT_TRUE(fileBytes(in) == before) << "the input was changed";
  }
  {
    // The manipulated sphere far from the shape: the run fails after the output was named.
    const std::string out = tmp / "kept.ply";
    { std::ofstream(out) << "a file that was there"; }
    const std::string nowhere = writeScenario(tmp, Eigen::Vector3d(50, 50, 50), drag, "nowhere.json");
    const CliRun r = deformStreamed(tmp, in, nowhere, out);
    EXPECT_NE(r.status, 0);
    EXPECT_NE(r.err.find("selects no point"), std::string::npos) << r.err;
    EXPECT_EQ(fileBytes(out), "a file that was there");
    // The report cannot be written once the streamed output is: the file that was there is put
    // back, not the streamed output left.
    const CliRun late =
        deformStreamed(tmp, in, scenario, out, "--report '" + (tmp / "no/such/dir/r.json") + "'");
    EXPECT_NE(late.status, 0);
    EXPECT_NE(late.err.find("r.json"), std::string::npos) << late.err;
    EXPECT_EQ(fileBytes(out), "a file that was there");
  }
}

// The progress line of a run of 10M records: the passes counted (the stray passes share a name
// and are told apart by the position going back), the rate of the full passes only (not the
// strided frame sample), the time left over the passes planned.
TEST(StreamCli, ProgressCountsPassesRateAndTimeLeft) {
  hgdcli::StreamProgress p("scan.ply", false, false);
  const std::uint64_t n = 10000000;
  const auto at = [&](const char* pass, std::uint64_t done, double t) {
    return p.line(hgd::RecordProgress{pass, done, n}, t);
  };
  EXPECT_EQ(at("frame", 5000000, 0.5), "");  // a strided sample: no rate from it
  at("body", 1000000, 0.6);
  // body: 0.5 -> 1.5 s for 10M records: 10M points/s; 4 passes after it.
  EXPECT_EQ(at("body", n, 1.5), "scan.ply: pass 1 of 5 (body) 100%, 10 M points/s, about 0:04 left");
  EXPECT_EQ(at("beyond", 123, 1.5), "");  // a few records read alone, back in the file: not a pass
  EXPECT_EQ(at("handles", n / 2, 2.0),
            "scan.ply: pass 2 of 5 (handles)  50%, 10 M points/s, about 0:04 left");
  at("handles", n, 2.5);
  at("grid", n, 2.6);   // strided: its 0.1 s is not in the rate
  at("cells", n, 4.6);  // a slower pass: 30M records in 4 s
  // The strays' passes join the plan: 7 passes; 3.5 done at 7.5M points/s.
  EXPECT_EQ(at("strays", n / 2, 5.266666),
            "scan.ply: pass 4 of 7 (strays)  50%, 7.5 M points/s, about 0:05 left");
  at("strays", n, 5.933333);
  EXPECT_EQ(at("strays", n / 10, 6.066666),
            "scan.ply: pass 5 of 7 (strays)  10%, 7.5 M points/s, about 0:04 left");
}

// The streamed plane generator (hgdeform-make-scans, the bench's streaming rows) writes what
// writeShape writes of the plane held whole, byte for byte, as PLY and as PCD.
TEST(StreamCli, GeneratedPlaneIsTheWholePlanesBytes) {
  TempDir tmp;
  for (const char* name : {"plane.ply", "plane.pcd"}) {
    SCOPED_TRACE(name);
    const std::string whole = tmp / (std::string("whole_") + name), rows = tmp / name;
    hgd::writeShape(whole, hgd::shapes::bumpyPlane(5, 0.05f, 1.0f / 137));
    hgd::shapes::writeBumpyPlane(rows, 5, 0.05f, 1.0f / 137);
    const std::string a = fileBytes(whole), b = fileBytes(rows);
    EXPECT_GT(a.size(), 138u * 138u * 24u);
    EXPECT_TRUE(a == b) << a.size() << " bytes against " << b.size();
  }
}

// `mpirun -n 3 hgdeform deform --mpi` as a cluster user runs it: the one output file the three
// ranks write is, byte for byte, the file `hgdeform deform` writes holding the scan in memory
// (and `--stream`'s); rank 0 alone reports. A scenario that selects nothing fails every rank:
// a non-zero exit, the reason said once (not once a rank), no output.
TEST(StreamMpi, RanksWriteTheFileOneProcessWrites) {
#ifndef HGD_HAVE_MPI
  GTEST_SKIP() << "built without MPI";
#else
  if (std::system("command -v mpirun > /dev/null 2>&1") != 0) GTEST_SKIP() << "mpirun is not on PATH";
  TempDir tmp;
  const hgd::Shape scan = userScan(140000, 23, kOffset, true);
  ASSERT_GT(scan.size(), 131072u);
  const std::string in = tmp / "survey.ply";
  hgd::writeShape(in, scan);
  char move[512];
  std::snprintf(move, sizeof move,
                R"([{"drag": {"from": [%.3f, %.3f, %.3f], "to": [%.3f, %.3f, %.3f]}},
                    {"frame": {"translate": [0.05, 0, 0.1], "rotate": {"axis": [0, 0, 1], "degrees": 20}}}])",
                kOffset.x() + 1, kOffset.y(), kOffset.z(), kOffset.x() + 1.2, kOffset.y() + 0.1,
                kOffset.z() + 0.3);
  const std::string scenario = writeScenario(tmp, kOffset, move);
  const std::string tool = HGD_TOOL, memory = tmp / "memory.ply", split = tmp / "split.ply",
                    report = tmp / "r.json", err = tmp / "mpi.txt";
  ASSERT_EQ(std::system((tool + " deform '" + in + "' -s '" + scenario + "' -o '" + memory + "' -q").c_str()),
            0);
  // (timeout: a rank waiting for another that left fails the test, not the suite's time)
  const std::string mpirun = "timeout 300 mpirun --allow-run-as-root --oversubscribe -np 3 ";
  const int raw = std::system((mpirun + tool + " deform --mpi '" + in + "' -s '" + scenario + "' -o '" +
                               split + "' --report '" + report + "' 2> '" + err + "' > /dev/null")
                                  .c_str());
  ASSERT_TRUE(WIFEXITED(raw) && WEXITSTATUS(raw) == 0) << fileBytes(err);
  const std::string a = fileBytes(memory), b = fileBytes(split);
  ASSERT_EQ(a.size(), b.size());
  const hgd_test::ByteDiff diff = hgd_test::diffBytes(a, b, fileBytes(in));
  EXPECT_EQ(diff.differ, 0u) << "bytes that differ";
  EXPECT_GT(diff.moved, a.size() / 50);
  EXPECT_NE(fileBytes(report).find("split across 3 ranks"), std::string::npos);
  // One report of the run's notes: rank 0's.
  const std::string said = fileBytes(err);
  std::size_t notes = 0;
  for (std::size_t at = 0; (at = said.find("streamed: the coarse level", at)) != std::string::npos; ++at)
    ++notes;
  EXPECT_EQ(notes, 1u) << said;

  const std::string nothing = writeScenario(tmp, kOffset + Eigen::Vector3d(100, 0, 0), move, "nothing.json");
  const std::string none = tmp / "none.ply";
  const int bad = std::system((mpirun + tool + " deform --mpi '" + in + "' -s '" + nothing + "' -o '" + none +
                               "' 2> '" + err + "' > /dev/null")
                                  .c_str());
  EXPECT_FALSE(WIFEXITED(bad) && WEXITSTATUS(bad) == 0);
  const std::string why = fileBytes(err);
  std::size_t said_once = 0;
  for (std::size_t at = 0; (at = why.find("selects no point", at)) != std::string::npos; ++at) ++said_once;
  EXPECT_EQ(said_once, 1u) << why;
  EXPECT_FALSE(std::filesystem::exists(none));
  for (const auto& e : std::filesystem::directory_iterator(tmp.dir))
    EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
#endif
}
