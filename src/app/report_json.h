// The deform report as JSON objects, for the tools that carry reports further: `hgdeform batch`
// keeps each scan's figures in summary.json and passes them between MPI ranks. One serialiser:
// reportJson() (report.h) is reportToJson()'s text.
// For the library and its tools: not installed (it includes nlohmann/json.hpp, which the
// installed package does not require).
#pragma once

#include <nlohmann/json.hpp>

#include "hgdeform/app/runner.h"

namespace hgd {

/// The whole report: reportFigures() and the rest (notes, warnings, pieces, surface, energy,
/// the stages' timings).
nlohmann::json reportToJson(const DeformReport& report);

/// The figures a summary of many runs keeps: points, clusters, iterations, frames,
/// handle_error and "ms": {read, build, field, sampling, clusters, solve, interpolation, write,
/// total}.
nlohmann::json reportFigures(const DeformReport& report);

/// Reads reportFigures() back into `report` (its other members are left as they are). Throws
/// nlohmann::json::exception when a figure is missing or of another type.
void readReportFigures(const nlohmann::json& figures, DeformReport& report);

}  // namespace hgd
