// hgdeform-bench's whole-command row: `hgdeform deform` (the CLI beside the bench) on a shape
// written as a binary PLY, against PCL reading and writing the same file, in the same run.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "hgdeform/io/shape.h"

namespace hgdbench {

/// The bench's first argument that makes it PCL's reference instead (pclIoReference).
inline constexpr const char* kPclIoFlag = "--pcl-io-reference";

/// Reads `in` with PCL's PLYReader and writes it with PLYWriter (binary) to `out`, and prints
/// the two times in ms on stdout: what the whole-command row compares with, measured in a fresh
/// process as a PCL program runs. 0, or 1 when PCL fails.
int pclIoReference(const char* in, const char* out);

/// Writes `shape` to a temporary binary PLY and `scenario` (JSON text) beside it; then, `repeat`
/// times alternating, each in a fresh process in the user's environment (as a user runs them,
/// not the bench's: hugePageMalloc): `hgdeform deform` on them (its wall time and peak RSS) and
/// PCL's PLYReader + PLYWriter (binary) on the same file (their own times). Medians: {"points",
/// "command_ms", "command_peak_mb", "pcl_read_ms", "pcl_write_ms", "bytes_per_point"}; an
/// object with "left_out" when the CLI is not beside the bench.
nlohmann::json commandReference(const hgd::Shape& shape, const std::string& scenario, int repeat);

/// The streaming row at `points` (about: a square grid): hgdeform-make-scans' bumpy plane and
/// scenario written a row at a time as a binary PLY in a temporary folder, then `repeat` times
/// alternating, each in a fresh process: a copy of the file through the page cache, `hgdeform
/// deform --stream` (wall time, peak from its report) and, where the machine holds the cloud
/// twice, PCL's read + write. Medians: {"points", "file_mb", "generate_ms", "command_ms",
/// "command_peak_mb", "copy_ms", "command_over_copy", "pcl_read_ms", "pcl_write_ms"} ("left_out"
/// or "pcl_left_out" when a part could not run).
nlohmann::json streamReference(long points, int repeat);
/// Prints streamReference's row.
void printStreamRow(const nlohmann::json& row);

}  // namespace hgdbench
