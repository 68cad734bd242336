// One named phase of a build (its kNN, normals, field solve, prolongation ...), as
// BuildTimings::phases lists them: what the benchmark's per-phase thread scaling is made of.
#pragma once

#include <string>

namespace hgd {

struct BuildPhase {
  std::string name;  ///< e.g. "graph.knn", "multires.coarsen", "solver.setup"
  double ms = 0;
};

}  // namespace hgd
