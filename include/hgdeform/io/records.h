// Shape files whose points are records of one size, one after another at a known place (binary
// PLY, binary PCD): read in blocks, in place, without holding every point. What a streamed
// build (a scan larger than memory) reads.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "hgdeform/io/shape.h"

namespace hgd {

/// A file's points as fixed-size records at `offset` (readRecordLayout).
struct RecordLayout {
  /// The file as read without its points' data: its fields (`cloud.fields`, `point_step`,
  /// `width` x `height`), the sensor pose, its extras (PLY elements after the vertices,
  /// comments); `cloud.data` is empty.
  Shape shape;
  std::uint64_t offset = 0;  ///< where the first record starts in the file
  std::uint64_t count = 0;   ///< records
  std::uint32_t bytes = 0;   ///< a record's size (the cloud's point_step)
};

/// Reads a file's header, and whatever of it is not the points' records, as readShape would.
/// Throws IoError naming the file and the problem when it is malformed (as readShape says) or
/// when its points are not fixed-size records in the host's byte order that can be read in
/// place: ascii, binary_compressed PCD, big-endian PLY, a vertex element with list properties or
/// after another element with data, PCL's organized PLY (range_grid), other formats.
RecordLayout readRecordLayout(const std::string& path);

/// Reads blocks of a layout's records (pread: one reader may serve threads reading apart).
class RecordReader {
 public:
  explicit RecordReader(const RecordLayout& layout);
  ~RecordReader();
  RecordReader(const RecordReader&) = delete;
  RecordReader& operator=(const RecordReader&) = delete;

  /// Records [first, first + count) into `out` (count x bytes). Throws IoError naming the file
  /// when it cannot be read (it shrank since its header was read).
  void read(std::uint64_t first, std::size_t count, std::uint8_t* out) const;
  const RecordLayout& layout() const { return layout_; }

 private:
  const RecordLayout& layout_;
  int fd_ = -1;
};

/// Where a long run's passes over a file's records are (what a front end shows as progress).
struct RecordProgress {
  const char* pass = "";      ///< what the pass is for (streamPass's name)
  std::uint64_t done = 0;     ///< how far in the file the last read ended (a pass reads in order)
  std::uint64_t records = 0;  ///< the file's records
};
/// The calling thread's RecordReaders report each read to `hook` (empty: none); returns the
/// hook that was set.
std::function<void(const RecordProgress&)> setRecordProgress(std::function<void(const RecordProgress&)> hook);
/// Names the pass the calling thread's reads belong to from now on (a string that lives as long
/// as the program: a literal).
void streamPass(const char* name);
/// The calling thread reads only records [first, last) of a file in its passes (its rank's share
/// of a split run): its reports count those (`done` from `first`, `records` their number). A
/// `last` of 0: the whole file.
void streamShare(std::uint64_t first, std::uint64_t last);

/// Where writeRecords() sends the records, in order.
class RecordSink {
 public:
  virtual ~RecordSink() = default;
  virtual void write(const std::uint8_t* records, std::size_t bytes) = 0;
  /// For records other processes write into the file (a scan split across MPI ranks): the file
  /// being written (the temporary file beside the output until it is complete), or "" when the
  /// output cannot be written by others (a descriptor, a pipe) ...
  virtual std::string file() const { return {}; }
  /// ... the byte of it the next record goes to, ...
  virtual std::uint64_t offset() const { return 0; }
  /// ... and a move past `bytes` that the others write (only when file() names one).
  virtual void skip(std::uint64_t /*bytes*/) {
    throw std::logic_error("RecordSink::skip: this sink's records cannot be written by others");
  }
};

/// Records [first, last) of a file (a rank's share of them).
struct RecordShare {
  std::uint64_t first = 0, last = 0;
};
/// The share of `rank` among `ranks` processes: the records in file order, split into nearly
/// equal runs (the first `records % ranks` one longer).
RecordShare shareOf(std::uint64_t records, int rank, int ranks);

/// The processes of one streamed run split over its records (`mpirun hgdeform deform --mpi`:
/// MPI's ranks, tools/stream_mpi.cpp): each reads its share of the records (shareOf), what each
/// pass finds is gathered so that every rank holds the same level and builds the same deformer,
/// and each writes its share of the output at its place in the one file.
class StreamRanks {
 public:
  virtual ~StreamRanks() = default;
  virtual int rank() const = 0;
  virtual int size() const = 0;
  /// Every rank's `mine`, in rank order, on every rank. Collective: every rank makes the same
  /// calls in the same order.
  virtual std::vector<std::string> allgather(const std::string& mine) = 0;
  /// Writes this rank's bytes into `file` (an existing file every rank can open) from byte `at`
  /// on, as `part` sends them to its sink, each rank on its own (no collective call: the caller
  /// gathers the outcome). Returns "" or what went wrong on this rank (`part`'s throw included).
  virtual std::string writeAt(const std::string& file, std::uint64_t at,
                              const std::function<void(RecordSink&)>& part) = 0;
};

/// Writes `layout`'s shape as writeShape would write it holding the records that `records`
/// gives (each record as the file's layout has it, `layout.count` of them in order): the same
/// header, the same elements after the points, atomically (nothing at `path` unless complete).
/// The format is `path`'s extension's and must be the file's own, binary; `path` must not be
/// the file the layout was read from. Throws IoError naming the path otherwise.
void writeRecords(const std::string& path, const RecordLayout& layout,
                  const std::function<void(RecordSink&)>& records);

}  // namespace hgd
