// Wall-clock stopwatch in milliseconds (internal).
#pragma once

#include <chrono>

namespace hgd {

class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  double ms() const {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_).count();
  }
  /// Milliseconds since the last lap (or construction), then restarts.
  double lap() {
    const auto now = std::chrono::steady_clock::now();
    const double v = std::chrono::duration<double, std::milli>(now - start_).count();
    start_ = now;
    return v;
  }

 private:
  std::chrono::steady_clock::time_point start_;
};
}  // namespace hgd
