// Named phase timings of a build (internal). precompute() and the Deformer install a log for
// the thread that builds; the stages they call add their phases to it with PhaseClock, which
// records nothing (and costs one clock read a lap) when no log is installed.
#pragma once

#include <chrono>
#include <string>
#include <vector>

#include "hgdeform/util/phase.h"

namespace hgd {

/// The log the current thread's phases go to (null: none).
inline thread_local std::vector<BuildPhase>* t_phase_log = nullptr;

/// Installs `log` as this thread's phase log while it lives (the previous one is restored).
class PhaseRecording {
 public:
  explicit PhaseRecording(std::vector<BuildPhase>* log) : previous_(t_phase_log) { t_phase_log = log; }
  ~PhaseRecording() { t_phase_log = previous_; }
  PhaseRecording(const PhaseRecording&) = delete;
  PhaseRecording& operator=(const PhaseRecording&) = delete;

 private:
  std::vector<BuildPhase>* previous_;
};

/// Consecutive phases: lap(name) adds the time since the last lap (or construction) under
/// `name` to the installed log and returns it in ms.
class PhaseClock {
 public:
  PhaseClock() : start_(std::chrono::steady_clock::now()) {}
  double lap(const char* name) {
    const auto now = std::chrono::steady_clock::now();
    const double ms = std::chrono::duration<double, std::milli>(now - start_).count();
    start_ = now;
    if (t_phase_log) t_phase_log->push_back({name, ms});
    return ms;
  }
  /// Restarts without recording (time spent in something else that records its own phases).
  void skip() { start_ = std::chrono::steady_clock::now(); }

 private:
  std::chrono::steady_clock::time_point start_;
};

}  // namespace hgd
