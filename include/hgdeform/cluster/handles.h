// The handles of a deformation as point indices: what every stage after the field takes (the
// scenario's regions resolve to them, app/regions.h).
#pragma once

#include <vector>

namespace hgd {

/// Handles as indices into Geometry::points (finite points).
struct Handles {
  std::vector<std::vector<int>> fixed;  ///< one list per fixed handle
  std::vector<int> manipulated;
  std::vector<std::vector<int>> joints;
};

}  // namespace hgd
