// Stable sort of integer keys carrying an index payload (internal).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "util/parallel.h"

namespace hgd {

/// Sorts `keys` ascending and permutes `payload` (same length) alongside; stable. LSD radix
/// sort with `digit_bits` per pass, as many passes as `max_key` (no key larger) needs, on every
/// thread: each block of the keys counts its digits, and scatters them (in order) to where the
/// blocks before it leave off. A pass whose digit is the same for every key is skipped.
template <typename Key, typename KeyAlloc, typename PayloadAlloc>
void radixSort(std::vector<Key, KeyAlloc>& keys, std::vector<std::uint32_t, PayloadAlloc>& payload,
               Key max_key, int digit_bits) {
  const std::size_t n = keys.size();
  const std::size_t buckets = std::size_t{1} << digit_bits;
  const Key mask = static_cast<Key>(buckets - 1);
  const int blocks = chunkCount(static_cast<long long>(n));
  // The second buffers are left uninitialised (a serial pass zeroing them cost more than a pass
  // of the sort at 4M points): the first scatter writes them, on every thread.
  std::unique_ptr<Key[]> tmp_keys(new Key[n]);
  std::unique_ptr<std::uint32_t[]> tmp_payload(new std::uint32_t[n]);
  Key* from_keys = keys.data();
  std::uint32_t* from_payload = payload.data();
  Key* to_keys = tmp_keys.get();
  std::uint32_t* to_payload = tmp_payload.get();
  std::vector<std::size_t> count(buckets * static_cast<std::size_t>(blocks));
  for (int shift = 0; shift < static_cast<int>(8 * sizeof(Key)) && (max_key >> shift) != 0;
       shift += digit_bits) {
    forChunks(static_cast<long long>(n), blocks, [&](int begin, int end, int b) {
      std::size_t* c = count.data() + static_cast<std::size_t>(b) * buckets;
      std::fill(c, c + buckets, std::size_t{0});
      for (int i = begin; i < end; ++i)
        ++c[static_cast<std::size_t>((from_keys[static_cast<std::size_t>(i)] >> shift) & mask)];
    });
    // Where each (digit, block) starts: digits in order, and within a digit the blocks in order.
    std::size_t sum = 0;
    bool one_digit = false;
    for (std::size_t d = 0; d < buckets; ++d) {
      std::size_t digit_total = 0;
      for (int b = 0; b < blocks; ++b) {
        std::size_t& slot = count[static_cast<std::size_t>(b) * buckets + d];
        const std::size_t v = slot;
        slot = sum;
        sum += v;
        digit_total += v;
      }
      one_digit = one_digit || digit_total == n;
    }
    if (one_digit) continue;  // every key has this digit: the pass would copy them in order
    forChunks(static_cast<long long>(n), blocks, [&](int begin, int end, int b) {
      std::size_t* c = count.data() + static_cast<std::size_t>(b) * buckets;
      for (int i = begin; i < end; ++i) {
        const auto k = static_cast<std::size_t>(i);
        const std::size_t dst = c[static_cast<std::size_t>((from_keys[k] >> shift) & mask)]++;
        to_keys[dst] = from_keys[k];
        to_payload[dst] = from_payload[k];
      }
    });
    std::swap(from_keys, to_keys);
    std::swap(from_payload, to_payload);
  }
  if (from_keys != keys.data()) {  // an odd number of passes: the result is in the buffers
    forChunks(static_cast<long long>(n), blocks, [&](int begin, int end, int) {
      std::copy(from_keys + begin, from_keys + end, keys.data() + begin);
      std::copy(from_payload + begin, from_payload + end, payload.data() + begin);
    });
  }
}

/// Where each run of equal keys starts in sorted `keys` (0 first, ascending), found on every
/// thread: the cells of a grid whose points were sorted by cell key (graph/grid_knn.cpp, the
/// coarse level's multires/coarse_cells.cpp).
template <typename Key, typename KeyAlloc>
std::vector<int> runStarts(const std::vector<Key, KeyAlloc>& keys) {
  return indicesWhere(static_cast<long long>(keys.size()),
                      [&keys](std::size_t s) { return s == 0 || keys[s] != keys[s - 1]; });
}

}  // namespace hgd
