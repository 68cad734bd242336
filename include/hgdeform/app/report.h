// The report of a deformation, as JSON (the tools' JSON objects are internal: src/app/report_json.h) and as
// one line for the terminal. The field stored as a per-point scalar is storeField() in fields.h.
#pragma once

#include <string>
#include <vector>

#include "hgdeform/app/runner.h"

namespace hgd {

/// The report as JSON text:
/// {"version", "points", "clusters", "iterations", "energy": {"detail", "prop", "manip", "length", "total"},
///  "ms": {"build", "field", "sampling", "clusters", "solve", "solve_per_iteration",
///         "interpolation", "total"}, ...}
std::string reportJson(const DeformReport& report);

/// Writes reportJson() to `path` atomically.
void writeReportJson(const std::string& path, const DeformReport& report);

/// One line for the terminal.
std::string summaryLine(const DeformReport& report);

/// What a report says of a deformer's build and moves (every front end's): its timings,
/// clusters, notes, pieces and their warnings, each move's figures and warning, the energy.
/// `moves` and `results`: the moves applied and what each did; `isovalues`: the run's.
void describeRun(const Deformer& deformer, const std::vector<Move>& moves,
                 const std::vector<MoveResult>& results, int isovalues, DeformReport& report);

}  // namespace hgd
