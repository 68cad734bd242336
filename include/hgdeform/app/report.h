// Outputs beside the shape: the field as a per-point scalar, and the JSON report of a deformation.
#pragma once

#include <string>
#include <vector>

#include "hgdeform/app/runner.h"
#include "hgdeform/io/geometry.h"
#include "hgdeform/io/shape.h"

namespace hgd {

/// Adds (or overwrites) a float field `name` holding `values` (one per finite point; NaN for
/// points that are not finite). With `colour`, also writes the values as a blue-to-red colour
/// map: red/green/blue uchar fields for PLY/OBJ, a packed `rgb` field for PCD.
void storeField(Shape& shape, const Geometry& geometry, const std::vector<float>& values,
                const std::string& name, bool colour = false);

/// The report as JSON text:
/// {"version", "points", "clusters", "iterations", "energy": {"detail", "prop", "manip", "length", "total"},
///  "ms": {"build", "field", "sampling", "clusters", "solve", "solve_per_iteration",
///         "interpolation", "total"}, ...}
std::string reportJson(const DeformReport& report);

/// Writes reportJson() to `path` atomically.
void writeReportJson(const std::string& path, const DeformReport& report);

/// One line for the terminal.
std::string summaryLine(const DeformReport& report);

/// Writes `text` to `path` through a temporary file and a rename. Throws IoError.
void writeTextAtomically(const std::string& path, const std::string& text);

}  // namespace hgd
