// hgdeform-bench's peers and shared gestures: the standard drag and the Armadillo's handles
// (used by the timing rows too), the frame against CGAL's ARAP (--arap) and the quality rows
// (local distortion of hgdeform and of ARAP run to convergence on the same mesh and move).
#pragma once

#include <Eigen/Core>
#include <chrono>
#include <nlohmann/json.hpp>
#include <string>

#include "hgdeform/deformer/deformer.h"
#include "hgdeform/io/geometry.h"

namespace hgdbench {

/// The Armadillo's handles: the feet fixed (the lowest 6% of its height), the top of the head
/// manipulated (the highest 8%).
hgd::Handles armadilloHandles(const hgd::Geometry& g);

/// A standard drag: the handle's first point pulled up by a tenth of the diagonal in `frames`
/// interactive frames, every frame solved to convergence and interpolated. Each frame's
/// wall time (solve + interpolation), and the solver's figures, through `each`.
template <class Each>
void standardDrag(hgd::Deformer& d, const hgd::Handles& h, int frames, Each each) {
  const Eigen::Vector3d from = d.deformedWorld(static_cast<std::size_t>(h.manipulated[0]));
  const Eigen::Vector3d to = from + Eigen::Vector3d(0, 0, 0.1 * d.diagonal());
  Eigen::Vector3d cur = from;
  for (int k = 1; k <= frames; ++k) {
    const Eigen::Vector3d next = from + (to - from) * (static_cast<double>(k) / frames);
    const auto f0 = std::chrono::steady_clock::now();
    const hgd::SolveStats st = d.drag(cur, next);
    each(k, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - f0).count(), st);
    cur = next;
  }
}

/// One frame of hgdeform against five iterations of CGAL's ARAP on the Armadillo at `armadillo`.
nlohmann::json runArap(const std::string& armadillo, int repeat);

/// The quality rows (the Armadillo when its file is there, and the procedural quadruped).
nlohmann::json runQuality(const std::string& armadillo);

}  // namespace hgdbench
