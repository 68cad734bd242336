// Stable sort of integer keys carrying an index payload (internal).
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

namespace hgd {

/// Sorts `keys` ascending and permutes `payload` (same length) alongside; stable. LSD radix
/// sort with `digit_bits` per pass, as many passes as `max_key` (no key larger) needs.
template <typename Key>
void radixSort(std::vector<Key>& keys, std::vector<std::uint32_t>& payload, Key max_key, int digit_bits) {
  const std::size_t n = keys.size();
  const Key mask = (Key{1} << digit_bits) - 1;
  std::vector<Key> tmp_keys(n);
  std::vector<std::uint32_t> tmp_payload(n), count(std::size_t{1} << digit_bits);
  for (int shift = 0; shift < static_cast<int>(8 * sizeof(Key)) && (max_key >> shift) != 0;
       shift += digit_bits) {
    std::fill(count.begin(), count.end(), 0u);
    for (std::size_t i = 0; i < n; ++i) ++count[static_cast<std::size_t>((keys[i] >> shift) & mask)];
    std::uint32_t sum = 0;
    for (auto& slot : count) {
      const std::uint32_t v = slot;
      slot = sum;
      sum += v;
    }
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t dst = count[static_cast<std::size_t>((keys[i] >> shift) & mask)]++;
      tmp_keys[dst] = keys[i];
      tmp_payload[dst] = payload[i];
    }
    keys.swap(tmp_keys);
    payload.swap(tmp_payload);
  }
}

}  // namespace hgd
