// Whether a shape fits in memory before it is read: an estimate of what deforming it takes,
// from its header alone, against the memory the machine has (or a cap the user sets). A scan
// larger than memory is refused at once with the reason, not read until the system kills the
// process.
#pragma once

#include <cstdint>
#include <string>

#include "hgdeform/io/io.h"

namespace hgd {

/// The memory the system can give a new process without swapping (Linux: MemAvailable of
/// /proc/meminfo), in bytes; 0 when it cannot be read.
std::uint64_t availableMemory();

/// About what `hgdeform deform` holds at its peak for a shape of this size, in bytes: the
/// points' records as read plus the build's per-point data (the multi-resolution build's, or
/// the full-resolution graph's when `full_resolution`), the faces, and the program's base.
/// Measured on procedural scans and meshes (tests/test_memory.cpp holds it within 0.7x-1.5x of
/// the measured peak).
std::uint64_t deformMemoryEstimate(const ShapeSize& size, bool full_resolution);

/// Parses a byte count as a user writes one: "1500000000", "1.5G", "800M", "64k" (K, M, G, T:
/// powers of 1024; a trailing B or iB is allowed). False for anything else, and for 0.
bool parseByteCount(const std::string& text, std::uint64_t* bytes);

/// "1.5 GB" (powers of 1024, three significant digits).
std::string byteText(std::uint64_t bytes);

/// Throws IoError naming `path` when deforming it would need more than `cap` bytes (0: the
/// available memory; when that is unknown, nothing is checked). `multires_above`: the point
/// count above which the build runs on a coarse level (DeformOptions::multires_above; 0 keeps
/// every point in the graph). Reads the header only.
void checkDeformMemory(const std::string& path, std::uint64_t cap, std::size_t multires_above);

}  // namespace hgd
