// hgdeform batch: deform every scan of a folder. A thread pool (--jobs), resumable runs (an output
// whose provenance record matches its input, scenario, options and tool version is skipped; see
// batch_provenance.h), deterministic shards (--shard K/N) for job arrays, and, when launched by
// mpirun, MPI ranks sharing the scans through a one-sided counter.
#include <omp.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <climits>
#include <condition_variable>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <future>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <regex>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "batch_provenance.h"
#include "batch_report.h"
#include "cli_common.h"
#include "hgdeform/deformer.h"
#include "hgdeform/io.h"
#include "hgdeform/runner.h"
#include "hgdeform/scenario.h"
#ifdef HGD_HAVE_RENDER
#include "hgdeform/render.h"
#endif
#ifdef HGD_HAVE_MPI
#include <mpi.h>
#endif

namespace hgdcli {

namespace {

namespace fs = std::filesystem;
using batch::ScanResult;
using Clock = std::chrono::steady_clock;

const char* kBatchDescription =
    "Deforms every PLY, PCD, OBJ, XYZ, OFF and STL file in INPUT_DIR as the scenario says and writes the "
    "results\n"
    "under OUTPUT_DIR with the same relative paths. A scenario beside a scan with the same base\n"
    "name (scan_017.json for scan_017.pcd) replaces S.json for that scan. Outputs are written\n"
    "atomically and inputs are never modified. Each output's provenance (its input's size, time\n"
    "and content hash, the scenario, the options, the tool version) is recorded in\n"
    "OUTPUT_DIR/.hgdeform/; a scan whose record still matches is skipped (up to date), so a rerun\n"
    "redoes exactly what changed and an interrupted batch resumes where it stopped; each line says\n"
    "why. A scan that fails is reported and the batch goes on. A second batch writing to the same\n"
    "OUTPUT_DIR at the same time refuses to start (exit 1); shards of one split may share it.\n"
    "FIFOs, devices, dangling links and (with --recursive) links to folders are skipped with a\n"
    "warning; links to folders are not followed.";

const char* kBatchFooter =
    "On a terminal a progress bar shows files done, the current file, the rate and the ETA;\n"
    "otherwise one line per scan is printed. SIGINT and SIGTERM stop the batch without leaving\n"
    "a partial file (exit status 130 / 143). Exit status: 0 when every scan was deformed or up\n"
    "to date, 1 when any failed, 2 on usage errors.\n"
    "\n"
    "MPI: when built with MPI and started by mpirun (or srun), the ranks share the scans\n"
    "dynamically, largest first, one scan at a time per rank; rank 0 prints the summary and\n"
    "writes the report. See docs/batch.md.";

using hgdcli::UsageError;

// --- options ---------------------------------------------------------------------------------

struct Config {
  fs::path input_dir, output_dir, scenario_path, report_dir;
  int jobs = 1;
  bool recursive = false, force = false, quiet = false;
  std::string format = "same";  // "ply", "pcd" or "same"
  int shard_k = 0, shard_n = 1;
  bool sharded = false;
};

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
  std::string input, output, scenario, shard, report;
  app.add_option("INPUT_DIR", input, "the folder of scans")->required()->type_name("");
  app.add_option("-s,--scenario", scenario, "default scenario (docs/scenario.md); required")
      ->required()
      ->type_name("FILE");
  app.add_option("-o,--output", output,
                 "output directory (created); neither INPUT_DIR nor inside it; required")
      ->required()
      ->type_name("DIR");
  app.add_option("-j,--jobs", c.jobs,
                 "scans processed in parallel (default 1); each scan gets\n"
                 "max(1, cores / N) OpenMP threads (at most OMP_NUM_THREADS)")
      ->check(hgdcli::integerFrom(1, 1024))
      ->type_name("N");
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
  app.add_flag("-q,--quiet", c.quiet, "print errors only");
  const int status = hgdcli::parse(app, argc, argv, print);
  if (status >= 0) return status;
  c.input_dir = input;
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

fs::path normalisedAbsolute(const fs::path& p) {
  fs::path n = fs::weakly_canonical(fs::absolute(p)).lexically_normal();
  if (!n.has_filename() && n.has_parent_path() && n != n.root_path()) n = n.parent_path();
  return n;
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

// --- the scans -------------------------------------------------------------------------------

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

std::string lowerExtension(const fs::path& p) {
  std::string e = p.extension().string();
  for (char& ch : e) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  return e;
}

bool isScanFile(const fs::path& p) {
  const std::string e = lowerExtension(p);
  // Not .txt: too common a name for notes and logs in a folder of scans.
  return e == ".ply" || e == ".pcd" || e == ".obj" || e == ".xyz" || e == ".off" || e == ".stl";
}

bool hidden(const fs::path& p) {
  const std::string name = p.filename().string();
  return !name.empty() && name[0] == '.';
}

/// Every scan of the input, sorted by relative path (the order shards and ranks agree on).
/// Entries that look like scans but cannot be one (FIFOs, devices, dangling links) and, with
/// --recursive, links to folders (not followed: they could make cycles) go to `skipped`, with why.
std::vector<Scan> listScans(const Config& c, std::vector<batch::SkippedEntry>& skipped) {
  std::vector<fs::path> files;
  std::error_code ec;
  auto consider = [&](const fs::directory_entry& e) {
    if (hidden(e.path())) return;
    std::error_code e1, e2;
    const fs::file_status own = e.symlink_status(e1);
    const fs::file_status target = e.status(e2);  // links followed
    const bool link = !e1 && fs::is_symlink(own);
    const std::string rel = e.path().lexically_relative(c.input_dir).generic_string();
    if (link && !fs::exists(target)) {  // dangling, or a loop of links
      std::error_code e3;
      const fs::path to = fs::read_symlink(e.path(), e3);
      if (isScanFile(e.path()) || isScanFile(to))
        skipped.push_back({rel, "a dangling symbolic link (" + to.string() + ": " +
                                    (e2 ? e2.message() : std::string("No such file or directory")) + ")"});
      return;
    }
    if (link && fs::is_directory(target)) {
      if (c.recursive)
        skipped.push_back({rel,
                           "a symbolic link to a folder: not followed, to avoid cycles (give the folder "
                           "it names as INPUT_DIR to process it)"});
      return;
    }
    if (!isScanFile(e.path()) || fs::is_directory(target)) return;
    if (fs::is_regular_file(target)) {
      files.push_back(e.path());
      return;
    }
    const std::string what = fs::is_fifo(target)                                          ? "a FIFO"
                             : fs::is_socket(target)                                      ? "a socket"
                             : fs::is_block_file(target) || fs::is_character_file(target) ? "a device"
                                                                                          : "a special file";
    skipped.push_back({rel, what + (link ? " (through a symbolic link)" : "") + ", not a regular file"});
  };
  if (c.recursive) {
    fs::recursive_directory_iterator it(c.input_dir, fs::directory_options::skip_permission_denied, ec), end;
    if (ec) throw std::runtime_error(c.input_dir.string() + ": cannot list: " + ec.message());
    for (; it != end; it.increment(ec)) {
      if (ec) throw std::runtime_error(c.input_dir.string() + ": cannot list: " + ec.message());
      if (hidden(it->path())) {
        std::error_code e2;
        if (it->is_directory(e2)) it.disable_recursion_pending();  // .git, .cache, ...
        continue;
      }
      consider(*it);
    }
  } else {
    fs::directory_iterator it(c.input_dir, ec), end;
    if (ec) throw std::runtime_error(c.input_dir.string() + ": cannot list: " + ec.message());
    for (; it != end; it.increment(ec)) {
      if (ec) throw std::runtime_error(c.input_dir.string() + ": cannot list: " + ec.message());
      consider(*it);
    }
  }

  std::vector<Scan> scans;
  std::set<std::string> inputs;  // canonical input paths, so that no output overwrites an input
  for (const auto& f : files) {
    Scan s;
    s.input = f;
    s.rel = f.lexically_relative(c.input_dir).generic_string();
    fs::path out_rel(s.rel);
    if (c.format != "same") out_rel.replace_extension("." + c.format);
    s.out_rel = out_rel.generic_string();
    s.output = c.output_dir / out_rel;
    const fs::path own = f.parent_path() / (f.stem().string() + ".json");
    std::error_code e1, e2;
    if (fs::is_regular_file(own, e1) && !fs::equivalent(own, c.scenario_path, e2)) {
      s.scenario = own;
      s.own_scenario = true;
    } else {
      s.scenario = c.scenario_path;
    }
    s.size = fs::file_size(f, e1);
    if (e1) s.size = 0;
    inputs.insert(normalisedAbsolute(f).string());
    scans.push_back(std::move(s));
  }
  std::sort(scans.begin(), scans.end(), [](const Scan& a, const Scan& b) { return a.rel < b.rel; });
  std::sort(skipped.begin(), skipped.end(),
            [](const batch::SkippedEntry& a, const batch::SkippedEntry& b) { return a.path < b.path; });
  std::map<std::string, std::string> writer;  // output -> the scan writing it
  for (auto& s : scans) {
    auto [it, fresh] = writer.emplace(s.out_rel, s.rel);
    if (!fresh)
      s.error = "output " + s.out_rel + " would also be written by " + it->second + " (use --format same)";
    else if (inputs.count(normalisedAbsolute(s.output).string()))
      s.error = "output " + s.output.string() + " would overwrite an input scan";
  }
  return scans;
}

/// Removes temporary files left by a killed run (".<name>.tmp-<pid>-<hex>", as hgd::writeShape
/// and writeFileAtomically make them) under `dir`. A file is left alone while its process is
/// alive on this machine or when it changed during the last minute (a writer on another node of
/// a cluster sharing the directory).
void removeStaleTemporaries(const fs::path& dir) {
  static const std::regex pattern(R"(^\..+\.tmp-([0-9]+)-[0-9a-f]+$)");
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return;
  fs::recursive_directory_iterator it(dir, fs::directory_options::skip_permission_denied, ec), end;
  for (; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    std::smatch m;
    if (!std::regex_match(name, m, pattern)) continue;
    std::error_code e2;
    if (!it->is_regular_file(e2)) continue;
    const std::string pid_text = m[1].str();
    if (pid_text.size() <= 9) {
      const long pid = std::strtol(pid_text.c_str(), nullptr, 10);
      if (pid > 0 && (::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM)) continue;  // alive
    }
    const auto age = fs::file_time_type::clock::now() - fs::last_write_time(it->path(), e2);
    if (e2 || age < std::chrono::seconds(60)) continue;
    fs::remove(it->path(), e2);
  }
}

// --- one scan --------------------------------------------------------------------------------

struct Context {
  Config cfg;
  hgd::Scenario default_scenario;
  std::string default_scenario_hash;  // of its canonical form (hgd::scenarioToJson)
  bool thumbnails = false;
  int rank = 0;
};

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// --- provenance: is an output up to date? ---------------------------------------------------

/// OUTPUT_DIR/.hgdeform/records/<output>.json: what the output was made from. One small file per
/// output, written by whichever thread, shard or MPI rank made that output (each output has
/// exactly one writer), right after the output: no shared file to merge, and an interrupted run
/// keeps the records of the scans it finished.
fs::path recordPath(const Context& ctx, const Scan& s) {
  return ctx.cfg.output_dir / ".hgdeform" / "records" / (s.out_rel + ".json");
}

/// The options that change an output's bytes: only its format (the deformation options are the
/// tool's own, covered by its version).
nlohmann::json outputOptions(const Scan& s) {
  std::string ext = lowerExtension(s.output);
  if (!ext.empty()) ext.erase(0, 1);
  return {{"output_format", ext}};
}

/// Why the scan must be (re)done: reasons joined by ", ", "" when its output is up to date.
/// Hashes the input (into `input_hash`) only when its size is the recorded one but its time is
/// not; `refresh` then says that only the record's input time is out of date.
std::string whyRedo(const Scan& s, const batch::FileState& input, const std::optional<batch::Provenance>& rec,
                    const std::string& scenario_hash, const nlohmann::json& options, std::string& input_hash,
                    bool& refresh) {
  const batch::FileState out = batch::fileState(s.output.string());
  if (!out.exists) return rec ? "output missing" : "new";
  if (!rec) return "no record";
  std::vector<std::string> why;
  if (!rec->invalid.empty() || rec->input != s.rel || rec->input_size != input.size) {
    why.push_back("input changed");
  } else if (rec->input_mtime_ns != input.mtime_ns) {
    input_hash = batch::hashFile(s.input.string());
    if (input_hash != rec->input_hash)
      why.push_back("input changed");
    else
      refresh = batch::fileState(s.input.string()).unchangedFrom(input);
  }
  if (scenario_hash != rec->scenario_hash) why.push_back("scenario changed");
  if (options != rec->options) why.push_back("options changed");
  if (batch::toolVersion() != rec->tool) why.push_back("tool version changed");
  if (out.size != rec->output_size) why.push_back("output changed");
  std::string text;
  for (const auto& w : why) text += (text.empty() ? "" : ", ") + w;
  return text;
}

/// HGDEFORM_BATCH_TEST_HOOK=REL:FILE, for tests only: once the output of scan REL is written
/// (before its input is checked again and its record written), create FILE and wait until it
/// is removed (60 s at most). Lets a test change an input mid-scan or hold a run open.
void testHook(const std::string& rel) {
  const char* env = std::getenv("HGDEFORM_BATCH_TEST_HOOK");
  if (!env) return;
  const std::string hook = env;
  const auto colon = hook.find(':');
  if (colon == std::string::npos || hook.compare(0, colon, rel) != 0) return;
  const fs::path flag = hook.substr(colon + 1);
  hgd::writeFileAtomically(flag.string(), "waiting\n");
  const auto deadline = Clock::now() + std::chrono::seconds(60);
  std::error_code ec;
  while (fs::exists(flag, ec) && Clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
}

#ifdef HGD_HAVE_RENDER
std::string thumbnailName(const std::string& rel) {
  return "thumbs/" + rel + ".png";
}

std::mutex g_render_mutex;  // VTK is not thread-safe: one picture at a time

void renderThumbnail(const hgd::Shape& before, const hgd::Shape& after, const fs::path& png) {
  fs::create_directories(png.parent_path());
  hgd::RenderOptions o;
  o.width = 640;
  o.height = 320;
  o.point_size = 2;
  o.titles = {"before", "after"};
  std::lock_guard<std::mutex> lock(g_render_mutex);
  hgd::renderPng({&before, &after}, png.string(), o);
}
#endif

/// Thumbnail of a deformed scan, or of an up-to-date one (from its input and existing output).
/// A scan's warnings are one line, joined by "; ".
void appendWarning(std::string& warning, const std::string& more) {
  warning += (warning.empty() ? "" : "; ") + more;
}

/// Returns the name relative to the report directory, "" (and a warning) on failure.
std::string thumbnail(const Context& ctx, const Scan& s, const hgd::Shape* before, const hgd::Shape* after,
                      std::string& warning) {
#ifdef HGD_HAVE_RENDER
  const std::string name = thumbnailName(s.rel);
  const fs::path png = ctx.cfg.report_dir / name;
  try {
    if (before && after) {
      renderThumbnail(*before, *after, png);
    } else {
      std::error_code e1, e2;
      const auto t_png = fs::last_write_time(png, e1);
      const auto t_out = fs::last_write_time(s.output, e2);
      if (e1 || e2 || t_png < t_out) {
        const hgd::Shape in = hgd::readShape(s.input.string());
        const hgd::Shape out = hgd::readShape(s.output.string());
        renderThumbnail(in, out, png);
      }
    }
    return name;
  } catch (const std::exception& e) {
    appendWarning(warning, std::string("no thumbnail: ") + e.what());
    return "";
  }
#else
  (void)ctx, (void)s, (void)before, (void)after, (void)warning;
  return "";
#endif
}

/// The whole pipeline of one scan: read, deform, write (and thumbnail). Never throws.
ScanResult processScan(const Scan& s, const Context& ctx) {
  ScanResult r;
  r.file = s.rel;
  r.output = s.out_rel;
  r.scenario = s.scenario.string();
  r.own_scenario = s.own_scenario;
  r.rank = ctx.rank;
  const auto t0 = Clock::now();
  try {
    if (!s.error.empty()) throw std::runtime_error(s.error);
    std::optional<hgd::Scenario> own;
    if (s.own_scenario) own = hgd::readScenario(s.scenario.string());
    const hgd::Scenario& scenario = own ? *own : ctx.default_scenario;
    const std::string scenario_hash =
        own ? batch::hashBytes(hgd::scenarioToJson(*own)) : ctx.default_scenario_hash;
    const nlohmann::json options = outputOptions(s);
    const std::string record_path = recordPath(ctx, s).string();
    const std::optional<batch::Provenance> rec = batch::readRecord(record_path);
    const batch::FileState in_before = batch::fileState(s.input.string());
    std::string input_hash;
    bool refresh = false;
    r.reason =
        ctx.cfg.force ? "forced" : whyRedo(s, in_before, rec, scenario_hash, options, input_hash, refresh);
    if (r.reason.empty()) {
      r.reason = "up to date";
      r.status = "skipped";
      if (refresh) {  // touched, same bytes: remember the new time so as not to hash it again
        batch::Provenance p = *rec;
        p.input_mtime_ns = in_before.mtime_ns;
        try {
          hgd::writeFileAtomically(record_path, batch::recordText(p));
        } catch (const std::exception& e) {
          appendWarning(r.warning, std::string("provenance record not updated: ") + e.what());
        }
      }
      if (ctx.thumbnails) r.thumbnail = thumbnail(ctx, s, nullptr, nullptr, r.warning);
      r.ms_wall = msSince(t0);
      return r;
    }
    // Hash before reading: a change from here to the end shows in the input's stat below.
    if (input_hash.empty()) {
      const bool recorded = rec && rec->invalid.empty() && rec->input == s.rel &&
                            rec->input_size == in_before.size && rec->input_mtime_ns == in_before.mtime_ns;
      input_hash = recorded ? rec->input_hash : batch::hashFile(s.input.string());
    }
    hgd::ScenarioRunner run = hgd::ScenarioRunner::read(s.input.string());
    run.setScenario(scenario);
    run.applyMoves();
    fs::create_directories(s.output.parent_path());
    std::error_code gone;
    fs::remove(record_path, gone);  // from here until the new record, the output is unrecorded
    run.write(s.output.string(), {}, {s.scenario.string()});
    const hgd::DeformReport rep = run.report();
    r.ms_write = rep.write_ms;
    testHook(s.rel);
    batch::Provenance p;
    p.input = s.rel;
    p.input_size = in_before.size;
    p.input_mtime_ns = in_before.mtime_ns;
    p.input_hash = input_hash;
    p.scenario = s.scenario.string();
    p.scenario_hash = scenario_hash;
    p.options = options;
    p.tool = batch::toolVersion();
    p.output_size = batch::fileState(s.output.string()).size;
    if (!batch::fileState(s.input.string()).unchangedFrom(in_before)) {
      p.invalid = "the input changed while it was being deformed";
      appendWarning(r.warning,
                    "the input changed while it was being deformed: the output is not recorded as up to "
                    "date and the next run redoes it");
    }
    try {
      fs::create_directories(fs::path(record_path).parent_path());
      hgd::writeFileAtomically(record_path, batch::recordText(p));
    } catch (const std::exception& e) {
      appendWarning(
          r.warning,
          std::string("provenance record not written (the next run redoes this scan): ") + e.what());
    }
    r.status = "ok";
    r.has_metrics = true;
    r.points = rep.points;
    r.clusters = rep.clusters;
    r.iterations = rep.iterations;
    r.frames = rep.frames;
    r.handle_error = rep.handle_error;
    r.ms_read = rep.read_ms;
    r.ms_build = rep.build_ms;
    r.ms_field = rep.field_ms;
    r.ms_sampling = rep.sampling_ms;
    r.ms_clusters = rep.clusters_ms;
    r.ms_solve = rep.solve_ms;
    r.ms_interpolation = rep.interpolation_ms;
    r.ms_total = rep.total_ms;
    r.notes = rep.notes;
    for (const auto& w : rep.warnings) appendWarning(r.warning, w);
    if (ctx.thumbnails) {
      const hgd::Shape after = run.deformedShape();
      r.thumbnail = thumbnail(ctx, s, &run.shape(), &after, r.warning);
    }
  } catch (const std::bad_alloc&) {
    r.status = "failed";
    r.error = "out of memory";
  } catch (const std::exception& e) {
    r.status = "failed";
    r.error = e.what();
  } catch (...) {
    r.status = "failed";
    r.error = "unknown error";
  }
  if (r.status == "failed") r.has_metrics = false;
  r.ms_wall = msSince(t0);
  return r;
}

// --- progress --------------------------------------------------------------------------------

volatile std::sig_atomic_t g_bar_on_screen = 0;

/// Per-scan lines, or a progress bar redrawn in place on a terminal. Thread-safe.
class Progress {
 public:
  Progress(std::size_t total, bool tty, bool quiet, std::string prefix)
      : total_(total), tty_(tty), quiet_(quiet), prefix_(std::move(prefix)), start_(Clock::now()) {}

  void started(const std::string& rel) {
    std::lock_guard<std::mutex> lock(m_);
    running_.insert(rel);
    if (tty_ && !quiet_) draw();
  }

  /// `number` is the scan's place in the run (1-based); 0 = in order of completion.
  void finished(const ScanResult& r, std::size_t number = 0) {
    std::lock_guard<std::mutex> lock(m_);
    running_.erase(r.file);
    ++done_;
    if (number == 0) number = done_;
    if (r.status == "failed" || !r.warning.empty()) {
      clearBar();
      if (r.status == "failed")
        std::fprintf(stderr, "hgdeform batch: %s%s: %s\n", prefix_.c_str(), r.file.c_str(), r.error.c_str());
      if (!r.warning.empty())
        std::fprintf(stderr, "hgdeform batch: %s%s: warning: %s\n", prefix_.c_str(), r.file.c_str(),
                     r.warning.c_str());
      std::fflush(stderr);
    }
    if (quiet_) return;
    if (!r.notes.empty()) {
      clearBar();
      for (const auto& note : r.notes)
        std::fprintf(stderr, "hgdeform batch: %s%s: note: %s\n", prefix_.c_str(), r.file.c_str(),
                     note.c_str());
      std::fflush(stderr);
    }
    if (tty_) {
      draw();
      return;
    }
    std::string line =
        prefix_ + "[" + std::to_string(number) + "/" + std::to_string(total_) + "] " + r.file + ": ";
    if (r.status == "ok")
      line += "ok " + std::to_string(static_cast<long long>(r.ms_wall + 0.5)) + " ms (" + r.reason + ")";
    else if (r.status == "skipped")
      line += "skipped (up to date)";
    else
      line += "FAILED: " + r.error;
    line += "\n";
    std::fputs(line.c_str(), stdout);
    std::fflush(stdout);
  }

  /// Redraws the bar (the rate and ETA move on while a long scan runs).
  void tick() {
    std::lock_guard<std::mutex> lock(m_);
    if (tty_ && !quiet_ && drawn_) draw();
  }

  /// Ends the bar's line.
  void close() {
    std::lock_guard<std::mutex> lock(m_);
    if (tty_ && drawn_) {
      std::fputs("\n", stdout);
      std::fflush(stdout);
      drawn_ = false;
      g_bar_on_screen = 0;
    }
  }

 private:
  static int terminalWidth() {
    winsize w{};
    if (::ioctl(STDOUT_FILENO, TIOCGWINSZ, &w) == 0 && w.ws_col >= 20) return w.ws_col;
    return 80;
  }

  void clearBar() {
    if (!tty_ || !drawn_) return;
    std::fputs(("\r" + std::string(last_len_, ' ') + "\r").c_str(), stdout);
    std::fflush(stdout);
    drawn_ = false;
  }

  void draw() {
    const std::size_t width = static_cast<std::size_t>(terminalWidth()) - 1;
    const double elapsed = std::chrono::duration<double>(Clock::now() - start_).count();
    const double rate = elapsed > 0 ? static_cast<double>(done_) / elapsed : 0.0;
    char eta[32] = "--:--";
    if (done_ > 0 && rate > 0) {
      const long s = std::lround(static_cast<double>(total_ - done_) / rate);
      if (s >= 3600)
        std::snprintf(eta, sizeof eta, "%ld:%02ld:%02ld", s / 3600, (s / 60) % 60, s % 60);
      else
        std::snprintf(eta, sizeof eta, "%ld:%02ld", s / 60, s % 60);
    }
    const int bar_len = 20;
    const int filled = total_ ? static_cast<int>(bar_len * done_ / total_) : bar_len;
    std::string bar = "[" + std::string(static_cast<std::size_t>(filled), '#') +
                      std::string(static_cast<std::size_t>(bar_len - filled), '.') + "]";
    char tail[96];
    std::snprintf(tail, sizeof tail, "  %.2f files/s  ETA %s", rate, eta);
    std::string head = bar + " " + std::to_string(done_) + "/" + std::to_string(total_) + "  ";
    std::string current;
    if (!running_.empty()) {
      current = *running_.begin();
      if (running_.size() > 1) current += " (+" + std::to_string(running_.size() - 1) + ")";
    }
    const std::size_t fixed = head.size() + std::strlen(tail);
    if (fixed + current.size() > width) {
      const std::size_t room = width > fixed + 3 ? width - fixed - 3 : 0;
      current = room ? "..." + current.substr(current.size() - room) : "";
    }
    std::string text = head + current + tail;
    if (text.size() > width) text.resize(width);
    const std::size_t len = text.size();
    if (len < last_len_) text += std::string(last_len_ - len, ' ');
    last_len_ = len;
    std::fputs(("\r" + text).c_str(), stdout);
    std::fflush(stdout);
    drawn_ = true;
    g_bar_on_screen = 1;
  }

  std::mutex m_;
  std::size_t total_, done_ = 0;
  bool tty_, quiet_;
  std::string prefix_;
  Clock::time_point start_;
  std::multiset<std::string> running_;
  std::size_t last_len_ = 0;
  bool drawn_ = false;
};

// --- signals ---------------------------------------------------------------------------------

void onTerminatingSignal(int sig) {
  hgd::removeTemporaryFiles();  // async-signal-safe
  if (g_bar_on_screen) {
    const ssize_t ignored = ::write(STDOUT_FILENO, "\n", 1);
    (void)ignored;
  }
  ::_exit(sig == SIGINT ? 130 : 143);
}

void installSignalHandlers() {
  struct sigaction sa {};
  sa.sa_handler = onTerminatingSignal;
  sigemptyset(&sa.sa_mask);
  sigaddset(&sa.sa_mask, SIGINT);
  sigaddset(&sa.sa_mask, SIGTERM);
  sa.sa_flags = 0;
  ::sigaction(SIGINT, &sa, nullptr);
  ::sigaction(SIGTERM, &sa, nullptr);
}

// --- running the scans -----------------------------------------------------------------------

/// Dispatch order: largest first, so that a big scan started last does not hold up the end.
std::vector<std::size_t> largestFirst(const std::vector<Scan>& scans) {
  std::vector<std::size_t> order(scans.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return scans[a].size > scans[b].size; });
  return order;
}

/// OpenMP threads for each of `concurrent` scans: the cores (as this process may use them) shared
/// out, at most OMP_NUM_THREADS when that is set.
int ompThreadsPerScan(int concurrent) {
  int n = std::max(1, omp_get_num_procs() / std::max(1, concurrent));
  if (const char* env = std::getenv("OMP_NUM_THREADS")) {
    const long cap = std::strtol(env, nullptr, 10);
    if (cap >= 1) n = std::min(n, static_cast<int>(std::min(cap, 1024L)));
  }
  return n;
}

/// The thread pool: `jobs` workers take the next scan until none is left.
std::vector<ScanResult> runThreads(const std::vector<Scan>& scans, const Context& ctx, Progress& progress) {
  const std::size_t n = scans.size();
  std::vector<ScanResult> results(n);
  if (n == 0) return results;
  std::vector<std::size_t> order;
  if (ctx.cfg.jobs == 1) {
    for (std::size_t i = 0; i < n; ++i) order.push_back(i);  // the listing's order: easy to follow
  } else {
    order = largestFirst(scans);
  }
  const int threads_per_scan = ompThreadsPerScan(ctx.cfg.jobs);
  const std::size_t workers = std::min<std::size_t>(static_cast<std::size_t>(ctx.cfg.jobs), n);
  std::atomic<std::size_t> next{0};
  std::mutex m;
  std::condition_variable cv;
  std::size_t running = workers;
  auto work = [&] {
    omp_set_num_threads(threads_per_scan);  // this thread's parallel regions
    for (;;) {
      const std::size_t k = next.fetch_add(1);
      if (k >= n) break;
      const Scan& s = scans[order[k]];
      progress.started(s.rel);
      results[order[k]] = processScan(s, ctx);
      progress.finished(results[order[k]]);
    }
    std::lock_guard<std::mutex> lock(m);
    if (--running == 0) cv.notify_all();
  };
  std::vector<std::thread> pool;
  for (std::size_t i = 0; i < workers; ++i) pool.emplace_back(work);
  {
    std::unique_lock<std::mutex> lock(m);
    while (!cv.wait_for(lock, std::chrono::seconds(1), [&] { return running == 0; })) {
      lock.unlock();
      progress.tick();
      lock.lock();
    }
  }
  for (auto& t : pool) t.join();
  return results;
}

// --- MPI -------------------------------------------------------------------------------------

/// MPI_Init only when started by an MPI launcher; otherwise the plain program.
struct MpiSession {
  bool active = false;
  bool collectives_started = false;  // from here on, a rank failing alone must abort them all
  int rank = 0, size = 1;
  MpiSession() {
#ifdef HGD_HAVE_MPI
    if (std::getenv("OMPI_COMM_WORLD_SIZE") || std::getenv("PMI_SIZE")) {
      int provided = 0;
      // Only the main thread calls MPI; the scan runs on a worker thread meanwhile.
      MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
      active = true;
      MPI_Comm_rank(MPI_COMM_WORLD, &rank);
      MPI_Comm_size(MPI_COMM_WORLD, &size);
    }
#endif
  }
  ~MpiSession() {
#ifdef HGD_HAVE_MPI
    if (active) MPI_Finalize();
#endif
  }
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
  void barrier() const {
#ifdef HGD_HAVE_MPI
    if (active) MPI_Barrier(MPI_COMM_WORLD);
#endif
  }
  /// Rank 0's value on every rank.
  int broadcast(int value) const {
#ifdef HGD_HAVE_MPI
    if (active) MPI_Bcast(&value, 1, MPI_INT, 0, MPI_COMM_WORLD);
#endif
    return value;
  }
};

#ifdef HGD_HAVE_MPI
/// FNV-1a of the list, for checking that every MPI rank sees the same scans.
std::uint64_t listHash(const std::vector<Scan>& scans) {
  std::uint64_t h = 1469598103934665603ull;
  auto add = [&](const std::string& s) {
    for (unsigned char ch : s) h = (h ^ ch) * 1099511628211ull;
    h = (h ^ 0xff) * 1099511628211ull;
  };
  for (const auto& s : scans) {
    add(s.rel);
    add(std::to_string(s.size));
  }
  return h;
}

/// Ranks on this node, so that they share its cores.
int ranksOnThisNode() {
  MPI_Comm node;
  MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node);
  int n = 1;
  MPI_Comm_size(node, &n);
  MPI_Comm_free(&node);
  return n;
}

/// Every rank holds the same list. Scans, largest first, are handed out by a counter on rank 0
/// (MPI_Fetch_and_op, passive target), one at a time per rank. Returns on rank 0 the results of
/// all ranks (sorted by file), on the others their own.
std::vector<ScanResult> runMpi(const std::vector<Scan>& scans, const Context& ctx, Progress& progress,
                               const MpiSession& mpi) {
  // Same scans everywhere? (A rank on a node with a stale view of a shared file system would
  // otherwise process the wrong files.)
  unsigned long long mine = listHash(scans), root = mine;
  MPI_Bcast(&root, 1, MPI_UNSIGNED_LONG_LONG, 0, MPI_COMM_WORLD);
  int differs = root != mine ? 1 : 0, any_differs = 0;
  MPI_Allreduce(&differs, &any_differs, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  if (any_differs) throw std::runtime_error("the MPI ranks do not see the same scans in the input directory");

  const int threads_per_scan = ompThreadsPerScan(ranksOnThisNode());
  const std::vector<std::size_t> order = largestFirst(scans);
  const long n = static_cast<long>(scans.size());

  long* counter = nullptr;
  MPI_Win win;
  MPI_Win_allocate(mpi.rank == 0 ? static_cast<MPI_Aint>(sizeof(long)) : 0, sizeof(long), MPI_INFO_NULL,
                   MPI_COMM_WORLD, &counter, &win);
  if (mpi.rank == 0) {
    MPI_Win_lock(MPI_LOCK_EXCLUSIVE, 0, 0, win);
    *counter = 0;
    MPI_Win_unlock(0, win);
  }
  MPI_Barrier(MPI_COMM_WORLD);
  MPI_Win_lock_all(0, win);

  std::vector<ScanResult> results;
  for (;;) {
    const long one = 1;
    long k = 0;
    MPI_Fetch_and_op(&one, &k, MPI_LONG, 0, 0, MPI_SUM, win);
    MPI_Win_flush(0, win);
    if (k >= n) break;
    const Scan& s = scans[order[static_cast<std::size_t>(k)]];
    progress.started(s.rel);
    auto future = std::async(std::launch::async, [&] {
      omp_set_num_threads(threads_per_scan);
      return processScan(s, ctx);
    });
    // Keep this rank's MPI progressing meanwhile: with some transports the counter on rank 0
    // only advances when rank 0 enters the library.
    while (future.wait_for(std::chrono::milliseconds(20)) != std::future_status::ready) {
      int flag = 0;
      MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, MPI_STATUS_IGNORE);
    }
    results.push_back(future.get());
    progress.finished(results.back(), static_cast<std::size_t>(k) + 1);
  }
  MPI_Win_unlock_all(win);
  MPI_Win_free(&win);

  // Gather the results on rank 0 as JSON text.
  nlohmann::json array = nlohmann::json::array();
  for (const auto& r : results) array.push_back(batch::toJson(r));
  const std::string text = array.dump();
  int len = static_cast<int>(text.size());
  std::vector<int> lens(static_cast<std::size_t>(mpi.size)), displs(static_cast<std::size_t>(mpi.size));
  MPI_Gather(&len, 1, MPI_INT, lens.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
  std::vector<char> all;
  if (mpi.rank == 0) {
    long long total = 0;
    for (int r = 0; r < mpi.size; ++r) {
      displs[static_cast<std::size_t>(r)] = static_cast<int>(total);
      total += lens[static_cast<std::size_t>(r)];
    }
    all.resize(static_cast<std::size_t>(std::max(total, 1LL)));
  }
  MPI_Gatherv(text.data(), len, MPI_CHAR, all.data(), lens.data(), displs.data(), MPI_CHAR, 0,
              MPI_COMM_WORLD);
  if (mpi.rank != 0) return results;
  std::vector<ScanResult> merged;
  for (int r = 0; r < mpi.size; ++r) {
    const auto ri = static_cast<std::size_t>(r);
    const auto j = nlohmann::json::parse(all.begin() + displs[ri], all.begin() + displs[ri] + lens[ri]);
    for (const auto& e : j) merged.push_back(batch::fromJson(e));
  }
  std::sort(merged.begin(), merged.end(),
            [](const ScanResult& a, const ScanResult& b) { return a.file < b.file; });
  return merged;
}
#endif

// --- the report ------------------------------------------------------------------------------

void writeReport(const Context& ctx, const std::vector<ScanResult>& results, const batch::Totals& totals,
                 const std::string& note) {
  const fs::path& dir = ctx.cfg.report_dir;
  fs::create_directories(dir);
  hgd::writeFileAtomically((dir / "summary.json").string(), batch::summaryJson(results, totals));
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
  const std::vector<Scan> all = listScans(cfg, skipped_entries);
  std::vector<Scan> scans;
  for (std::size_t i = 0; i < all.size(); ++i)
    if (static_cast<int>(i % static_cast<std::size_t>(cfg.shard_n)) == cfg.shard_k) scans.push_back(all[i]);
  if (all.empty() && root)
    std::fprintf(stderr, "hgdeform batch: warning: no PLY, PCD, OBJ, XYZ, OFF or STL file in %s%s\n",
                 cfg.input_dir.c_str(), cfg.recursive ? "" : " (subfolders are searched with --recursive)");
  if (root)
    for (const auto& e : skipped_entries)
      std::fprintf(stderr, "hgdeform batch: warning: skipped %s: %s\n", e.path.c_str(), e.why.c_str());

  std::string note;
  if (!cfg.report_dir.empty()) {
#ifdef HGD_HAVE_RENDER
    const std::string problem = hgd::displayProblem();
    ctx.thumbnails = problem.empty();
    if (!ctx.thumbnails)
      note = "No thumbnails (they need an X display): " + problem +
             ". Run the batch under xvfb-run -a (or with a display) to get "
             "before/after pictures.";
#else
    note = "No thumbnails: this hgdeform was built without PCL visualization (the hgdeform_render target).";
#endif
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
      writeReport(ctx, results, totals, note);
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

int runBatch(int argc, char** argv) {
  MpiSession mpi;
  const bool root = mpi.rank == 0;
  Config cfg;
  try {
    if (const int status = parseArgs(argc, argv, cfg, root); status >= 0) return status;
    checkDirectories(cfg);
  } catch (const UsageError& e) {
    if (root) std::fprintf(stderr, "hgdeform batch: %s\n(see 'hgdeform batch --help')\n", e.what());
    return 2;
  }
  try {
    return run(cfg, mpi);
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
