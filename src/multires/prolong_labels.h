// The route prolongInterpolation() replaced (internal; the tests' reference): per-point labels
// prolonged first, the table built from them after.
#pragma once

#include <vector>

#include "hgdeform/cluster/clustering.h"
#include "hgdeform/multires/multires.h"

namespace hgd {

/// The clustering of every shape point from the coarse level's: member and sample indices
/// become shape indices; each point takes its anchor's two clusters, and its blend factor from
/// its own φ where the anchor's came from φ (else the anchor's).
Clustering prolongClustering(Clustering coarse, const CoarseLevel& level,
                             const std::vector<float>& coarse_phi, const std::vector<float>& phi);

}  // namespace hgd
