// hgdeform batch: one scan's outcome, and the report files made of all of them (summary.json,
// summary.csv, index.html). Pure text building: the caller writes the files atomically.
#pragma once

#include <cstddef>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "hgdeform/app/runner.h"

namespace hgdcli {
namespace batch {

/// What happened to one scan.
struct ScanResult {
  std::string file;           ///< path relative to INPUT_DIR ('/' separators)
  std::string output;         ///< path relative to OUTPUT_DIR
  std::string scenario;       ///< the scenario file used
  bool own_scenario = false;  ///< a per-scan override (scan_017.json beside scan_017.pcd)
  std::string status;         ///< "ok", "failed" or "skipped"
  /// Why it was (re)done or skipped: "new", "output missing", "no record", "forced", "up to date",
  /// or any of "input changed", "scenario changed", "options changed", "tool version changed",
  /// "output changed" joined by ", ". "" when it failed before that was decided.
  std::string reason;
  std::string error;         ///< why it failed ("" otherwise)
  std::string warning;       ///< e.g. why there is no thumbnail ("" otherwise)
  std::string thumbnail;     ///< PNG relative to the report directory ("" = none)
  int rank = 0;              ///< MPI rank that processed it (0 without MPI)
  bool has_metrics = false;  ///< false for failed and skipped scans
  /// The deformation's figures, timings and notes (what it adjusted) as hgd::ScenarioRunner
  /// reported them; empty for failed and skipped scans. The report files show, and MPI ranks
  /// pass on (toJson, fromJson), only part of it.
  hgd::DeformReport report;
  double ms_wall = 0;  ///< the whole scan as seen by the batch (read, deform, write)
};

/// An entry of INPUT_DIR that was not taken as a scan although it might look like one: a FIFO,
/// a device, a dangling link, a link to a folder (not followed).
struct SkippedEntry {
  std::string path;  ///< relative to INPUT_DIR
  std::string why;
};

struct Totals {
  std::size_t scans = 0, ok = 0, failed = 0, skipped = 0, points = 0;
  double wall_s = 0;
  int jobs = 1, ranks = 1;
  std::string shard;  ///< "K/N" or ""
  std::vector<SkippedEntry> skipped_entries;
};

Totals countResults(const std::vector<ScanResult>& results);

nlohmann::json toJson(const ScanResult& r);
ScanResult fromJson(const nlohmann::json& j);

/// {"scans": [per-scan objects, sorted by file], "totals": {...}, "skipped_entries": [{path, why}],
/// "warnings": [what the whole run could not do, e.g. why there are no thumbnails]}
std::string summaryJson(const std::vector<ScanResult>& results, const Totals& totals,
                        const std::vector<std::string>& warnings = {});

/// Header file,status,error,points,clusters,iterations,handle_error,ms_build,ms_field,ms_sampling,
/// ms_clusters,ms_solve,ms_interpolation,ms_total,reason, then one row per scan (RFC 4180 quoting).
std::string summaryCsv(const std::vector<ScanResult>& results);

/// A page with one row per scan: status, figures, before/after thumbnail (or the error).
/// `note` (may be empty) is shown at the top, e.g. why there are no thumbnails.
std::string indexHtml(const std::vector<ScanResult>& results, const Totals& totals, const std::string& note);

/// One CSV field, quoted when it holds a comma, quote, CR or LF.
std::string csvField(const std::string& s);
std::string htmlEscape(const std::string& s);
/// Percent-encodes a relative path for an href/src attribute ('/' kept).
std::string urlPath(const std::string& s);

}  // namespace batch
}  // namespace hgdcli
