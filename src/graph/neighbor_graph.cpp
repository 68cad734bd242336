#include "hgdeform/graph/neighbor_graph.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <stdexcept>
#include <vector>

#include "graph/graph_build.h"
#include "util/parallel.h"

namespace hgd {

NeighborGraph unionGraph(const NeighborGraph& a, const NeighborGraph& b) {
  const std::size_t n = a.size();
  NeighborGraph g;
  g.offsets.assign(n + 1, 0);
  g.adj.reserve(a.adj.size() + b.adj.size());
  for (std::size_t i = 0; i < n; ++i) {
    const int *x = a.begin(i), *xe = a.end(i), *y = b.begin(i), *ye = b.end(i);
    while (x != xe || y != ye) {
      int v;
      if (y == ye || (x != xe && *x < *y))
        v = *x++;
      else if (x == xe || *y < *x)
        v = *y++;
      else {
        v = *x++;
        ++y;
      }
      g.adj.push_back(v);
    }
    g.offsets[i + 1] = static_cast<int>(g.adj.size());
  }
  return g;
}

NeighborGraph addEdges(const NeighborGraph& graph, const std::vector<std::pair<int, int>>& edges) {
  return unionGraph(graph, symmetricGraph(graph.size(), [&](auto&& emit) {
                      for (const auto& [a, b] : edges)
                        if (a != b) emit(a, b);
                    }));
}

NeighborGraph ringGraph(std::size_t n, const std::vector<pcl::Vertices>& faces) {
  return symmetricGraph(n, [&](auto&& emit) {
    for (const auto& f : faces) {
      const auto& v = f.vertices;
      for (std::size_t m = 0; m < v.size(); ++m) {
        const int a = static_cast<int>(v[m]), b = static_cast<int>(v[(m + 1) % v.size()]);
        if (a != b) emit(a, b);
      }
    }
  });
}

int connectedComponents(const NeighborGraph& graph, std::vector<int>& label) {
  // A concurrent union-find over the edges, in parallel (lock-free: a root is linked under a
  // smaller index by compare-and-swap, so every root ends as its piece's smallest index);
  // pieces are then numbered in the order of their smallest index.
  const std::size_t n = graph.size();
  const long long nn = static_cast<long long>(n);
  std::unique_ptr<std::atomic<int>[]> parent(new std::atomic<int>[n]);
#pragma omp parallel for schedule(static) if (nn > kParallelMin)
  for (long long i = 0; i < nn; ++i) parent[i].store(static_cast<int>(i), std::memory_order_relaxed);
  auto find = [&](int x) {
    for (;;) {
      int p = parent[x].load(std::memory_order_relaxed);
      if (p == x) return x;
      const int gp = parent[p].load(std::memory_order_relaxed);
      if (gp != p) parent[x].compare_exchange_weak(p, gp, std::memory_order_relaxed);  // halving
      x = gp;
    }
  };
#pragma omp parallel for schedule(dynamic, 4096) if (nn > kParallelMin)
  for (long long i = 0; i < nn; ++i)
    for (const int* j = graph.begin(static_cast<std::size_t>(i)); j != graph.end(static_cast<std::size_t>(i));
         ++j) {
      if (*j == i) continue;
      int a = find(static_cast<int>(i)), b = find(*j);
      while (a != b) {
        if (a < b) std::swap(a, b);  // link the larger root under the smaller
        int expected = a;
        if (parent[a].compare_exchange_strong(expected, b)) break;
        a = find(a);
        b = find(b);
      }
    }
  label.resize(n);
#pragma omp parallel for schedule(static) if (nn > kParallelMin)
  for (long long i = 0; i < nn; ++i) label[static_cast<std::size_t>(i)] = find(static_cast<int>(i));
  int count = 0;
  for (std::size_t i = 0; i < n; ++i)  // a root precedes the rest of its piece
    label[i] = label[i] == static_cast<int>(i) ? count++ : label[static_cast<std::size_t>(label[i])];
  return count;
}

}  // namespace hgd
