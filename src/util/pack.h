// Values packed into bytes and read back in the same order (internal): what the ranks of a
// split streamed run send each other (hgd::StreamRanks). Trivially copyable values only, in the
// host's byte order: every rank of one run is the same build on the same kind of machine.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

namespace hgd::pack {

class Writer {
 public:
  template <typename T>
  Writer& put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    bytes_.append(reinterpret_cast<const char*>(&v), sizeof(T));
    return *this;
  }
  template <typename T>
  Writer& put(const std::vector<T>& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    put<std::uint64_t>(v.size());
    bytes_.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
    return *this;
  }
  /// A vector of values whose bytes are their value but which the language does not call
  /// trivially copyable (Eigen's fixed-size vectors, structs of them).
  template <typename T>
  Writer& putBytes(const std::vector<T>& v) {
    put<std::uint64_t>(v.size());
    bytes_.append(reinterpret_cast<const char*>(static_cast<const void*>(v.data())), v.size() * sizeof(T));
    return *this;
  }
  Writer& put(const std::string& s) {
    put<std::uint64_t>(s.size());
    bytes_.append(s);
    return *this;
  }
  std::string& bytes() { return bytes_; }

 private:
  std::string bytes_;
};

class Reader {
 public:
  explicit Reader(const std::string& bytes) : bytes_(bytes) {}
  template <typename T>
  T get() {
    static_assert(std::is_trivially_copyable_v<T>);
    T v;
    take(&v, sizeof(T));
    return v;
  }
  template <typename T>
  void get(T& v) {
    v = get<T>();
  }
  template <typename T>
  void get(std::vector<T>& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    const auto n = get<std::uint64_t>();
    if (n > (bytes_.size() - at_) / std::max<std::size_t>(1, sizeof(T))) bad();
    v.resize(static_cast<std::size_t>(n));
    take(v.data(), v.size() * sizeof(T));
  }
  template <typename T>
  void getBytes(std::vector<T>& v) {
    const auto n = get<std::uint64_t>();
    if (n > (bytes_.size() - at_) / std::max<std::size_t>(1, sizeof(T))) bad();
    v.resize(static_cast<std::size_t>(n));
    take(static_cast<void*>(v.data()), v.size() * sizeof(T));
  }
  void get(std::string& s) {
    const auto n = get<std::uint64_t>();
    if (n > bytes_.size() - at_) bad();
    s.assign(bytes_, at_, static_cast<std::size_t>(n));
    at_ += static_cast<std::size_t>(n);
  }
  /// Appends a packed vector to `v`.
  template <typename T>
  void append(std::vector<T>& v) {
    std::vector<T> more;
    get(more);
    v.insert(v.end(), more.begin(), more.end());
  }

 private:
  void take(void* out, std::size_t n) {
    if (n > bytes_.size() - at_) bad();
    if (n) std::memcpy(out, bytes_.data() + at_, n);
    at_ += n;
  }
  [[noreturn]] static void bad() { throw std::logic_error("hgd::pack: a message shorter than its contents"); }
  const std::string& bytes_;
  std::size_t at_ = 0;
};

}  // namespace hgd::pack
