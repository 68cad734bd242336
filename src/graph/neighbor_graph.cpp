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
#include "util/uninit.h"

namespace hgd {

namespace {

// The union of two sorted rows, [x, xe) and [y, ye): out(v) for each entry, ascending, once.
template <typename Out>
void mergeRows(const int* x, const int* xe, const int* y, const int* ye, Out&& out) {
  while (x != xe || y != ye) {
    if (y == ye || (x != xe && *x < *y))
      out(*x++);
    else if (x == xe || *y < *x)
      out(*y++);
    else {
      out(*x++);
      ++y;
    }
  }
}

// offsets[i + 1] holds row i's length: made the rows' starts (serial: a pass over the rows).
void rowStarts(std::vector<int>& offsets) {
  for (std::size_t i = 1; i < offsets.size(); ++i) offsets[i] += offsets[i - 1];
}

// The graph of `edges`, both directions, self-loops and repeats dropped, rows sorted; on every
// thread: each block of the edges counts its entries per row and writes them where the blocks
// before it leave off, and each row is then sorted and its repeats dropped on its own, so the
// result does not depend on the order of `edges` or the blocks. A block's counts span every row:
// blocks are capped at one per n edges, so that a few edges on a large graph (a mesh's dropped
// edges) count on one thread, in memory of the graph's size as before.
NeighborGraph edgeGraph(std::size_t n, const std::vector<std::pair<int, int>>& edges) {
  const long long m = static_cast<long long>(edges.size());
  const long long nn = static_cast<long long>(n);
  const int blocks = static_cast<int>(
      std::max<long long>(1, std::min<long long>(blockCount(m), m / std::max<long long>(1, nn))));
  // (Allocated here, so that running out of memory throws to the caller, not in a worker.)
  UninitVector<int> counts(static_cast<std::size_t>(blocks) * n);
  std::vector<int*> count(static_cast<std::size_t>(blocks));
  for (int b = 0; b < blocks; ++b)
    count[static_cast<std::size_t>(b)] = counts.data() + static_cast<std::size_t>(b) * n;
  forBlocks(m, blocks, [&](int begin, int end, int b) {
    int* const c = count[static_cast<std::size_t>(b)];
    std::fill(c, c + n, 0);
    for (int e = begin; e < end; ++e) {
      const auto [x, y] = edges[static_cast<std::size_t>(e)];
      if (x == y) continue;
      ++c[static_cast<std::size_t>(x)];
      ++c[static_cast<std::size_t>(y)];
    }
  });
  NeighborGraph g;
  g.offsets.assign(n + 1, 0);
#pragma omp parallel for schedule(static) if (nn > kParallelMin && blocks > 1)
  for (long long i = 0; i < nn; ++i) {
    int total = 0;
    for (const int* c : count) total += c[static_cast<std::size_t>(i)];
    g.offsets[static_cast<std::size_t>(i) + 1] = total;
  }
  rowStarts(g.offsets);
  // Where each block writes in each row: the row's start, then the blocks before it.
#pragma omp parallel for schedule(static) if (nn > kParallelMin && blocks > 1)
  for (long long i = 0; i < nn; ++i) {
    int at = g.offsets[static_cast<std::size_t>(i)];
    for (int* c : count) {
      const int k = c[static_cast<std::size_t>(i)];
      c[static_cast<std::size_t>(i)] = at;
      at += k;
    }
  }
  std::vector<int> adj(static_cast<std::size_t>(g.offsets[n]));
  forBlocks(m, blocks, [&](int begin, int end, int b) {
    int* const at = count[static_cast<std::size_t>(b)];
    for (int e = begin; e < end; ++e) {
      const auto [x, y] = edges[static_cast<std::size_t>(e)];
      if (x == y) continue;
      adj[static_cast<std::size_t>(at[static_cast<std::size_t>(x)]++)] = y;
      adj[static_cast<std::size_t>(at[static_cast<std::size_t>(y)]++)] = x;
    }
  });
  counts = {};
  // Each row sorted, its repeats dropped (its length in kept), then the rows packed.
  std::vector<int> kept(n + 1, 0);
#pragma omp parallel for schedule(dynamic, kDynamicChunkCostly) if (m > kParallelMin)
  for (long long i = 0; i < nn; ++i) {
    const auto row = adj.begin() + g.offsets[static_cast<std::size_t>(i)];
    const auto row_end = adj.begin() + g.offsets[static_cast<std::size_t>(i) + 1];
    std::sort(row, row_end);
    kept[static_cast<std::size_t>(i) + 1] = static_cast<int>(std::unique(row, row_end) - row);
  }
  rowStarts(kept);
  g.adj.resize(static_cast<std::size_t>(kept[n]));
#pragma omp parallel for schedule(dynamic, kDynamicChunkCostly) if (m > kParallelMin)
  for (long long i = 0; i < nn; ++i) {
    const auto r = static_cast<std::size_t>(i);
    std::copy(adj.begin() + g.offsets[r], adj.begin() + g.offsets[r] + (kept[r + 1] - kept[r]),
              g.adj.begin() + kept[r]);
  }
  g.offsets.swap(kept);
  return g;
}

}  // namespace

NeighborGraph unionGraph(const NeighborGraph& a, const NeighborGraph& b) {
  // On every thread: each row's length, then the rows.
  const std::size_t n = a.size();
  const long long nn = static_cast<long long>(n);
  const bool parallel =
      nn > kParallelMin || static_cast<long long>(a.adj.size() + b.adj.size()) > kParallelMin;
  NeighborGraph g;
  g.offsets.assign(n + 1, 0);
#pragma omp parallel for schedule(dynamic, kDynamicChunkCostly) if (parallel)
  for (long long ii = 0; ii < nn; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    int length = 0;
    mergeRows(a.begin(i), a.end(i), b.begin(i), b.end(i), [&length](int) { ++length; });
    g.offsets[i + 1] = length;
  }
  rowStarts(g.offsets);
  g.adj.resize(static_cast<std::size_t>(g.offsets[n]));
#pragma omp parallel for schedule(dynamic, kDynamicChunkCostly) if (parallel)
  for (long long ii = 0; ii < nn; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    int* out = g.adj.data() + g.offsets[i];
    mergeRows(a.begin(i), a.end(i), b.begin(i), b.end(i), [&out](int v) { *out++ = v; });
  }
  return g;
}

NeighborGraph addEdges(const NeighborGraph& graph, const std::vector<std::pair<int, int>>& edges) {
  NeighborGraph added = edgeGraph(graph.size(), edges);
  if (graph.adj.empty()) return added;
  return unionGraph(graph, added);
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
