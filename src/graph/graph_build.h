// Building a symmetric CSR graph from an edge generator (internal; the graph stage's files).
#pragma once

#include <algorithm>
#include <vector>

#include "hgdeform/graph/neighbor_graph.h"

namespace hgd {

/// Builds a symmetric CSR graph from a directed edge generator, removing self-loops and repeats.
template <typename ForEachEdge>
inline NeighborGraph symmetricGraph(std::size_t n, ForEachEdge&& for_each_edge) {
  NeighborGraph g;
  g.offsets.assign(n + 1, 0);
  for_each_edge([&](int i, int j) {
    ++g.offsets[static_cast<std::size_t>(i) + 1];
    ++g.offsets[static_cast<std::size_t>(j) + 1];
  });
  for (std::size_t i = 0; i < n; ++i) g.offsets[i + 1] += g.offsets[i];
  g.adj.resize(static_cast<std::size_t>(g.offsets[n]));
  std::vector<int> fill(g.offsets.begin(), g.offsets.end() - 1);
  for_each_edge([&](int i, int j) {
    g.adj[static_cast<std::size_t>(fill[static_cast<std::size_t>(i)]++)] = j;
    g.adj[static_cast<std::size_t>(fill[static_cast<std::size_t>(j)]++)] = i;
  });
  // Sort and deduplicate each row, compacting in place.
  int write = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const int b = g.offsets[i], e = g.offsets[i + 1];
    std::sort(g.adj.begin() + b, g.adj.begin() + e);
    const int row_start = write;
    for (int m = b; m < e; ++m)
      if (m == b || g.adj[static_cast<std::size_t>(m)] != g.adj[static_cast<std::size_t>(m - 1)])
        g.adj[static_cast<std::size_t>(write++)] = g.adj[static_cast<std::size_t>(m)];
    g.offsets[i] = row_start;
  }
  g.offsets[n] = write;
  g.adj.resize(static_cast<std::size_t>(write));
  g.adj.shrink_to_fit();
  return g;
}

}  // namespace hgd
