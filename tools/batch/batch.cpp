// hgdeform batch: deform every scan of a folder. A thread pool (--jobs), resumable runs (an output
// whose provenance record matches its input, scenario, options and tool version is skipped; see
// batch_provenance.h), deterministic shards (--shard K/N) for job arrays, and, when launched by
// mpirun, MPI ranks sharing the scans through a one-sided counter.
//
// This file is the command: its arguments, the checks, the top-level run and the summary line.
// The stages live beside it (see batch_internal.h).
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

#include "batch_internal.h"
#include "batch_provenance.h"
#include "batch_report.h"
#include "cli_common.h"
#include "hgdeform/app/scenario.h"
#include "hgdeform/io/io.h"
#ifdef HGD_HAVE_RENDER
#include "thumbnails.h"
#endif
#ifdef HGD_HAVE_MPI
#include <mpi.h>
#endif

namespace hgdcli {
namespace batch {

namespace {

const char* kBatchDescription =
    "Deforms every PLY, PCD, OBJ, XYZ, OFF and STL file in INPUT_DIR as the scenario says and writes the "
    "results\n"
    "under OUTPUT_DIR with the same relative paths. A scenario beside a scan with the same base\n"
    "name (scan_017.json for scan_017.pcd) replaces S.json for that scan. Outputs are written\n"
    "atomically and inputs are never modified. Each output's provenance (its input's size, times,\n"
    "inode and content hash, the scenario, the options, the tool version, the output's size, ctime\n"
    "and inode) is recorded in OUTPUT_DIR/.hgdeform/; a scan whose record still matches is\n"
    "skipped (up to date), so a rerun redoes exactly what changed and an interrupted batch\n"
    "resumes where it stopped; each line says why. A scan that fails is reported and the batch\n"
    "goes on. A second batch writing to the same OUTPUT_DIR at the same time refuses to start\n"
    "(exit 1); shards of one split may share it. FIFOs, devices, dangling links and (with\n"
    "--recursive) links to folders are skipped with a warning; links to folders are not followed.";

const char* kBatchFooter =
    "On a terminal a progress bar shows files done, the current file, the rate and the ETA;\n"
    "otherwise one line per scan is printed. SIGINT, SIGTERM, SIGHUP and SIGPIPE stop the batch\n"
    "without leaving a partial file (it ends by that signal: 130 / 143 / 129 / 141 in a shell).\n"
    "Exit status: 0 when every scan was deformed or up to date, 1 when any failed, 2 on usage\n"
    "errors.\n"
    "\n"
    "MPI: when built with MPI and started by mpirun (or srun), the ranks share the scans\n"
    "dynamically, largest first, one scan at a time per rank; rank 0 prints the summary and\n"
    "writes the report. See docs/batch.md.";

using hgdcli::UsageError;

// --- options ---------------------------------------------------------------------------------

long parseInteger(const std::string& text, const std::string& what, long lo, long hi) {
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(text.c_str(), &end, 10);
  if (text.empty() || *end != '\0' || errno != 0 || v < lo || v > hi)
    throw UsageError(what + " must be an integer from " + std::to_string(lo) + " to " + std::to_string(hi) +
                     " (got '" + text + "')");
  return v;
}

/// Parses `batch ARGS` (argv[0] is the command) into `c`; returns -1 to go on, else the exit
/// status. Only rank 0 (`print`) writes help, version and usage errors.
int parseArgs(int argc, char** argv, Config& c, bool print) {
  CLI::App app(kBatchDescription);
  hgdcli::configureApp(app, "hgdeform batch");
  app.footer(kBatchFooter);
  std::string input, output, scenario, shard, report, memory;
  app.add_option("INPUT_DIR", input, "the folder of scans")->required()->type_name("");
  app.add_option("-s,--scenario", scenario, "default scenario (docs/scenario.md); required")
      ->required()
      ->type_name("FILE");
  app.add_option("-o,--output", output,
                 "output directory (created); neither INPUT_DIR nor inside it; required")
      ->required()
      ->type_name("DIR");
  hgdcli::addCount(app, "-j,--jobs", c.jobs,
                   "scans processed in parallel (default 1); each scan gets\n"
                   "max(1, cores / N) OpenMP threads (at most OMP_NUM_THREADS)",
                   1, 1024);
  app.add_flag("--recursive", c.recursive, "every scan of the tree under INPUT_DIR, not only the top level");
  app.add_option("--format", c.format, "ply, pcd or same (default same: the input's own format)")
      ->check(hgdcli::oneOf({"ply", "pcd", "same"}))
      ->type_name("FORMAT");
  app.add_flag("-f,--force", c.force, "also redo scans whose output is up to date (reason \"forced\")");
  CLI::Option* report_option =
      app.add_option("--report", report,
                     "write DIR/summary.json, DIR/summary.csv and DIR/index.html, with\n"
                     "before/after thumbnails in DIR/thumbs/ (needs an X display)")
          ->type_name("DIR");
  app.add_option("--shard", shard,
                 "process only shard K (0-based) of N: scan i of the list sorted by\n"
                 "relative path belongs to shard i % N")
      ->type_name("K/N");
  app.add_option("--memory", memory,
                 "the memory a scan may take (e.g. 1.5G; default: what the machine has available\n"
                 "when the scan starts): a scan estimated to need more is streamed (binary PLY or PCD)\n"
                 "or fails before it is read")
      ->type_name("BYTES");
  app.add_flag("-q,--quiet", c.quiet, "print errors only");
  const int status = hgdcli::parse(app, argc, argv, print);
  if (status >= 0) return status;
  c.input_dir = input;
  c.memory = hgdcli::memoryOption(memory);
  if (scenario.empty()) throw UsageError("--scenario is required");
  if (output.empty()) throw UsageError("--output is required");
  c.scenario_path = scenario;
  c.output_dir = output;
  if (report_option->count() > 0) {
    if (report.empty()) throw UsageError("--report needs a directory");
    c.report_dir = report;
  }
  if (!shard.empty()) {
    const auto slash = shard.find('/');
    if (slash == std::string::npos) throw UsageError("--shard must be K/N, e.g. 0/4 (got '" + shard + "')");
    c.shard_n = static_cast<int>(parseInteger(shard.substr(slash + 1), "--shard N", 1, 1000000));
    c.shard_k = static_cast<int>(parseInteger(shard.substr(0, slash), "--shard K", 0, c.shard_n - 1));
    c.sharded = true;
  }
  return -1;
}

/// True when `child` is `parent` or lies under it (both absolute and normalised).
bool isWithin(const fs::path& child, const fs::path& parent) {
  const auto [p, c] = std::mismatch(parent.begin(), parent.end(), child.begin(), child.end());
  (void)c;
  return p == parent.end();
}

void checkDirectories(const Config& c) {
  std::error_code ec;
  const std::string in_text = c.input_dir.string();
  if (!fs::exists(c.input_dir, ec)) throw UsageError("input directory '" + in_text + "' does not exist");
  if (!fs::is_directory(c.input_dir, ec)) throw UsageError("'" + in_text + "' is not a directory");
  const fs::path in = normalisedAbsolute(fs::canonical(c.input_dir));
  const fs::path out = normalisedAbsolute(c.output_dir);
  if (isWithin(out, in))
    throw UsageError(
        "output directory '" + c.output_dir.string() + "' " +
        (out == in ? "is the input directory" : "is inside the input directory '" + in_text + "'") +
        ": outputs would mix with the scans; choose a directory outside INPUT_DIR");
  if (fs::exists(c.output_dir, ec) && !fs::is_directory(c.output_dir, ec))
    throw UsageError("output '" + c.output_dir.string() + "' exists and is not a directory");
  if (!c.report_dir.empty() && isWithin(normalisedAbsolute(c.report_dir), in))
    throw UsageError("report directory '" + c.report_dir.string() + "' is inside the input directory '" +
                     in_text + "'; choose a directory outside INPUT_DIR");
  if (!c.report_dir.empty() && fs::exists(c.report_dir, ec) && !fs::is_directory(c.report_dir, ec))
    throw UsageError("report '" + c.report_dir.string() + "' exists and is not a directory");
}

void writeReport(const Context& ctx, const std::vector<ScanResult>& results, const batch::Totals& totals,
                 const std::vector<std::string>& warnings) {
  const fs::path& dir = ctx.cfg.report_dir;
  std::string note;
  for (const auto& w : warnings) note += (note.empty() ? "" : " ") + w;
  if (!note.empty()) note[0] = static_cast<char>(std::toupper(static_cast<unsigned char>(note[0])));
  fs::create_directories(dir);
  hgd::writeFileAtomically((dir / "summary.json").string(), batch::summaryJson(results, totals, warnings));
  hgd::writeFileAtomically((dir / "summary.csv").string(), batch::summaryCsv(results));
  hgd::writeFileAtomically((dir / "index.html").string(), batch::indexHtml(results, totals, note));
}

int run(const Config& cfg, MpiSession& mpi) {
  const auto t_start = Clock::now();
  const bool root = mpi.rank == 0;
  Context ctx;
  ctx.cfg = cfg;
  ctx.rank = mpi.rank;
  ctx.default_scenario = hgd::readScenario(cfg.scenario_path.string());
  ctx.default_scenario_hash = batch::hashBytes(hgd::scenarioToJson(ctx.default_scenario));

  std::vector<batch::SkippedEntry> skipped_entries;
  RunInputs inputs;
  const std::vector<Scan> all = listScans(cfg, skipped_entries, inputs);
  std::vector<Scan> scans;
  for (std::size_t i = 0; i < all.size(); ++i)
    if (static_cast<int>(i % static_cast<std::size_t>(cfg.shard_n)) == cfg.shard_k) scans.push_back(all[i]);
  // The report's files are outputs too: one that would replace an input (the scenario saved as
  // DIR/summary.json, a link to a scan) stops the run before anything is written.
  if (!cfg.report_dir.empty()) {
    for (const char* name : {"summary.json", "summary.csv", "index.html"})
      inputs.refuse((cfg.report_dir / name).string());
    for (const Scan& s : scans) inputs.refuse((cfg.report_dir / thumbnailName(s.rel)).string());
  }
  if (all.empty() && root)
    std::fprintf(stderr, "hgdeform batch: warning: no PLY, PCD, OBJ, XYZ, OFF or STL file in %s%s\n",
                 cfg.input_dir.c_str(), cfg.recursive ? "" : " (subfolders are searched with --recursive)");
  if (root)
    for (const auto& e : skipped_entries)
      std::fprintf(stderr, "hgdeform batch: warning: skipped %s: %s\n", e.path.c_str(), e.why.c_str());

  // Why the report has no thumbnails, if it has none: one warning on stderr, in summary.json's
  // warnings and at the top of index.html.
  std::string note;
  if (!cfg.report_dir.empty()) {
#ifdef HGD_HAVE_RENDER
    const std::string problem = thumbnailProblem();
    ctx.thumbnails = problem.empty();
    if (!ctx.thumbnails)
      note = thumbnailModuleLoaded()
                 ? "no thumbnails (they need an X display with OpenGL): " + problem +
                       ". Run the batch under xvfb-run -a (or with a display) to get before/after pictures."
                 : "no thumbnails: " + problem;
#else
    note = "no thumbnails: this hgdeform was built without PCL visualization (the hgdeform_render target).";
#endif
  }
  std::vector<std::string> run_warnings;
  if (!note.empty()) {
    run_warnings.push_back(note);
    if (root) std::fprintf(stderr, "hgdeform batch: warning: %s\n", note.c_str());
  }

  // One run per output folder (shards of one split excepted). Under MPI rank 0 holds the lock
  // for all ranks and tells them whether it got it.
  batch::OutputLock lock;
  std::string lock_problem;
  if (root) {
    try {
      fs::create_directories(cfg.output_dir);
      lock.acquire(cfg.output_dir.string(), cfg.shard_k, cfg.sharded ? cfg.shard_n : 0);
    } catch (const std::exception& e) {
      lock_problem = e.what();
    }
  }
  mpi.collectives_started = true;  // the other ranks wait for rank 0 from here on
  if (mpi.broadcast(lock_problem.empty() ? 0 : 1) != 0) {
    if (root) std::fprintf(stderr, "hgdeform batch: %s\n", lock_problem.c_str());
    return 1;
  }
  if (root) {
    removeStaleTemporaries(cfg.output_dir);
    if (!cfg.report_dir.empty()) {
      fs::create_directories(cfg.report_dir);
      removeStaleTemporaries(cfg.report_dir);
    }
  }
  mpi.barrier();  // no rank writes before the stale files are gone
  installSignalHandlers();

  if (mpi.active && root && cfg.jobs > 1 && !cfg.quiet)
    std::fprintf(stderr,
                 "hgdeform batch: note: under MPI each rank processes one scan at a time (--jobs unused)\n");
  const bool tty = !mpi.active && ::isatty(STDOUT_FILENO);
  const std::string prefix = mpi.active ? "[rank " + std::to_string(mpi.rank) + "] " : "";
  Progress progress(scans.size(), tty, cfg.quiet, prefix);
  std::vector<ScanResult> results;
  int any_failed = 0;
#ifdef HGD_HAVE_MPI
  if (mpi.active) {
    results = runMpi(scans, ctx, progress, mpi);
    int mine = 0;
    for (const auto& r : results) mine |= r.status == "failed" ? 1 : 0;
    MPI_Allreduce(&mine, &any_failed, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  }
#endif
  if (!mpi.active) {
    results = runThreads(scans, ctx, progress);
    for (const auto& r : results) any_failed |= r.status == "failed" ? 1 : 0;
  }
  progress.close();
  if (!root) return any_failed ? 1 : 0;

  batch::Totals totals = batch::countResults(results);
  totals.wall_s = std::chrono::duration<double>(Clock::now() - t_start).count();
  totals.jobs = mpi.active ? 1 : cfg.jobs;
  totals.ranks = mpi.size;
  if (cfg.sharded) totals.shard = std::to_string(cfg.shard_k) + "/" + std::to_string(cfg.shard_n);
  totals.skipped_entries = skipped_entries;
  int status = any_failed ? 1 : 0;
  bool report_written = false;
  if (!cfg.report_dir.empty()) {
    try {
      writeReport(ctx, results, totals, run_warnings);
      report_written = true;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "hgdeform batch: report: %s\n", e.what());
      status = 1;
    }
  }
  if (!cfg.quiet) {
    std::printf(
        "hgdeform batch: %zu scans in %.1f s (%.2f files/s): %zu ok, %zu failed, %zu skipped (up to date)",
        totals.scans, totals.wall_s,
        totals.wall_s > 0 ? static_cast<double>(totals.scans) / totals.wall_s : 0.0, totals.ok, totals.failed,
        totals.skipped);
    if (!skipped_entries.empty())
      std::printf("; %zu %s skipped (see the warnings)", skipped_entries.size(),
                  skipped_entries.size() == 1 ? "entry" : "entries");
    if (cfg.sharded) std::printf("; shard %s", totals.shard.c_str());
    if (mpi.active) std::printf("; %d MPI ranks", mpi.size);
    if (!cfg.report_dir.empty()) {
      if (report_written)
        std::printf("; report %s", (cfg.report_dir / "index.html").c_str());
      else
        std::printf("; report FAILED: %s not (completely) written (see the error)", cfg.report_dir.c_str());
    }
    std::printf("\n");
    std::fflush(stdout);
  }
  if (totals.failed) {
    std::string names;
    for (const auto& r : results)
      if (r.status == "failed") names += (names.empty() ? "" : ", ") + r.file;
    std::fprintf(stderr, "hgdeform batch: %zu of %zu scans failed: %s\n", totals.failed, totals.scans,
                 names.c_str());
  }
  return status;
}

}  // namespace
}  // namespace batch

int runBatch(int argc, char** argv) {
  batch::MpiSession mpi;
  const bool root = mpi.rank == 0;
  batch::Config cfg;
  try {
    if (const int status = batch::parseArgs(argc, argv, cfg, root); status >= 0) return status;
    batch::checkDirectories(cfg);
  } catch (const UsageError& e) {
    if (root) std::fprintf(stderr, "hgdeform batch: %s\n(see 'hgdeform batch --help')\n", e.what());
    return 2;
  }
  try {
    return batch::run(cfg, mpi);
  } catch (const std::exception& e) {
    // Before the first collective call every rank fails alike (same files, same checks): rank 0
    // says why. After it, a rank failing alone must not leave the others waiting forever.
#ifdef HGD_HAVE_MPI
    if (mpi.active && mpi.collectives_started) {
      std::fprintf(stderr, "hgdeform batch: [rank %d] %s\n", mpi.rank, e.what());
      std::fflush(stderr);
      MPI_Abort(MPI_COMM_WORLD, 1);
    }
#endif
    if (root) std::fprintf(stderr, "hgdeform batch: %s\n", e.what());
    return 1;
  }
}

}  // namespace hgdcli
