// Resolving scenario regions to points. The one region selector used everywhere.
#pragma once

#include <string>
#include <vector>

#include "hgdeform/app/scenario.h"
#include "hgdeform/cluster/handles.h"
#include "hgdeform/io/geometry.h"
#include "hgdeform/io/shape.h"

namespace hgd {

/// The finite points a region selects, sorted. Index regions refer to file order; an index
/// past the end is an error, an index of a NaN point is skipped. Field regions read the
/// shape's per-point fields: `geometry` must have been extracted from `shape`. Throws
/// ScenarioError naming the region (its JSON path) when it selects no point, or when a field
/// region names a field the shape does not have (the message lists the shape's fields).
std::vector<int> selectRegion(const Region& region, const Geometry& geometry, const Shape& shape,
                              const std::string& scenario_name);

/// The same without the shape: sphere, box, cylinder and index regions. A field region is a
/// ScenarioError (it needs the shape's fields: use the overload above).
std::vector<int> selectRegion(const Region& region, const Geometry& geometry,
                              const std::string& scenario_name);

/// Resolves every region of a scenario. Throws ScenarioError naming the region (its JSON path)
/// when a region selects no point, or a point is both fixed and manipulated, or a joint
/// overlaps a handle. `geometry` must have been extracted from `shape`.
Handles resolveHandles(const Scenario& scenario, const Geometry& geometry, const Shape& shape);

/// The same without the shape: field regions are a ScenarioError (see selectRegion).
Handles resolveHandles(const Scenario& scenario, const Geometry& geometry);

}  // namespace hgd
