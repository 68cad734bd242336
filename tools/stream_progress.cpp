// A streamed run's progress on stderr (stream_progress.h).
#include "stream_progress.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

namespace hgdcli {

namespace {

// The passes that read every record (the others read a sample on a stride, or a few records alone:
// quick), and how many a run makes: the body, the handles, the cells, the held points and the write; the
// strays' two when the level has sparse cells.
bool fullPass(const std::string& pass) {
  return pass != "frame" && pass != "grid" && pass != "beyond";
}
constexpr int kPlannedPasses = 5, kStrayPasses = 2;

std::string millions(std::uint64_t n) {
  char b[32];
  std::snprintf(b, sizeof b, n >= 10000000 ? "%.0f M" : "%.1f M", static_cast<double>(n) / 1e6);
  return b;
}

std::string clock(double seconds) {
  const long s = std::lround(std::max(0.0, seconds));
  char b[32];
  if (s >= 3600)
    std::snprintf(b, sizeof b, "%ld:%02ld:%02ld", s / 3600, (s / 60) % 60, s % 60);
  else
    std::snprintf(b, sizeof b, "%ld:%02ld", s / 60, s % 60);
  return b;
}

}  // namespace

StreamProgress::StreamProgress(std::string label, bool on, bool tty)
    : label_(std::move(label)), on_(on), tty_(tty) {
  if (on_) previous_ = hgd::setRecordProgress([this](const hgd::RecordProgress& p) { update(p); });
}

StreamProgress::~StreamProgress() {
  if (!on_) return;
  hgd::setRecordProgress(std::move(previous_));
  if (drawn_ > 0) {
    std::fprintf(stderr, "\r%*s\r", static_cast<int>(drawn_), "");
    std::fflush(stderr);
  }
}

std::string StreamProgress::line(const hgd::RecordProgress& p, double seconds) {
  const std::string pass = p.pass;
  if (pass != pass_ || p.done < last_done_) {  // a new pass (the stray passes share a name)
    // A pass starts where the one before ended: its first block is read before it reports.
    if (full_) {
      ++full_done_;
      full_seconds_ += last_seconds_ - pass_start_;
    }
    pass_ = pass;
    full_ = fullPass(pass);
    strays_ = strays_ || pass == "strays";
    pass_start_ = last_seconds_;
  }
  last_done_ = p.done;
  last_seconds_ = seconds;
  if (!full_ || p.records == 0) return "";
  const double records = static_cast<double>(p.records);
  const double read = full_done_ * records + static_cast<double>(p.done);
  const double spent = full_seconds_ + (seconds - pass_start_);
  if (spent <= 0 || read <= 0) return "";
  const double rate = read / spent;
  const int planned = std::max(kPlannedPasses + (strays_ ? kStrayPasses : 0), full_done_ + 1);
  const double left = (planned * records - read) / rate;
  char b[256];
  std::snprintf(b, sizeof b, "%s: pass %d of %d (%s) %3.0f%%, %s points/s, about %s left", label_.c_str(),
                full_done_ + 1, planned, pass_.c_str(), 100.0 * static_cast<double>(p.done) / records,
                millions(static_cast<std::uint64_t>(rate)).c_str(), clock(left).c_str());
  return b;
}

void StreamProgress::update(const hgd::RecordProgress& p) {
  const double now = std::chrono::duration<double>(Clock::now() - start_).count();
  const std::string text = line(p, now);
  // After two seconds: a quick run says nothing; on a terminal four times a second, in a log
  // every ten seconds.
  if (text.empty() || now < 2.0 || now - last_shown_ < (tty_ ? 0.25 : 10.0)) return;
  last_shown_ = now;
  if (tty_) {
    const std::string shown = "hgdeform: " + text;
    std::fprintf(stderr, "\r%-*s", static_cast<int>(drawn_), shown.c_str());
    drawn_ = std::max(drawn_, shown.size());
  } else {
    std::fprintf(stderr, "hgdeform: %s\n", text.c_str());
  }
  std::fflush(stderr);
}

}  // namespace hgdcli
