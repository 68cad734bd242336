// What a streamed run (a scan larger than memory) shows on stderr while it reads its file: the
// pass, the points done, the rate and the time left. On a terminal one line, redrawn; otherwise
// (a log, a cluster job's output) a line every ten seconds. Nothing for a run of a few seconds.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <string>

#include "hgdeform/io/records.h"

namespace hgdcli {

class StreamProgress {
 public:
  /// Shows the progress of the calling thread's record reads (hgd::setRecordProgress) until
  /// destroyed; `label` starts each line (the file). `on`: false shows nothing.
  StreamProgress(std::string label, bool on, bool tty);
  ~StreamProgress();
  StreamProgress(const StreamProgress&) = delete;
  StreamProgress& operator=(const StreamProgress&) = delete;

  /// The line for a run at `p`, `seconds` after it started (a test's entry point): "" before a
  /// full pass has read a block.
  std::string line(const hgd::RecordProgress& p, double seconds);

 private:
  using Clock = std::chrono::steady_clock;
  void update(const hgd::RecordProgress& p);

  std::string label_;
  bool on_, tty_;
  Clock::time_point start_ = Clock::now();
  double last_shown_ = 0;
  std::size_t drawn_ = 0;  // characters of the line on the terminal (0: none)
  std::function<void(const hgd::RecordProgress&)> previous_;
  // The passes: full passes done, the current one and when it started, the seconds spent in
  // full passes (the rate), whether the stray passes are in the run.
  std::string pass_;
  std::uint64_t last_done_ = 0;
  int full_done_ = 0;
  bool full_ = false, strays_ = false;
  double pass_start_ = 0, last_seconds_ = 0, full_seconds_ = 0;
};

}  // namespace hgdcli
