// hgdeform batch: what each output was made from (its provenance record), and the lock that
// keeps two runs out of one output folder. See docs/batch.md, "Up to date".
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>

namespace hgdcli {
namespace batch {

/// What stat(2) says about a file (links followed), times to the nanosecond.
struct FileState {
  bool exists = false;
  std::uint64_t size = 0;
  std::int64_t mtime_ns = 0, ctime_ns = 0;
  std::uint64_t dev = 0, ino = 0;
  /// Same file, not touched in between (ctime too: it moves on every write and utimes()).
  bool unchangedFrom(const FileState& o) const {
    return exists == o.exists && size == o.size && mtime_ns == o.mtime_ns && ctime_ns == o.ctime_ns &&
           dev == o.dev && ino == o.ino;
  }
};

FileState fileState(const std::string& path);

/// XXH3 (64 bit) of a file's bytes / of a string, as 16 hex digits. hashFile throws on read errors.
std::string hashFile(const std::string& path);
std::string hashBytes(std::string_view bytes);

/// The record kept beside an output (OUTPUT_DIR/.hgdeform/records/<output>.json).
struct Provenance {
  std::string input;  ///< relative to INPUT_DIR
  std::uint64_t input_size = 0;
  /// The input's times and inode: when any differs its bytes are hashed again (and decide).
  /// The ctime cannot be set back (touch -r, a restored mtime), and moves on every write.
  std::int64_t input_mtime_ns = 0, input_ctime_ns = 0;
  std::uint64_t input_ino = 0;
  std::string input_hash;     ///< hashFile() of the input
  std::string scenario;       ///< the scenario file (for people)
  std::string scenario_hash;  ///< hashBytes(hgd::scenarioToJson(effective scenario))
  nlohmann::json options;     ///< the options that change the output, e.g. {"output_format": "ply"}
  std::string tool;           ///< "hgdeform 0.2.0"
  /// The output as written: another size, ctime or inode means something else changed or
  /// replaced it (even with its time set back), and the scan is redone.
  std::uint64_t output_size = 0;
  std::int64_t output_ctime_ns = 0;
  std::uint64_t output_ino = 0;
  /// Not empty: the output does not match this record (e.g. the input changed while it was
  /// being deformed); the next run redoes it.
  std::string invalid;
};

/// The input as recorded: the same size, times and inode as `now` (then its bytes are taken to
/// be the recorded ones, without hashing).
bool sameInput(const Provenance& p, const FileState& now);
/// The output as recorded: the same size, ctime and inode as `now`.
bool sameOutput(const Provenance& p, const FileState& now);
/// Sets the record's input / output state (size, times, inode) from `s`.
void recordInput(Provenance& p, const FileState& s);
void recordOutput(Provenance& p, const FileState& s);

std::string recordText(const Provenance& p);
/// nullopt when the file is missing or is not a record.
std::optional<Provenance> readRecord(const std::string& path);

/// "hgdeform <version>" of this build.
std::string toolVersion();

/// flock(2) on OUTPUT_DIR/.hgdeform/batch.lock, released when the object dies (or the process).
/// A whole run holds it exclusively; shards of one split (--shard K/N, same N) share it and each
/// holds .hgdeform/batch-shard-K-of-N.lock exclusively. Acquire throws a runtime_error saying who
/// holds the folder.
class OutputLock {
 public:
  OutputLock() = default;
  ~OutputLock();
  OutputLock(const OutputLock&) = delete;
  OutputLock& operator=(const OutputLock&) = delete;
  /// shard_n = 0: the whole run.
  void acquire(const std::string& output_dir, int shard_k, int shard_n);

 private:
  int fd_ = -1, shard_fd_ = -1;
};

}  // namespace batch
}  // namespace hgdcli
