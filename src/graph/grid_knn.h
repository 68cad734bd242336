// Exact k-nearest-neighbour search on a uniform grid (internal).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace hgd {

/// For every point of `xyz` (n x 3, packed), its `kk` nearest points (itself included, at
/// distance 0), sorted by distance: indices into `idx` and squared distances into `d2`, both
/// n x kk. Exact: the search widens around a point until no closer point can lie outside it.
/// Meant for scanned surfaces (a few points per cell); returns false, writing nothing useful,
/// when the points are too unevenly spread for a grid (crowded cells, huge extents) or not
/// finite: the caller then uses a k-d tree.
///
/// Far outliers, whose neighbours lie beyond the shells a grid searches cell by cell, are
/// listed in `far` (point indices, ascending) with their rows unfinished, for the caller to
/// search otherwise; the rest of the cloud keeps the grid's results.
bool gridKnn(const float* xyz, std::size_t n, int kk, int* idx, float* d2, std::vector<std::uint32_t>& far);

}  // namespace hgd
