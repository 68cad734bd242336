// The threshold of the stray rule (internal): the graph's strays (findOutliers, graph/strays.cpp)
// and the coarse level's (multires/coarse_strays.cpp) measure different distances, and both
// call a distance a stray's by this one rule.
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

namespace hgd {

/// The squared distance beyond which a point is a stray, from a sample of the typical squared
/// distances (`d2`, not empty; reordered here): 3 times the median distance, but never under the
/// sparsest 3%'s, as strays are few by definition (a scan whose density falls off with range
/// has no strays for that).
inline float strayLimit2(std::vector<float>& d2) {
  const auto at = [&](std::size_t k) {
    std::nth_element(d2.begin(), d2.begin() + static_cast<long>(k), d2.end());
    return d2[k];
  };
  return std::max(9.0f * at(d2.size() / 2), at(d2.size() * 97 / 100));
}

}  // namespace hgd
