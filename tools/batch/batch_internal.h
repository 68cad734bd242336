// hgdeform batch, shared by its files (not installed). The pipeline, one file per stage:
//   batch.cpp          the command: arguments, checks, the top-level run, the summary line
//   batch_scans.cpp    the scans of INPUT_DIR, their outputs and scenarios
//   batch_dispatch.cpp who processes which scan: the thread pool (--jobs) or MPI ranks
//   batch_worker.cpp   one scan: up to date?, read, deform, write, provenance record, thumbnail
//   batch_progress.cpp what the user sees, and stopping cleanly (signals, stale temporaries)
//   batch_report.cpp   summary.json, summary.csv, index.html
//   batch_provenance.cpp  the records that make a rerun skip what is up to date
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "batch_report.h"
#include "hgdeform/app/scenario.h"

namespace hgdcli {
namespace batch {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// --- options (batch.cpp) ---------------------------------------------------------------------

struct Config {
  fs::path input_dir, output_dir, scenario_path, report_dir;
  int jobs = 1;
  bool recursive = false, force = false, quiet = false;
  std::string format = "same";  // "ply", "pcd" or "same"
  int shard_k = 0, shard_n = 1;
  bool sharded = false;
  std::uint64_t memory = 0;  // --memory: a scan's cap, 0 for what the machine has available
};

// --- the scans (batch_scans.cpp) -------------------------------------------------------------

struct Scan {
  fs::path input;
  std::string rel;  // relative to INPUT_DIR, '/' separators
  fs::path output;
  std::string out_rel;
  fs::path scenario;  // the one to use (own or default)
  bool own_scenario = false;
  std::uintmax_t size = 0;
  std::string error;  // known before processing (e.g. two scans writing one output)
};

/// Every file the run reads (the scans, the default scenario, the scans' own scenarios), so
/// that no output of the run replaces one. refuse() asks hgd::refuseInputs, the one check of
/// every tool; the index only saves comparing each output with every input: an output that is
/// one of them is that very file (the same device and inode, through any link or spelling).
class RunInputs {
 public:
  void add(const fs::path& input);
  /// Throws hgd::IoError "<output>: refusing to overwrite the input <input>" when `output`
  /// names one of the inputs.
  void refuse(const std::string& output) const;

 private:
  std::map<std::pair<std::uint64_t, std::uint64_t>, std::string> by_id_;  // (st_dev, st_ino) -> path
};

/// The extension of `p`, lower case, with its dot (".ply").
std::string lowerExtension(const fs::path& p);

fs::path normalisedAbsolute(const fs::path& p);

/// Every scan of the input, sorted by relative path (the order shards and ranks agree on).
/// Entries that look like scans but cannot be one (FIFOs, devices, dangling links) and, with
/// --recursive, links to folders (not followed: they could make cycles) go to `skipped`, with why.
/// The scans and their scenarios go to `inputs`; a scan whose output would replace one of them
/// gets that error.
std::vector<Scan> listScans(const Config& c, std::vector<batch::SkippedEntry>& skipped, RunInputs& inputs);

// --- one scan (batch_worker.cpp) -------------------------------------------------------------

struct Context {
  Config cfg;
  hgd::Scenario default_scenario;
  std::string default_scenario_hash;  // of its canonical form (hgd::scenarioToJson)
  bool thumbnails = false;
  int rank = 0;
};

/// A scan's thumbnail, relative to the report directory: "thumbs/<rel>.png".
std::string thumbnailName(const std::string& rel);

/// The whole pipeline of one scan: read, deform, write (and thumbnail). Never throws.
ScanResult processScan(const Scan& s, const Context& ctx);

// --- progress, signals, temporaries (batch_progress.cpp) -------------------------------------

/// Per-scan lines, or a progress bar redrawn in place on a terminal. Thread-safe.
class Progress {
 public:
  Progress(std::size_t total, bool tty, bool quiet, std::string prefix);

  void started(const std::string& rel);

  /// `number` is the scan's place in the run (1-based); 0 = in order of completion.
  void finished(const ScanResult& r, std::size_t number = 0);

  /// Redraws the bar (the rate and ETA move on while a long scan runs).
  void tick();

  /// Ends the bar's line.
  void close();

 private:
  static int terminalWidth();
  void clearBar();
  void draw();

  std::mutex m_;
  std::size_t total_, done_ = 0;
  bool tty_, quiet_;
  std::string prefix_;
  Clock::time_point start_;
  std::multiset<std::string> running_;
  std::size_t last_len_ = 0;
  bool drawn_ = false;
};

/// SIGINT, SIGTERM, SIGHUP and SIGPIPE remove this process's temporary files, then end it by
/// the same signal (hgd::removeTemporaryFilesOnSignals).
void installSignalHandlers();

/// Removes temporary files left by a killed run (".<name>.tmp-<pid>-<hex>", as hgd::writeShape
/// and writeFileAtomically make them) under `dir`. A file is left alone while its process is
/// alive on this machine or when it changed during the last minute (a writer on another node of
/// a cluster sharing the directory).
void removeStaleTemporaries(const fs::path& dir);

// --- who processes which scan (batch_dispatch.cpp) -------------------------------------------

/// The thread pool: `jobs` workers take the next scan until none is left.
std::vector<ScanResult> runThreads(const std::vector<Scan>& scans, const Context& ctx, Progress& progress);

/// MPI_Init only when started by an MPI launcher; otherwise the plain program.
struct MpiSession {
  bool active = false;
  bool collectives_started = false;  // from here on, a rank failing alone must abort them all
  int rank = 0, size = 1;
  MpiSession();
  ~MpiSession();
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
  void barrier() const;
  /// Rank 0's value on every rank.
  int broadcast(int value) const;
};

#ifdef HGD_HAVE_MPI
/// Every rank holds the same list. Scans, largest first, are handed out by a counter on rank 0
/// (MPI_Fetch_and_op, passive target), one at a time per rank. Returns on rank 0 the results of
/// all ranks (sorted by file), on the others their own.
std::vector<ScanResult> runMpi(const std::vector<Scan>& scans, const Context& ctx, Progress& progress,
                               const MpiSession& mpi);
#endif

}  // namespace batch
}  // namespace hgdcli
