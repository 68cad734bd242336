// One scan split across ranks (hgd::StreamRanks; `mpirun hgdeform deform --mpi` in the CLI): each
// rank reads its share of the records and the passes are gathered, so every rank must hold the
// level one process builds, and the file the ranks write together must be the one process's,
// byte for byte. Here the ranks are threads of this process (the same calls as MPI's ranks make;
// test_stream_cli runs the real mpirun), with shares whose edges fall inside the read blocks.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <future>
#include <mutex>
#include <random>
#include <string>
#include <tuple>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "../src/multires/streamed_passes.h"  // the passes' merges themselves
#include "hgdeform/deformer/deformer.h"
#include "hgdeform/deformer/streamed.h"
#include "hgdeform/io/io.h"
#include "hgdeform/io/records.h"
#include "hgdeform/multires/streamed.h"
#include "stream_fixtures.h"

namespace {

using hgd_test::fileBytes;
using hgd_test::recordHandles;
using hgd_test::TempDir;
using hgd_test::userScan;

/// N ranks as threads: every allgather waits for all N (a barrier), as MPI's collectives do.
class ThreadWorld {
 public:
  explicit ThreadWorld(int n) : n_(n), slots_(static_cast<std::size_t>(n)) {}

  class Rank final : public hgd::StreamRanks {
   public:
    Rank(ThreadWorld& world, int rank) : world_(world), rank_(rank) {}
    int rank() const override { return rank_; }
    int size() const override { return world_.n_; }
    std::vector<std::string> allgather(const std::string& mine) override {
      return world_.gather(rank_, mine);
    }
    std::string writeAt(const std::string& file, std::uint64_t at,
                        const std::function<void(hgd::RecordSink&)>& part) override {
      std::string failed;  // (each rank on its own, as MPI's ranks open it: no collective call)
      const int fd = ::open(file.c_str(), O_WRONLY | O_CLOEXEC);
      if (fd < 0) failed = file + ": cannot open";
      struct Sink final : hgd::RecordSink {
        int fd;
        std::uint64_t at;
        void write(const std::uint8_t* p, std::size_t n) override {
          if (::pwrite(fd, p, n, static_cast<off_t>(at)) != static_cast<ssize_t>(n))
            throw hgd::IoError("pwrite failed");
          at += n;
        }
      } sink;
      sink.fd = fd;
      sink.at = at;
      if (fd >= 0) {
        try {
          if (rank_ == world_.fail_write) throw hgd::IoError("rank " + std::to_string(rank_) + ": disk full");
          part(sink);
        } catch (const std::exception& e) {
          failed = e.what();
        }
        ::close(fd);
      }
      return failed;
    }

   private:
    ThreadWorld& world_;
    int rank_;
  };

  /// Runs fn(rank) on N threads; each result or exception comes back per rank. A run that
  /// does not end in two minutes (ranks waiting for one that left) fails the whole test binary.
  template <typename T>
  std::vector<std::future<T>> run(const std::function<T(hgd::StreamRanks&)>& fn) {
    std::vector<std::future<T>> out;
    for (int r = 0; r < n_; ++r)
      out.push_back(std::async(std::launch::async, [this, r, fn] {
        Rank rank(*this, r);
        return fn(rank);
      }));
    for (auto& f : out)
      if (f.wait_for(std::chrono::minutes(2)) != std::future_status::ready) {
        ADD_FAILURE() << "the ranks did not finish: one waits for another that left";
        std::_Exit(1);
      }
    return out;
  }

  int fail_write = -1;  ///< a rank whose share cannot be written

 private:
  std::vector<std::string> gather(int rank, const std::string& mine) {
    std::unique_lock<std::mutex> lock(m_);
    const std::uint64_t round = round_;
    slots_[static_cast<std::size_t>(rank)] = mine;
    if (++arrived_ == n_) {
      result_ = slots_;
      arrived_ = 0;
      ++round_;
      cv_.notify_all();
    } else {
      cv_.wait(lock, [&] { return round_ != round; });
    }
    return result_;  // (the next round cannot end before this rank joins it)
  }

  int n_;
  std::mutex m_;
  std::condition_variable cv_;
  std::vector<std::string> slots_, result_;
  int arrived_ = 0;
  std::uint64_t round_ = 0;
};

/// Every field of two levels equal (the frame, the coarse points, the rules' state).
void expectSameLevel(const hgd::StreamedLevel& a, const hgd::StreamedLevel& b) {
  EXPECT_EQ(a.origin, b.origin);
  EXPECT_EQ(a.body.min(), b.body.min());
  EXPECT_EQ(a.body.max(), b.body.max());
  EXPECT_EQ(a.records, b.records);
  EXPECT_EQ(a.points, b.points);
  EXPECT_EQ(a.far_points, b.far_points);
  EXPECT_EQ(a.file_normals, b.file_normals);
  EXPECT_EQ(a.warnings, b.warnings);
  EXPECT_EQ(a.cell, b.cell);
  ASSERT_EQ(a.coarse.size(), b.coarse.size());
  std::size_t differ = 0;
  for (std::size_t k = 0; k < a.coarse.size(); ++k) {
    differ += a.coarse[k].getVector3fMap() != b.coarse[k].getVector3fMap();
    if (a.file_normals) differ += a.normals[k].getNormalVector3fMap() != b.normals[k].getNormalVector3fMap();
  }
  EXPECT_EQ(differ, 0u) << "coarse points that differ";
  EXPECT_EQ(a.coarse_record, b.coarse_record);
  EXPECT_EQ(a.weight, b.weight);
  EXPECT_EQ(a.morton_rank, b.morton_rank);
  EXPECT_EQ(a.coarse_fixed, b.coarse_fixed);
  EXPECT_EQ(a.coarse_manipulated, b.coarse_manipulated);
  EXPECT_EQ(a.coarse_joints, b.coarse_joints);
  EXPECT_EQ(a.strays, b.strays);
  EXPECT_EQ(a.stray_anchor, b.stray_anchor);
  EXPECT_EQ(a.far_strays, b.far_strays);
  EXPECT_EQ(a.frame_centre, b.frame_centre);
  EXPECT_EQ(a.far, b.far);
  EXPECT_EQ(a.stray_distance, b.stray_distance);
  EXPECT_EQ(a.zeros_apart, b.zeros_apart);
  EXPECT_EQ(a.grid_lo, b.grid_lo);
  EXPECT_EQ(a.axis_bits, b.axis_bits);
  EXPECT_EQ(a.cell_key, b.cell_key);
  EXPECT_EQ(a.cell_id, b.cell_id);
  EXPECT_EQ(a.record_class, b.record_class);
}

/// The temporary files writers leave beside an output (none, after a run that failed).
std::size_t leftovers(const std::filesystem::path& dir) {
  std::size_t n = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    n += e.path().filename().string().find(".tmp-") != std::string::npos;
  return n;
}

}  // namespace

// The level that 2, 3 and 7 ranks gather is the level one process builds, every field of it: on
// the georeferenced PLY of doubles with NaN records, zeros set apart, far strays and the sparse
// cells' strays (every pass runs, the stray passes included), and on PCL's page-padded PCD.
TEST(StreamRanks, SplitPassesGatherTheLevelOneProcessBuilds) {
  TempDir tmp;
  const Eigen::Vector3d offset(512345.25, 4187654.5, 312.0);
  const hgd::Shape scan = userScan(60000, 5, offset, true);
  const std::string ply = tmp / "survey.ply", pcd = tmp / "pcl.pcd";
  hgd::writeShape(ply, scan);
  const hgd::Shape plain = userScan(60000, 7, Eigen::Vector3d::Zero(), false);
  ASSERT_EQ(pcl::io::savePCDFileBinary(pcd, hgd_test::asPointNormals(plain)), 0);
  for (const std::string& path : {ply, pcd}) {
    SCOPED_TRACE(path);
    const hgd::RecordLayout layout = hgd::readRecordLayout(path);
    const hgd::RecordHandles handles =
        recordHandles(hgd::readShape(path), path == ply ? offset : Eigen::Vector3d::Zero());
    hgd::StreamedLevelOptions options;
    options.coarse_points = 3000;
    options.block = 4096;  // shares end inside blocks
    const hgd::StreamedLevel one = hgd::streamCoarseLevel(layout, handles, options);
    // What makes the comparison worth making: every rule had something to find.
    EXPECT_FALSE(one.strays.empty());
    if (path == ply) {
      EXPECT_FALSE(one.far_strays.empty());
      EXPECT_TRUE(one.zeros_apart);
    }
    EXPECT_LT(one.points, one.records);
    for (const int n : {2, 3, 7}) {
      SCOPED_TRACE(std::to_string(n) + " ranks");
      ThreadWorld world(n);
      auto levels = world.run<hgd::StreamedLevel>([&](hgd::StreamRanks& ranks) {
        hgd::StreamedLevelOptions o = options;
        o.ranks = &ranks;
        return hgd::streamCoarseLevel(layout, handles, o);
      });
      for (auto& f : levels) expectSameLevel(f.get(), one);
    }
  }
}

// Three ranks, each deforming its share of the records and writing it at its place, write the
// file one process writes, byte for byte (a frame move: turned and shifted; NaN records, zeros
// and far strays left as they were), and the file is complete only when every share is in it.
TEST(StreamRanks, SplitWriteIsTheOneProcessFile) {
  TempDir tmp;
  const Eigen::Vector3d offset(512345.25, 4187654.5, 312.0);
  const hgd::Shape scan = userScan(60000, 13, offset, true);
  const std::string in = tmp / "survey.ply";
  hgd::writeShape(in, scan);
  const hgd::RecordLayout layout = hgd::readRecordLayout(in);
  const hgd::RecordHandles rh = recordHandles(scan, offset);
  hgd::DeformOptions options;
  options.multires_above = 1;
  options.coarse_points = 3000;
  hgd::StreamedLevelOptions lo;
  lo.coarse_points = options.coarse_points;
  const auto deformAndWrite = [&](const std::string& out, hgd::StreamRanks* ranks) {
    hgd::StreamedLevelOptions o = lo;
    o.ranks = ranks;
    const hgd::StreamedLevel level = hgd::streamCoarseLevel(layout, rh, o);
    const hgd::StreamedDeformer s = hgd::streamedDeformer(layout, level, rh, options);
    const Eigen::Vector3d centre = s.deformer->handleCentre();
    s.deformer->moveHandle(
        Eigen::Translation3d(Eigen::Vector3d(0.2, 0.1, 0.3)) * Eigen::Translation3d(centre) *
        Eigen::AngleAxisd(0.5, Eigen::Vector3d(1, 0.3, 0.2).normalized()) * Eigen::Translation3d(-centre));
    return hgd::writeStreamedDeformed(out, layout, level, s, 5000, ranks);
  };
  const std::string one = tmp / "one.ply", split = tmp / "split.ply";
  const std::vector<std::string> warnings = deformAndWrite(one, nullptr);
  ThreadWorld world(3);
  auto results = world.run<std::vector<std::string>>(
      [&](hgd::StreamRanks& ranks) { return deformAndWrite(split, &ranks); });
  for (auto& f : results) EXPECT_EQ(f.get(), warnings);
  const std::string a = fileBytes(one), b = fileBytes(split), input = fileBytes(in);
  ASSERT_EQ(a.size(), b.size());
  const hgd_test::ByteDiff diff = hgd_test::diffBytes(a, b, input);
  EXPECT_EQ(diff.differ, 0u) << "bytes that differ";
  EXPECT_GT(diff.moved, a.size() / 20);  // it did deform, in every rank's share
  const hgd::RecordShare last = hgd::shareOf(layout.count, 2, 3);
  std::size_t moved_last = 0;
  for (std::size_t k = layout.offset + last.first * layout.bytes; k < a.size(); ++k)
    moved_last += a[k] != input[k];
  EXPECT_GT(moved_last, 0u);
  EXPECT_EQ(leftovers(tmp.dir), 0u);
}

// A rank that fails fails them all, each with the reason, and none waits for another: a file
// cut short after its header was read (the later ranks' shares are gone; the first rank's reads
// succeed), and a share that cannot be written (the others' shares are; nothing is left at the
// output, no temporary file beside it, and the file that was there stays).
TEST(StreamRanks, OneRankFailingFailsEveryRankAndLeavesNoOutput) {
  TempDir tmp;
  const hgd::Shape scan = userScan(30000, 3, Eigen::Vector3d::Zero(), false);
  const std::string in = tmp / "scan.ply";
  hgd::writeShape(in, scan);
  const hgd::RecordHandles rh = recordHandles(scan, Eigen::Vector3d::Zero());
  {
    const std::string cut = tmp / "cut.ply";
    std::filesystem::copy_file(in, cut);
    const hgd::RecordLayout layout = hgd::readRecordLayout(cut);
    std::filesystem::resize_file(cut, layout.offset + layout.count / 2 * layout.bytes);
    ThreadWorld world(3);
    auto results = world.run<int>([&](hgd::StreamRanks& ranks) {
      hgd::StreamedLevelOptions o;
      o.coarse_points = 1000;
      o.block = 1000;
      o.ranks = &ranks;
      hgd::streamCoarseLevel(layout, rh, o);
      return 0;
    });
    for (auto& f : results) {
      try {
        f.get();
        ADD_FAILURE() << "a rank did not fail";
      } catch (const hgd::IoError& e) {
        EXPECT_NE(std::string(e.what()).find("truncated"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find(cut), std::string::npos) << e.what();
      }
    }
  }
  // A split run writing `out` whose rank `fail_write` cannot write its share: each rank's error.
  const auto splitWrite = [&](const std::string& out, int fail_write) {
    const hgd::RecordLayout layout = hgd::readRecordLayout(in);
    hgd::DeformOptions options;
    options.multires_above = 1;
    options.coarse_points = 1000;
    ThreadWorld world(3);
    world.fail_write = fail_write;
    auto results = world.run<int>([&](hgd::StreamRanks& ranks) {
      hgd::StreamedLevelOptions o;
      o.coarse_points = 1000;
      o.ranks = &ranks;
      const hgd::StreamedLevel level = hgd::streamCoarseLevel(layout, rh, o);
      const hgd::StreamedDeformer s = hgd::streamedDeformer(layout, level, rh, options, &ranks);
      s.deformer->moveHandle(Eigen::Affine3d(Eigen::Translation3d(0.1, 0, 0)));
      hgd::writeStreamedDeformed(out, layout, level, s, 4096, &ranks);
      return 0;
    });
    std::vector<std::string> errors;
    for (auto& f : results) {
      try {
        f.get();
        errors.emplace_back();
      } catch (const hgd::IoError& e) {
        errors.emplace_back(e.what());
      }
    }
    return errors;
  };
  {
    const std::string out = tmp / "out.ply";
    { std::ofstream(out) << "what was there"; }
    for (const std::string& e : splitWrite(out, 2))
      EXPECT_NE(e.find("rank 2: disk full"), std::string::npos) << "'" << e << "'";
    EXPECT_EQ(fileBytes(out), "what was there");
    EXPECT_EQ(leftovers(tmp.dir), 0u);
  }
  // Rank 0 cannot make the output (its folder does not exist: before the others are told where
  // to write), and cannot put it in place (a folder stands at its name: after every share is in).
  std::filesystem::create_directory(tmp / "folder.ply");
  for (const std::string& out : {tmp / "no/such/folder/out.ply", tmp / "folder.ply"}) {
    SCOPED_TRACE(out);
    for (const std::string& e : splitWrite(out, -1))
      EXPECT_NE(e.find(out), std::string::npos) << "'" << e << "'";
    EXPECT_EQ(leftovers(tmp.dir), 0u);
  }
  EXPECT_TRUE(std::filesystem::is_directory(tmp / "folder.ply"));
}

// The shares: every record in exactly one, in file order, sizes within one of each other.
TEST(StreamRanks, SharesCoverTheRecordsOnceInOrder) {
  for (const std::uint64_t n : {0ull, 1ull, 5ull, 1000003ull, 4000000000ull})
    for (const int ranks : {1, 2, 3, 7, 64}) {
      std::uint64_t next = 0, smallest = ~0ull, largest = 0;
      for (int r = 0; r < ranks; ++r) {
        const hgd::RecordShare s = hgd::shareOf(n, r, ranks);
        EXPECT_EQ(s.first, next);
        next = s.last;
        smallest = std::min(smallest, s.last - s.first);
        largest = std::max(largest, s.last - s.first);
      }
      EXPECT_EQ(next, n);
      EXPECT_LE(largest - smallest, 1u);
    }
}

// The merges themselves, on random findings in three shares of 1,000 records (ties included): the two
// smallest distances each sample met and each cell's count and nearest point are what one
// process meeting every point in file order finds. (On the scans above a merge that kept only
// one distance a rank still gives the same level: the stray limit is a median.)
TEST(StreamRanks, GathersMergeAsOneProcessMeets) {
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> small(0, 40);
  struct Met {
    int rank;
    std::size_t sample;
    float d;
    std::uint64_t key, record;
  };
  std::vector<Met> met;
  for (std::uint64_t i = 0; i < 3000; ++i)  // in file order: records ascending
    met.push_back({static_cast<int>(i / 1000), static_cast<std::size_t>(small(rng) % 25),
                   static_cast<float>(small(rng)) * 0.25f, static_cast<std::uint64_t>(small(rng) % 30), i});
  std::vector<hgd::stream::Typical> one(25);
  hgd::stream::CellPass cells_one;
  cells_one.list_cells.resize(1);
  for (const Met& m : met) {
    one[m.sample].meet(m.d);
    hgd::stream::CellAcc& c = cells_one.cells[m.key];
    ++c.count;
    c.offer(m.record, m.d, Eigen::Vector3f::Constant(m.d),
            Eigen::Vector3d::Constant(static_cast<double>(m.record)), Eigen::Vector3f::Zero());
  }
  ThreadWorld world(3);
  using Gathered = std::unordered_map<std::uint64_t, std::vector<hgd::stream::Near>>;
  auto results = world.run<std::tuple<std::vector<hgd::stream::Typical>, hgd::stream::CellPass, Gathered>>(
      [&](hgd::StreamRanks& ranks) {
        Gathered gathered;
        std::vector<hgd::stream::Typical> typ(25);
        hgd::stream::CellPass cells;
        cells.list_cells.resize(1);
        for (const Met& m : met) {
          if (m.rank != ranks.rank()) continue;
          typ[m.sample].meet(m.d);
          hgd::stream::CellAcc& c = cells.cells[m.key];
          ++c.count;
          c.offer(m.record, m.d, Eigen::Vector3f::Constant(m.d),
                  Eigen::Vector3d::Constant(static_cast<double>(m.record)), Eigen::Vector3f::Zero());
          cells.list_cells[0].insert(m.key * 2);
          if (m.key < 3)
            gathered[m.key].push_back(
                {m.record, Eigen::Vector3f::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3f::Zero(), 0});
        }
        hgd::stream::share(ranks, "", typ, gathered);
        hgd::stream::share(ranks, "", cells);
        return std::make_tuple(typ, cells, gathered);
      });
  for (auto& f : results) {
    const auto [typ, cells, gathered] = f.get();
    // Each sparse cell's points in file order, every rank's.
    for (std::uint64_t key = 0; key < 3; ++key) {
      std::vector<std::uint64_t> want, got;
      for (const Met& m : met)
        if (m.key == key) want.push_back(m.record);
      for (const hgd::stream::Near& q : gathered.at(key)) got.push_back(q.record);
      EXPECT_EQ(got, want) << key;
    }
    for (std::size_t k = 0; k < one.size(); ++k) {
      EXPECT_EQ(typ[k].d1, one[k].d1) << k;
      EXPECT_EQ(typ[k].d2, one[k].d2) << k;
    }
    ASSERT_EQ(cells.cells.size(), cells_one.cells.size());
    for (const auto& [key, c] : cells_one.cells) {
      const hgd::stream::CellAcc& got = cells.cells.at(key);
      EXPECT_EQ(got.count, c.count) << key;
      EXPECT_EQ(got.best, c.best) << key;
      EXPECT_EQ(got.best_d, c.best_d) << key;
      EXPECT_EQ(got.w, c.w) << key;
    }
    std::unordered_set<std::uint64_t> keys_twice;  // every rank's handle cells, each once
    for (const auto& kv : cells_one.cells) keys_twice.insert(kv.first * 2);
    EXPECT_EQ(cells.list_cells[0], keys_twice);
  }
}
