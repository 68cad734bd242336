// Resolving scenario regions to points. The one region selector used everywhere.
#pragma once

#include <vector>

#include "hgdeform/geometry.h"
#include "hgdeform/scenario.h"

namespace hgd {

/// Handles as indices into Geometry::points (finite points).
struct Handles {
  std::vector<std::vector<int>> fixed;  ///< one list per fixed handle
  std::vector<int> manipulated;
  std::vector<std::vector<int>> joints;
};

/// The finite points a region selects, sorted. Index regions refer to file order; an index
/// past the end is an error, an index of a NaN point is skipped.
std::vector<int> selectRegion(const Region& region, const Geometry& geometry,
                              const std::string& scenario_name);

/// Resolves every region of a scenario. Throws ScenarioError naming the region (its JSON path)
/// when a region selects no point, or a point is both fixed and manipulated, or a joint
/// overlaps a handle.
Handles resolveHandles(const Scenario& scenario, const Geometry& geometry);

}  // namespace hgd
