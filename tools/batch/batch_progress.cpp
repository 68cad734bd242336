// hgdeform batch: what the user sees (a line per scan, or a progress bar on a terminal), and
// stopping cleanly: SIGINT, SIGTERM, SIGHUP and SIGPIPE remove this run's temporaries, a new
// run those of a killed one.
#include <sys/ioctl.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <regex>
#include <string>
#include <system_error>

#include "batch_internal.h"
#include "hgdeform/io/cleanup.h"
#include "hgdeform/io/io.h"

namespace hgdcli {
namespace batch {

namespace {

volatile std::sig_atomic_t g_bar_on_screen = 0;

/// After the temporary files are gone, before the signal ends the process: the shell's prompt
/// goes below the progress bar. Async-signal-safe.
void endBarLine(int sig) {
  if (g_bar_on_screen && sig != SIGPIPE) {
    const ssize_t ignored = ::write(STDOUT_FILENO, "\n", 1);
    (void)ignored;
  }
}

}  // namespace

// --- progress --------------------------------------------------------------------------------

Progress::Progress(std::size_t total, bool tty, bool quiet, std::string prefix)
    : total_(total), tty_(tty), quiet_(quiet), prefix_(std::move(prefix)), start_(Clock::now()) {}

void Progress::started(const std::string& rel) {
  std::lock_guard<std::mutex> lock(m_);
  running_.insert(rel);
  if (tty_ && !quiet_) draw();
}

void Progress::finished(const ScanResult& r, std::size_t number) {
  std::lock_guard<std::mutex> lock(m_);
  running_.erase(r.file);
  ++done_;
  if (number == 0) number = done_;
  if (r.status == "failed" || !r.warning.empty()) {
    clearBar();
    if (r.status == "failed")
      std::fprintf(stderr, "hgdeform batch: %s%s: %s\n", prefix_.c_str(), r.file.c_str(), r.error.c_str());
    if (!r.warning.empty())
      std::fprintf(stderr, "hgdeform batch: %s%s: warning: %s\n", prefix_.c_str(), r.file.c_str(),
                   r.warning.c_str());
    std::fflush(stderr);
  }
  if (quiet_) return;
  if (!r.report.notes.empty()) {
    clearBar();
    for (const auto& note : r.report.notes)
      std::fprintf(stderr, "hgdeform batch: %s%s: note: %s\n", prefix_.c_str(), r.file.c_str(), note.c_str());
    std::fflush(stderr);
  }
  if (tty_) {
    draw();
    return;
  }
  std::string line =
      prefix_ + "[" + std::to_string(number) + "/" + std::to_string(total_) + "] " + r.file + ": ";
  if (r.status == "ok")
    line += "ok " + std::to_string(static_cast<long long>(r.ms_wall + 0.5)) + " ms (" + r.reason + ")";
  else if (r.status == "skipped")
    line += "skipped (up to date)";
  else
    line += "FAILED: " + r.error;
  line += "\n";
  std::fputs(line.c_str(), stdout);
  std::fflush(stdout);
}

void Progress::tick() {
  std::lock_guard<std::mutex> lock(m_);
  if (tty_ && !quiet_ && drawn_) draw();
}

void Progress::close() {
  std::lock_guard<std::mutex> lock(m_);
  if (tty_ && drawn_) {
    std::fputs("\n", stdout);
    std::fflush(stdout);
    drawn_ = false;
    g_bar_on_screen = 0;
  }
}

int Progress::terminalWidth() {
  winsize w{};
  if (::ioctl(STDOUT_FILENO, TIOCGWINSZ, &w) == 0 && w.ws_col >= 20) return w.ws_col;
  return 80;
}

void Progress::clearBar() {
  if (!tty_ || !drawn_) return;
  std::fputs(("\r" + std::string(last_len_, ' ') + "\r").c_str(), stdout);
  std::fflush(stdout);
  drawn_ = false;
}

void Progress::draw() {
  const std::size_t width = static_cast<std::size_t>(terminalWidth()) - 1;
  const double elapsed = std::chrono::duration<double>(Clock::now() - start_).count();
  const double rate = elapsed > 0 ? static_cast<double>(done_) / elapsed : 0.0;
  char eta[32] = "--:--";
  if (done_ > 0 && rate > 0) {
    const long s = std::lround(static_cast<double>(total_ - done_) / rate);
    if (s >= 3600)
      std::snprintf(eta, sizeof eta, "%ld:%02ld:%02ld", s / 3600, (s / 60) % 60, s % 60);
    else
      std::snprintf(eta, sizeof eta, "%ld:%02ld", s / 60, s % 60);
  }
  const int bar_len = 20;
  const int filled = total_ ? static_cast<int>(bar_len * done_ / total_) : bar_len;
  std::string bar = "[" + std::string(static_cast<std::size_t>(filled), '#') +
                    std::string(static_cast<std::size_t>(bar_len - filled), '.') + "]";
  char tail[96];
  std::snprintf(tail, sizeof tail, "  %.2f files/s  ETA %s", rate, eta);
  std::string head = bar + " " + std::to_string(done_) + "/" + std::to_string(total_) + "  ";
  std::string current;
  if (!running_.empty()) {
    current = *running_.begin();
    if (running_.size() > 1) current += " (+" + std::to_string(running_.size() - 1) + ")";
  }
  const std::size_t fixed = head.size() + std::strlen(tail);
  if (fixed + current.size() > width) {
    const std::size_t room = width > fixed + 3 ? width - fixed - 3 : 0;
    current = room ? "..." + current.substr(current.size() - room) : "";
  }
  std::string text = head + current + tail;
  if (text.size() > width) text.resize(width);
  const std::size_t len = text.size();
  if (len < last_len_) text += std::string(last_len_ - len, ' ');
  last_len_ = len;
  std::fputs(("\r" + text).c_str(), stdout);
  std::fflush(stdout);
  drawn_ = true;
  g_bar_on_screen = 1;
}

// --- signals and temporaries -----------------------------------------------------------------

void installSignalHandlers() {
  hgd::removeTemporaryFilesOnSignals(endBarLine);
}

void removeStaleTemporaries(const fs::path& dir) {
  static const std::regex pattern(R"(^\..+\.tmp-([0-9]+)-[0-9a-f]+$)");
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return;
  fs::recursive_directory_iterator it(dir, fs::directory_options::skip_permission_denied, ec), end;
  for (; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    std::smatch m;
    if (!std::regex_match(name, m, pattern)) continue;
    std::error_code e2;
    if (!it->is_regular_file(e2)) continue;
    const std::string pid_text = m[1].str();
    if (pid_text.size() <= 9) {
      const long pid = std::strtol(pid_text.c_str(), nullptr, 10);
      if (pid > 0 && (::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM)) continue;  // alive
    }
    const auto age = fs::file_time_type::clock::now() - fs::last_write_time(it->path(), e2);
    if (e2 || age < std::chrono::seconds(60)) continue;
    fs::remove(it->path(), e2);
  }
}

}  // namespace batch
}  // namespace hgdcli
