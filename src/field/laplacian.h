// The field's Dirichlet solve on a neighbour graph (internal: HarmonicField's, and the tests' and
// the multilevel solver's reference).
#pragma once

#include <vector>

#include "hgdeform/field/harmonic_field.h"
#include "hgdeform/graph/neighbor_graph.h"

namespace hgd {

/// Solves the Dirichlet problem on a graph: value[i] given for constrained points (mask[i] =
/// true), harmonic (uniform weights) elsewhere. Points in components without a constraint are
/// set to 0 and listed in `unreachable`. `piece`, when given, receives every point's connected
/// piece label.
void solveDirichlet(const NeighborGraph& graph, const std::vector<char>& constrained,
                    std::vector<double>& value, const FieldOptions& options, std::vector<int>& unreachable,
                    FieldTimings& timings, std::vector<int>* piece = nullptr);

}  // namespace hgd
