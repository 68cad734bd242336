// Atomic writes (a temporary file beside the output, renamed over it when complete), the
// signal-safe registry of temporary files in progress, and the checks that keep a tool from
// writing over its input or leaving a failed output behind.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <filesystem>
#include <random>

#include "hgdeform/io/cleanup.h"
#include "io/internal.h"

namespace hgd {
namespace io_internal {
namespace {

namespace fs = std::filesystem;

// Temporary files being written, so that a signal handler can remove them
// (removeTemporaryFiles). Fixed slots and atomics only: readable from a signal handler.
struct TempSlot {
  std::atomic<int> state{0};  // 0 free, 1 claimed, 2 holds a live path
  char path[4096];
};
TempSlot g_temp_slots[64];

int registerTemp(const std::string& path) {
  if (path.size() >= sizeof(TempSlot::path)) return -1;
  for (int i = 0; i < 64; ++i) {
    int expected = 0;
    if (g_temp_slots[i].state.compare_exchange_strong(expected, 1)) {
      std::memcpy(g_temp_slots[i].path, path.c_str(), path.size() + 1);
      g_temp_slots[i].state.store(2);
      return i;
    }
  }
  return -1;
}

void unregisterTemp(int slot) {
  if (slot >= 0) g_temp_slots[slot].state.store(0);
}

/// A temporary name in `dir` for a file named `name`: ".NAME.tmp-PID-HEX", NAME cut (at a
/// character's start) where the whole would pass the file system's longest name, so that an
/// output named with 229-255 bytes is still written.
fs::path tempBeside(const fs::path& dir, const std::string& name, std::random_device& rd) {
  char suffix[64];
  std::snprintf(suffix, sizeof suffix, ".tmp-%ld-%08x%08x", static_cast<long>(::getpid()), rd(), rd());
  std::string base = name;
  const long name_max = ::pathconf(dir.c_str(), _PC_NAME_MAX);
  const std::size_t room =
      (name_max > 0 ? static_cast<std::size_t>(name_max) : 255) - 1 - std::strlen(suffix);
  if (base.size() > room) {
    std::size_t cut = room;
    while (cut > 0 && (static_cast<unsigned char>(base[cut]) & 0xC0) == 0x80) --cut;
    base.resize(cut);
  }
  return dir / ("." + base + suffix);
}

/// The descriptor an absolute, normalised path names: /dev/stdin, /dev/stdout, /dev/stderr,
/// /dev/fd/N, /proc/self/fd/N, /proc/thread-self/fd/N or /proc/<this process>/fd/N; else -1.
int descriptorNamed(const std::string& p) {
  if (p == "/dev/stdin") return 0;
  if (p == "/dev/stdout") return 1;
  if (p == "/dev/stderr") return 2;
  for (const std::string& dir :
       {std::string("/dev/fd/"), std::string("/proc/self/fd/"), std::string("/proc/thread-self/fd/"),
        "/proc/" + std::to_string(::getpid()) + "/fd/"}) {
    if (p.size() <= dir.size() || p.compare(0, dir.size(), dir) != 0 || p.size() - dir.size() > 9) continue;
    int fd = 0;
    for (std::size_t i = dir.size(); i < p.size(); ++i) {
      if (p[i] < '0' || p[i] > '9') return -1;
      fd = fd * 10 + (p[i] - '0');
    }
    return fd;
  }
  return -1;
}

/// A stdio stream on the open descriptor `fd` (taken over: closed when the stream cannot be
/// made, and the write fails naming `target`).
std::FILE* streamOn(int fd, const std::string& target) {
  std::FILE* f = ::fdopen(fd, "wb");
  if (!f) {
    const int e = errno;
    ::close(fd);
    fail(target, "cannot write: " + errnoText(e));
  }
  return f;
}

}  // namespace

int descriptorPath(const std::string& path) {
  fs::path p(path);
  for (int hops = 0; hops < 40; ++hops) {
    std::error_code ec;
    const fs::path abs = fs::absolute(p, ec).lexically_normal();
    if (ec) return -1;
    if (const int fd = descriptorNamed(abs.string()); fd >= 0) return fd;
    struct stat st {};
    if (::lstat(p.c_str(), &st) != 0 || !S_ISLNK(st.st_mode)) return -1;
    const fs::path to = fs::read_symlink(p, ec);
    if (ec) return -1;
    p = to.is_absolute() ? to : p.parent_path() / to;
  }
  return -1;
}

AtomicWriter::AtomicWriter(const std::string& target) : target_(target) {
  if (const int fd = descriptorPath(target); fd >= 0) {
    // Written to the descriptor itself (as "-" is to stdout): whatever it is open on, a file
    // that stdout was redirected to (appended to with >>) included, is never replaced.
    if (fd == STDOUT_FILENO) std::fflush(stdout);  // what the program printed comes first
    if (fd == STDERR_FILENO) std::fflush(stderr);
    const int copy = ::fcntl(fd, F_DUPFD_CLOEXEC, 0);
    if (copy < 0) fail(target_, "cannot write: " + errnoText(errno));
    file_ = streamOn(copy, target_);
    return;  // direct: commit only flushes
  }
  struct stat st {};
  const int found = ::stat(target.c_str(), &st);
  // A loop of links (l1 -> l2 -> l1) names no file: refused, not replaced by one.
  if (found != 0 && errno == ELOOP) fail(target_, "cannot write: " + errnoText(ELOOP));
  if (found == 0 && !S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode)) {
    const int fd = ::open(target.c_str(), O_WRONLY | O_CLOEXEC);
    if (fd < 0) fail(target_, "cannot write: " + errnoText(errno));
    file_ = streamOn(fd, target_);
    return;  // direct: commit only flushes
  }
  if (struct stat lst{}; ::lstat(target.c_str(), &lst) == 0 && S_ISLNK(lst.st_mode)) {
    // Follow the link (and links to links) to the file it names, existing or not.
    fs::path t(target);
    int hops = 0;
    for (std::error_code ec; fs::is_symlink(t, ec); ++hops) {
      if (hops == 40) fail(target_, "cannot write: " + errnoText(ELOOP));
      const fs::path to = fs::read_symlink(t, ec);
      if (ec) fail(target_, "cannot write: cannot read the symbolic link: " + ec.message());
      t = to.is_absolute() ? to : t.parent_path() / to;
    }
    rename_to_ = t.string();
  } else {
    rename_to_ = target;
  }
  const fs::path t(rename_to_);
  fs::path dir = t.parent_path();
  if (dir.empty()) dir = ".";
  std::random_device rd;
  for (int attempt = 0; attempt < 16; ++attempt) {
    const fs::path tmp = tempBeside(dir, t.filename().string(), rd);
    // Registered before it is created: a signal never finds it there and not yet registered
    // (removing a name not created yet does nothing).
    const int slot = registerTemp(tmp.string());
    const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0) {
      const int e = errno;
      unregisterTemp(slot);
      if (e == EEXIST) continue;
      fail(target_, "cannot write: cannot create a temporary file in " + dir.string() + ": " + errnoText(e));
    }
    tmp_ = tmp.string();
    slot_ = slot;
    file_ = ::fdopen(fd, "wb");
    if (!file_) {
      const int e = errno;
      ::close(fd);
      ::unlink(tmp_.c_str());
      tmp_.clear();
      fail(target_, "cannot write: " + errnoText(e));
    }
    return;
  }
  fail(target_, "cannot write: cannot create a unique temporary file");
}

AtomicWriter::~AtomicWriter() {
  if (file_) std::fclose(file_);
  if (!tmp_.empty()) ::unlink(tmp_.c_str());
  unregisterTemp(slot_);
}

void AtomicWriter::write(const void* p, std::size_t n) {
  if (n && std::fwrite(p, 1, n, file_) != n) failWrite(errno);
  const auto* bytes = static_cast<const unsigned char*>(p);
  for (std::uint64_t k = std::max<std::uint64_t>(written_, 80); k < 84 && k < written_ + n; ++k)
    count_bytes_[k - 80] = bytes[k - written_];
  written_ += n;
}

void AtomicWriter::skip(std::uint64_t n) {
  if (tmp_.empty())
    fail(target_, "cannot write: a descriptor or device cannot be written by several processes");
  if (std::fflush(file_) != 0) failWrite(errno);
  if (::fseeko(file_, static_cast<off_t>(n), SEEK_CUR) != 0) failWrite(errno);
  written_ += n;
}

bool AtomicWriter::hasBinaryStlSize() const {
  return written_ >= 84 && binaryStlSizeFits(count_bytes_, written_);
}

void AtomicWriter::commit() {
  if (std::fflush(file_) != 0 || std::ferror(file_)) failWrite(errno);
  std::FILE* f = file_;
  file_ = nullptr;
  if (std::fclose(f) != 0) failWrite(errno);
  if (tmp_.empty()) return;  // written directly
  if (std::rename(tmp_.c_str(), rename_to_.c_str()) != 0) failWrite(errno);
  tmp_.clear();
  unregisterTemp(slot_);
  slot_ = -1;
}

void AtomicWriter::failWrite(int e) {
  fail(target_, "cannot write: " + errnoText(e));
}

}  // namespace io_internal

using namespace io_internal;
namespace fs = std::filesystem;

bool samePath(const std::string& a, const std::string& b) {
  std::error_code ea, eb, ee;
  if (fs::exists(a, ea) && fs::exists(b, eb)) return fs::equivalent(a, b, ee) && !ee;
  // Not both there: the same when they resolve to the same place (links followed as far as
  // they exist, "." and ".." folded).
  const fs::path ca = fs::weakly_canonical(fs::absolute(a, ea), ea),
                 cb = fs::weakly_canonical(fs::absolute(b, eb), eb);
  return !ea && !eb && ca == cb;
}

void refuseInputs(const std::string& output, const std::vector<std::string>& inputs) {
  for (const std::string& in : inputs)
    if (!in.empty() && in != "-" && samePath(output, in))
      fail(output, "refusing to overwrite the input " + in);
}

void removeOutput(const std::string& path) noexcept {
  if (io_internal::descriptorPath(path) >= 0) return;  // written to a descriptor: nothing to take back
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) return;
  if (S_ISLNK(st.st_mode)) {  // what the writer wrote is the link's target
    std::error_code ec;
    const fs::path target = fs::canonical(path, ec);
    if (!ec && fs::is_regular_file(target, ec)) fs::remove(target, ec);
    return;
  }
  if (S_ISREG(st.st_mode)) ::unlink(path.c_str());
}

PreviousOutput::PreviousOutput(std::string path) : path_(std::move(path)) {
  if (io_internal::descriptorPath(path_) >= 0) return;  // a descriptor: nothing is replaced
  std::error_code ec;
  struct stat lst {};
  if (::lstat(path_.c_str(), &lst) != 0) return;  // nothing there yet: restore() removes
  target_ = path_;
  if (S_ISLNK(lst.st_mode)) {
    const fs::path t = fs::canonical(path_, ec);
    if (ec) return;
    target_ = t.string();
  }
  struct stat st {};
  if (::stat(target_.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) {
    target_.clear();  // a FIFO or a device is written to, never replaced: nothing to keep
    return;
  }
  const fs::path t(target_);
  fs::path dir = t.parent_path();
  if (dir.empty()) dir = ".";
  std::random_device rd;
  for (int attempt = 0; attempt < 16; ++attempt) {
    const std::string aside = tempBeside(dir, t.filename().string(), rd).string();
    const int slot = registerTemp(aside);
    if (::link(target_.c_str(), aside.c_str()) == 0) {
      aside_ = aside;
      slot_ = slot;
      return;
    }
    const int e = errno;
    unregisterTemp(slot);
    if (e != EEXIST) return;  // no hard links here: a failed run then leaves no output at all
  }
}

PreviousOutput::~PreviousOutput() {
  keep();
}

void PreviousOutput::restore() noexcept {
  if (!aside_.empty()) {
    if (::rename(aside_.c_str(), target_.c_str()) != 0) ::unlink(aside_.c_str());
    aside_.clear();
    unregisterTemp(slot_);
    slot_ = -1;
    return;
  }
  if (target_.empty()) removeOutput(path_);
}

void PreviousOutput::keep() noexcept {
  if (aside_.empty()) return;
  ::unlink(aside_.c_str());
  aside_.clear();
  unregisterTemp(slot_);
  slot_ = -1;
}

void removeTemporaryFiles() noexcept {
  for (auto& slot : g_temp_slots)
    if (slot.state.load() == 2) ::unlink(slot.path);
}

namespace {

std::atomic<void (*)(int)> g_also_on_signal{nullptr};

void onTerminatingSignal(int sig) {
  const int saved = errno;
  removeTemporaryFiles();
  if (void (*also)(int) = g_also_on_signal.load()) also(sig);
  // The default action, then the signal again: it is blocked while this handler runs, so it
  // ends the process (as killed by it) as soon as the handler returns.
  struct sigaction dfl {};
  dfl.sa_handler = SIG_DFL;
  sigemptyset(&dfl.sa_mask);
  ::sigaction(sig, &dfl, nullptr);
  ::raise(sig);
  errno = saved;
}

}  // namespace

void removeTemporaryFilesOnSignals(void (*also)(int)) noexcept {
  g_also_on_signal.store(also);
  // Every signal whose default ends the process and that a run may meet: a user's, a batch
  // system's (SIGUSR1/2 before a time limit, SIGXCPU), a timer's, and SIGXFSZ when the output
  // passes `ulimit -f`.
  const int signals[] = {SIGINT,  SIGTERM, SIGHUP,    SIGPIPE, SIGQUIT, SIGUSR1,
                         SIGUSR2, SIGALRM, SIGVTALRM, SIGXFSZ, SIGXCPU};
  struct sigaction sa {};
  sa.sa_handler = onTerminatingSignal;
  sigemptyset(&sa.sa_mask);
  for (const int s : signals) sigaddset(&sa.sa_mask, s);  // one handler at a time
  sa.sa_flags = 0;
  for (const int s : signals) {
    struct sigaction old {};
    if (::sigaction(s, nullptr, &old) == 0 && old.sa_handler == SIG_IGN) continue;  // nohup, ...
    ::sigaction(s, &sa, nullptr);
  }
}

void writeFileAtomically(const std::string& path, std::string_view bytes) {
  AtomicWriter w(path);
  w.write(bytes);
  w.commit();
}

}  // namespace hgd
