// Splitting work into contiguous blocks, one per thread (internal).
#pragma once

#ifdef _OPENMP
#include <omp.h>
#endif

#include <algorithm>
#include <cstddef>
#include <exception>
#include <vector>

namespace hgd {

/// Below this many items a loop runs on one thread: waking a team costs more than it saves
/// (and on a loaded machine a sleeping thread can take a whole time slice to join).
constexpr long long kParallelMin = 20000;
/// The same for loops whose items cost a microsecond or more each (a k-nearest query, a
/// neighbourhood's PCA): 2,048 of them already pay for the team. A mid-sized shape's coarse
/// level (20,000 points at 200,000) searched its neighbours on one thread under kParallelMin.
constexpr long long kParallelMinCostly = 2048;

/// Iterations per chunk of a loop whose chunks are handed out as threads come free
/// (schedule(dynamic, ...)), so that a thread slowed by something else on its core (another
/// process, a busy sibling hyperthread, a slower core) takes fewer: for items of a few
/// nanoseconds (a pass over every point: some 250 chunks at 4M points), and for items that cost
/// a neighbourhood's work (a coarse level of 65,536 points: 256 chunks). Each item is computed
/// alone, so the results do not depend on who ran it.
constexpr int kDynamicChunk = 16384;
constexpr int kDynamicChunkCostly = 256;

/// One block per thread when n is large enough to share (more than `min` items: kParallelMin,
/// kParallelMinCostly for items that cost a microsecond or so), else one.
inline int blockCount([[maybe_unused]] long long n, [[maybe_unused]] long long min = kParallelMin) {
  int threads = 1;
#ifdef _OPENMP
  if (n > min) threads = omp_get_max_threads();
#endif
  return threads;
}

/// Where block b of [0, n) split into `blocks` begins (forBlocks' split; b = blocks: n).
inline long long blockStart(long long n, int blocks, int b) {
  return n * b / blocks;
}

/// Splits [0, n) into `blocks` contiguous blocks and runs body(begin, end, block) on each
/// exactly once, in parallel (even if the runtime grants fewer threads than asked).
template <typename Body>
void forBlocks(long long n, int blocks, Body&& body) {
#pragma omp parallel for schedule(static, 1) num_threads(blocks) if (blocks > 1)
  for (int t = 0; t < blocks; ++t)
    body(static_cast<int>(blockStart(n, blocks, t)), static_cast<int>(blockStart(n, blocks, t + 1)), t);
}

/// Blocks for forChunks: eight per thread (at most 64: a radix sort keeps a table of counts per
/// block) when n is large enough to share (kParallelMin), else one.
inline int chunkCount([[maybe_unused]] long long n) {
  int chunks = 1;
#ifdef _OPENMP
  if (n > kParallelMin && omp_get_max_threads() > 1) chunks = std::min(64, 8 * omp_get_max_threads());
#endif
  return chunks;
}

/// The chunk of a loop of n cheap items under schedule(dynamic, ...): kDynamicChunk, smaller
/// where that would leave fewer than eight chunks a thread (at least 1,024 items).
inline int dynamicChunk([[maybe_unused]] long long n) {
  int threads = 1;
#ifdef _OPENMP
  threads = omp_get_max_threads();
#endif
  const long long per = n / (8LL * threads);
  return static_cast<int>(std::max(1024LL, std::min(static_cast<long long>(kDynamicChunk), per)));
}

/// forBlocks, but the blocks (chunkCount's: more than threads) are handed out as threads come
/// free: a thread slowed by something else on its core (another process, a busy sibling
/// hyperthread, a slower core) takes fewer. The blocks are the same whoever runs them.
template <typename Body>
void forChunks(long long n, int chunks, Body&& body) {
#pragma omp parallel for schedule(dynamic, 1) if (chunks > 1)
  for (int c = 0; c < chunks; ++c)
    body(static_cast<int>(blockStart(n, chunks, c)), static_cast<int>(blockStart(n, chunks, c + 1)), c);
}

/// The indices i in [0, n) for which test(i) holds, ascending, tested on every thread. A block's
/// exception (running out of memory) is rethrown here, not lost in a worker.
template <typename Test>
std::vector<int> indicesWhere(long long n, Test&& test) {
  const int blocks = blockCount(n);
  std::vector<std::vector<int>> part(static_cast<std::size_t>(blocks));
  std::vector<std::exception_ptr> failed(static_cast<std::size_t>(blocks));
  forBlocks(n, blocks, [&](int begin, int end, int b) {
    try {
      for (int i = begin; i < end; ++i)
        if (test(static_cast<std::size_t>(i))) part[static_cast<std::size_t>(b)].push_back(i);
    } catch (...) {
      failed[static_cast<std::size_t>(b)] = std::current_exception();
    }
  });
  for (const auto& e : failed)
    if (e) std::rethrow_exception(e);
  std::vector<int> out;
  for (const auto& p : part) out.insert(out.end(), p.begin(), p.end());
  return out;
}

}  // namespace hgd
