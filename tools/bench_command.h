// hgdeform-bench's whole-command row: `hgdeform deform` (the CLI beside the bench) on a shape
// written as a binary PLY, against PCL reading and writing the same file, in the same run.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "hgdeform/io/shape.h"

namespace hgdbench {

/// Writes `shape` to a temporary binary PLY and `scenario` (JSON text) beside it; then, `repeat`
/// times alternating: `hgdeform deform` on them (a child process: its wall time and peak RSS)
/// and PCL's PLYReader + PLYWriter (binary) on the same file. Medians: {"points",
/// "command_ms", "command_peak_mb", "pcl_read_ms", "pcl_write_ms", "bytes_per_point"}; an
/// object with "left_out" when the CLI is not beside the bench.
nlohmann::json commandReference(const hgd::Shape& shape, const std::string& scenario, int repeat);

}  // namespace hgdbench
