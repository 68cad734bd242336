// The colour map used for scalar fields everywhere (files, pictures, the viewer).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>

namespace hgd {

/// Blue -> cyan -> yellow -> red for values in [0, 1] (clamped; NaN maps to blue).
inline Eigen::Vector3f colourMap(float v) {
  v = std::clamp(std::isfinite(v) ? v : 0.0f, 0.0f, 1.0f);
  const Eigen::Vector3f stops[4] = {
      {0.23f, 0.30f, 0.75f}, {0.35f, 0.80f, 0.90f}, {0.95f, 0.85f, 0.30f}, {0.71f, 0.02f, 0.15f}};
  const float x = v * 3.0f;
  const int k = std::min(2, static_cast<int>(x));
  const float t = x - static_cast<float>(k);
  return (1 - t) * stops[k] + t * stops[k + 1];
}

}  // namespace hgd
