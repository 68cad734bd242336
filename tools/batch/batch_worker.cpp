// hgdeform batch: one scan. Is its output up to date (its provenance record)? If not: read,
// deform (hgd::ScenarioRunner), write atomically, record, and draw its thumbnail for the report.
#include <chrono>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <new>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "batch_internal.h"
#include "batch_provenance.h"
#include "hgdeform/app/memory.h"
#include "hgdeform/app/regions.h"
#include "hgdeform/app/runner.h"
#include "hgdeform/app/scenario.h"
#include "hgdeform/app/stream.h"
#include "hgdeform/io/geometry.h"
#include "hgdeform/io/io.h"
#include "hgdeform/io/records.h"
#ifdef HGD_HAVE_RENDER
#include "thumbnails.h"
#endif

namespace hgdcli {
namespace batch {

namespace {

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
/// Hashes the input (into `input_hash`) only when its size is the recorded one but its times
/// (mtime, ctime) or inode are not; `refresh` then says that only the record's input state is
/// out of date. An output whose size, ctime or inode is not the recorded one has changed.
std::string whyRedo(const Scan& s, const batch::FileState& input, const std::optional<batch::Provenance>& rec,
                    const std::string& scenario_hash, const nlohmann::json& options, std::string& input_hash,
                    bool& refresh) {
  const batch::FileState out = batch::fileState(s.output.string());
  if (!out.exists) return rec ? "output missing" : "new";
  if (!rec) return "no record";
  std::vector<std::string> why;
  if (!rec->invalid.empty() || rec->input != s.rel || rec->input_size != input.size) {
    why.push_back("input changed");
  } else if (!batch::sameInput(*rec, input)) {
    input_hash = batch::hashFile(s.input.string());
    if (input_hash != rec->input_hash)
      why.push_back("input changed");
    else
      refresh = batch::fileState(s.input.string()).unchangedFrom(input);
  }
  if (scenario_hash != rec->scenario_hash) why.push_back("scenario changed");
  if (options != rec->options) why.push_back("options changed");
  if (batch::toolVersion() != rec->tool) why.push_back("tool version changed");
  if (!batch::sameOutput(*rec, out)) why.push_back("output changed");
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
/// The scan before (its own colours) and after (coloured by each point's displacement, with a
/// scale), the handles marked in both, seen from the side where the motion shows best.
void renderThumbnail(const hgd::Shape& before, const hgd::Shape& after, const hgd::Geometry& rest,
                     const hgd::Handles& handles, const fs::path& png) {
  fs::create_directories(png.parent_path());
  std::vector<int> fixed, manipulated;
  for (const auto& f : handles.fixed)
    for (const int i : f) fixed.push_back(rest.raw_index[static_cast<std::size_t>(i)]);
  for (const int i : handles.manipulated) manipulated.push_back(rest.raw_index[static_cast<std::size_t>(i)]);
  const std::string file = png.string();
  drawThumbnail(ThumbnailRequest{&before, &after, &fixed, &manipulated, file.c_str()});
}
#endif

/// Thumbnail of a deformed scan, or of an up-to-date one (from its input and existing output).
/// A scan's warnings are one line, joined by "; ".
void appendWarning(std::string& warning, const std::string& more) {
  warning += (warning.empty() ? "" : "; ") + more;
}

/// Returns the name relative to the report directory, "" (and a warning) on failure. `run`: the
/// scan just deformed; else (an up-to-date scan) its input and output are read, and the handles
/// resolved from `scenario` (left unmarked when they cannot be).
std::string thumbnail(const Context& ctx, const Scan& s, const hgd::ScenarioRunner* run,
                      const hgd::Shape* after, const hgd::Scenario& scenario, std::string& warning) {
#ifdef HGD_HAVE_RENDER
  const std::string name = thumbnailName(s.rel);
  const fs::path png = ctx.cfg.report_dir / name;
  try {
    if (run && after) {
      renderThumbnail(run->shape(), *after, run->geometry(), run->handles(), png);
    } else {
      std::error_code e1, e2;
      const auto t_png = fs::last_write_time(png, e1);
      const auto t_out = fs::last_write_time(s.output, e2);
      if (e1 || e2 || t_png < t_out) {
        const hgd::Shape in = hgd::readShape(s.input.string());
        const hgd::Shape out = hgd::readShape(s.output.string());
        const hgd::Geometry g = hgd::extractGeometry(in);
        hgd::Handles handles;
        try {
          handles = hgd::resolveHandles(scenario, g, in);
        } catch (const std::exception&) {  // drawn without marks
        }
        renderThumbnail(in, out, g, handles, png);
      }
    }
    return name;
  } catch (const std::exception& e) {
    appendWarning(warning, std::string("no thumbnail: ") + e.what());
    return "";
  }
#else
  (void)ctx, (void)s, (void)run, (void)after, (void)scenario, (void)warning;
  return "";
#endif
}

/// Whether the scan is one a run holds in memory (a streamed one is not drawn).
/// The memory check of a scan (hgd::checkDeformMemory at the build the scenario asks for):
/// throws IoError with the reason when it does not fit.
void checkScanMemory(const Scan& s, const Context& ctx, const hgd::Scenario& scenario) {
  hgd::checkDeformMemory(s.input.string(), ctx.cfg.memory,
                         scenario.full_resolution.value_or(false) ? 0 : hgd::DeformOptions().multires_above);
}

bool fitsInMemory(const Scan& s, const Context& ctx, const hgd::Scenario& scenario) {
  try {
    checkScanMemory(s, ctx, scenario);
    return true;
  } catch (const hgd::IoError&) {
    return false;
  }
}

constexpr const char* kNoStreamedThumbnail =
    "no thumbnail: a streamed scan is not drawn (it does not fit in memory)";

}  // namespace

std::string thumbnailName(const std::string& rel) {
  return "thumbs/" + rel + ".png";
}

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
      if (refresh) {  // touched, same bytes: remember its new state so as not to hash it again
        batch::Provenance p = *rec;
        batch::recordInput(p, in_before);
        try {
          hgd::writeFileAtomically(record_path, batch::recordText(p));
        } catch (const std::exception& e) {
          appendWarning(r.warning, std::string("provenance record not updated: ") + e.what());
        }
      }
      if (ctx.thumbnails && fitsInMemory(s, ctx, scenario))
        r.thumbnail = thumbnail(ctx, s, nullptr, nullptr, scenario, r.warning);
      else if (ctx.thumbnails)
        appendWarning(r.warning, kNoStreamedThumbnail);
      r.ms_wall = msSince(t0);
      return r;
    }
    // Hash before reading: a change from here to the end shows in the input's stat below.
    if (input_hash.empty()) {
      const bool recorded =
          rec && rec->invalid.empty() && rec->input == s.rel && batch::sameInput(*rec, in_before);
      input_hash = recorded ? rec->input_hash : batch::hashFile(s.input.string());
    }
    // A file whose content is of no format (a link to a text file, a log) is said to be so, not
    // read by its name: the reader's precise error would quote its text into stderr and the
    // summary (the first line of a file that is no scan).
    hgd::sniffFormat(s.input.string());
    // A scan that does not fit in memory is streamed where its file allows (a binary PLY or PCD
    // built on a coarse level), as `hgdeform deform` does; the reason the memory check gave stands
    // otherwise.
    const bool full = scenario.full_resolution.value_or(false);
    std::optional<hgd::IoError> too_big;
    try {
      checkScanMemory(s, ctx, scenario);
    } catch (const hgd::IoError& e) {
      if (full || !hgd::canStream(s.input.string(), s.output.string())) throw;
      too_big = e;
    }
    std::optional<hgd::ScenarioRunner> run;
    if (!too_big) {
      run.emplace(hgd::ScenarioRunner::read(s.input.string()));
      run->setScenario(scenario);
      run->applyMoves();
    }
    fs::create_directories(s.output.parent_path());
    std::error_code gone;
    fs::remove(record_path, gone);  // from here until the new record, the output is unrecorded
    hgd::DeformReport rep;
    if (too_big) {
      rep = hgd::streamDeform(s.input.string(), scenario, hgd::RunOptions(), s.output.string());
      rep.notes.insert(rep.notes.begin(), std::string("streamed: ") + too_big->what());
    } else {
      // Without a thumbnail (which draws the rest shape beside the deformed one), the shape is
      // held once: deformed in place to be written.
      if (ctx.thumbnails)
        run->write(s.output.string(), {}, {s.scenario.string()});
      else
        run->writeAndRelease(s.output.string(), {}, {s.scenario.string()});
      rep = run->report();
    }
    testHook(s.rel);
    batch::Provenance p;
    p.input = s.rel;
    batch::recordInput(p, in_before);
    p.input_hash = input_hash;
    p.scenario = s.scenario.string();
    p.scenario_hash = scenario_hash;
    p.options = options;
    p.tool = batch::toolVersion();
    batch::recordOutput(p, batch::fileState(s.output.string()));
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
    r.report = rep;
    for (const auto& w : rep.warnings) appendWarning(r.warning, w);
    if (ctx.thumbnails && run) {
      const hgd::Shape after = run->deformedShape();
      r.thumbnail = thumbnail(ctx, s, &*run, &after, scenario, r.warning);
    } else if (ctx.thumbnails) {
      appendWarning(r.warning, kNoStreamedThumbnail);
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

}  // namespace batch
}  // namespace hgdcli
