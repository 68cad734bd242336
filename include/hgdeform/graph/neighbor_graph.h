// A symmetric neighbour graph in compressed rows and its operations (the graph stage).
#pragma once

#include <pcl/Vertices.h>

#include <cstddef>
#include <utility>
#include <vector>

namespace hgd {

/// A symmetric graph in compressed rows (CSR): neighbours of i are adj[offsets[i] .. offsets[i+1]).
struct NeighborGraph {
  std::vector<int> offsets{0};
  std::vector<int> adj;
  std::size_t size() const { return offsets.size() - 1; }
  int degree(std::size_t i) const { return offsets[i + 1] - offsets[i]; }
  const int* begin(std::size_t i) const { return adj.data() + offsets[i]; }
  const int* end(std::size_t i) const { return adj.data() + offsets[i + 1]; }
};

/// Every pair of either graph (same size; rows sorted, as every graph here has them).
NeighborGraph unionGraph(const NeighborGraph& a, const NeighborGraph& b);

/// `graph` with `edges` added (both directions; repeats and self-loops ignored).
NeighborGraph addEdges(const NeighborGraph& graph, const std::vector<std::pair<int, int>>& edges);

/// The 1-ring graph of a mesh (polygon edges).
NeighborGraph ringGraph(std::size_t n, const std::vector<pcl::Vertices>& faces);

/// Connected-component label of every vertex (0..count-1, numbered in the order of each
/// piece's smallest vertex), found in parallel; returns the count.
int connectedComponents(const NeighborGraph& graph, std::vector<int>& label);

}  // namespace hgd
