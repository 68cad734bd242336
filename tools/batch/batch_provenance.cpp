#include "batch_provenance.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <vector>

#include "hgdeform/version.h"

namespace hgdcli {
namespace batch {

namespace {

namespace fs = std::filesystem;

// /2: the input's ctime and inode, the output's ctime and inode. A /1 record is no record (its
// scan is redone once).
const char* kRecordFormat = "hgdeform-batch-record/2";

std::string hex(XXH64_hash_t h) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

std::int64_t nanoseconds(const timespec& t) {
  return static_cast<std::int64_t>(t.tv_sec) * 1000000000LL + static_cast<std::int64_t>(t.tv_nsec);
}

/// The whole of a small file ("" when it cannot be read).
std::string readAll(int fd) {
  std::string text;
  char buf[512];
  off_t at = 0;
  for (;;) {
    const ssize_t got = ::pread(fd, buf, sizeof buf, at);
    if (got <= 0) break;
    text.append(buf, static_cast<std::size_t>(got));
    at += got;
  }
  return text;
}

void writeAll(int fd, const std::string& text) {
  if (::ftruncate(fd, 0) != 0) return;  // only a description for messages: best effort
  const ssize_t ignored = ::pwrite(fd, text.data(), text.size(), 0);
  (void)ignored;
}

/// "split=<all|N> pid=<pid> host=<host>" (what the lock files hold).
std::string holderText(const std::string& split) {
  char host[256] = "?";
  if (::gethostname(host, sizeof host - 1) != 0) std::strcpy(host, "?");
  host[sizeof host - 1] = '\0';
  return "split=" + split + " pid=" + std::to_string(::getpid()) + " host=" + host + "\n";
}

std::string field(const std::string& text, const std::string& key) {
  std::istringstream in(text);
  std::string word;
  while (in >> word)
    if (word.rfind(key + "=", 0) == 0) return word.substr(key.size() + 1);
  return "";
}

/// "another hgdeform batch (pid 12 on node3, all scans)".
std::string describeHolder(const std::string& text) {
  const std::string pid = field(text, "pid"), host = field(text, "host"), split = field(text, "split");
  std::string d = "another hgdeform batch";
  if (pid.empty()) return d;
  d += " (pid " + pid + " on " + host;
  if (split == "all")
    d += ", all scans";
  else if (!split.empty())
    d += ", --shard K/" + split;
  return d + ")";
}

int openLockFile(const fs::path& path) {
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0)
    throw std::runtime_error(path.string() + ": cannot open the lock file: " + std::strerror(errno));
  return fd;
}

}  // namespace

FileState fileState(const std::string& path) {
  FileState s;
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return s;
  s.exists = true;
  s.size = static_cast<std::uint64_t>(st.st_size);
  s.mtime_ns = nanoseconds(st.st_mtim);
  s.ctime_ns = nanoseconds(st.st_ctim);
  s.dev = static_cast<std::uint64_t>(st.st_dev);
  s.ino = static_cast<std::uint64_t>(st.st_ino);
  return s;
}

std::string hashFile(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw std::runtime_error(path + ": cannot read: " + std::strerror(errno));
  std::unique_ptr<XXH3_state_t, XXH_errorcode (*)(XXH3_state_t*)> state(XXH3_createState(), XXH3_freeState);
  if (!state || XXH3_64bits_reset(state.get()) != XXH_OK) {
    ::close(fd);
    throw std::bad_alloc();
  }
  std::vector<char> buf(1 << 20);
  for (;;) {
    const ssize_t got = ::read(fd, buf.data(), buf.size());
    if (got == 0) break;
    if (got < 0) {
      if (errno == EINTR) continue;
      const int err = errno;
      ::close(fd);
      throw std::runtime_error(path + ": cannot read: " + std::strerror(err));
    }
    XXH3_64bits_update(state.get(), buf.data(), static_cast<std::size_t>(got));
  }
  ::close(fd);
  return hex(XXH3_64bits_digest(state.get()));
}

std::string hashBytes(std::string_view bytes) {
  return hex(XXH3_64bits(bytes.data(), bytes.size()));
}

bool sameInput(const Provenance& p, const FileState& now) {
  return now.exists && p.input_size == now.size && p.input_mtime_ns == now.mtime_ns &&
         p.input_ctime_ns == now.ctime_ns && p.input_ino == now.ino;
}

bool sameOutput(const Provenance& p, const FileState& now) {
  return now.exists && p.output_size == now.size && p.output_ctime_ns == now.ctime_ns &&
         p.output_ino == now.ino;
}

void recordInput(Provenance& p, const FileState& s) {
  p.input_size = s.size;
  p.input_mtime_ns = s.mtime_ns;
  p.input_ctime_ns = s.ctime_ns;
  p.input_ino = s.ino;
}

void recordOutput(Provenance& p, const FileState& s) {
  p.output_size = s.size;
  p.output_ctime_ns = s.ctime_ns;
  p.output_ino = s.ino;
}

std::string recordText(const Provenance& p) {
  nlohmann::json j;
  j["format"] = kRecordFormat;
  j["input"] = {{"file", p.input},
                {"size", p.input_size},
                {"mtime_ns", p.input_mtime_ns},
                {"ctime_ns", p.input_ctime_ns},
                {"inode", p.input_ino},
                {"xxh3", p.input_hash}};
  j["scenario"] = {{"file", p.scenario}, {"xxh3", p.scenario_hash}};
  j["options"] = p.options.is_null() ? nlohmann::json::object() : p.options;
  j["tool"] = p.tool;
  j["output"] = {{"size", p.output_size}, {"ctime_ns", p.output_ctime_ns}, {"inode", p.output_ino}};
  if (!p.invalid.empty()) j["invalid"] = p.invalid;
  return j.dump(2) + "\n";
}

std::optional<Provenance> readRecord(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  std::ostringstream ss;
  ss << in.rdbuf();
  try {
    const auto j = nlohmann::json::parse(ss.str());
    if (j.at("format").get<std::string>() != kRecordFormat) return std::nullopt;
    Provenance p;
    const auto& input = j.at("input");
    p.input = input.at("file").get<std::string>();
    p.input_size = input.at("size").get<std::uint64_t>();
    p.input_mtime_ns = input.at("mtime_ns").get<std::int64_t>();
    p.input_ctime_ns = input.at("ctime_ns").get<std::int64_t>();
    p.input_ino = input.at("inode").get<std::uint64_t>();
    p.input_hash = input.at("xxh3").get<std::string>();
    p.scenario = j.at("scenario").at("file").get<std::string>();
    p.scenario_hash = j.at("scenario").at("xxh3").get<std::string>();
    p.options = j.at("options");
    p.tool = j.at("tool").get<std::string>();
    p.output_size = j.at("output").at("size").get<std::uint64_t>();
    p.output_ctime_ns = j.at("output").at("ctime_ns").get<std::int64_t>();
    p.output_ino = j.at("output").at("inode").get<std::uint64_t>();
    p.invalid = j.value("invalid", std::string());
    return p;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

std::string toolVersion() {
  return std::string("hgdeform ") + hgd::version();
}

OutputLock::~OutputLock() {
  if (shard_fd_ >= 0) ::close(shard_fd_);
  if (fd_ >= 0) ::close(fd_);  // closing releases the flock
}

void OutputLock::acquire(const std::string& output_dir, int shard_k, int shard_n) {
  const fs::path dir = fs::path(output_dir) / ".hgdeform";
  fs::create_directories(dir);
  fd_ = openLockFile(dir / "batch.lock");
  const std::string split = shard_n > 0 ? std::to_string(shard_n) : "all";
  const std::string busy_tail = ": wait for it to finish, or choose another output folder";
  auto busy = [&] {
    return std::runtime_error(output_dir + " is in use by " + describeHolder(readAll(fd_)) + busy_tail);
  };
  const bool first = ::flock(fd_, LOCK_EX | LOCK_NB) == 0;
  if (first) writeAll(fd_, holderText(split));
  if (shard_n == 0) {
    if (!first) throw busy();
    return;
  }
  // Shards of one split share the folder. The first holds the lock exclusively for a moment
  // (while it writes its split into the file), hence a few tries; a whole run holds it for good.
  bool shared = false;
  for (int attempt = 0; attempt < 150 && !shared; ++attempt) {
    shared = ::flock(fd_, LOCK_SH | LOCK_NB) == 0;  // from exclusive: a conversion
    if (!shared) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  if (!shared) throw busy();
  const std::string holder = readAll(fd_);
  if (field(holder, "split") != split)
    throw std::runtime_error(output_dir + " is in use by " + describeHolder(holder) +
                             "; shards writing to one folder at once must all use --shard K/" +
                             field(holder, "split") + busy_tail);
  shard_fd_ = openLockFile(dir / ("batch-shard-" + std::to_string(shard_k) + "-of-" + split + ".lock"));
  if (::flock(shard_fd_, LOCK_EX | LOCK_NB) != 0)
    throw std::runtime_error(output_dir + ": shard " + std::to_string(shard_k) + "/" + split +
                             " is already running: " + describeHolder(readAll(shard_fd_)) + busy_tail);
  writeAll(shard_fd_, holderText(split));
}

}  // namespace batch
}  // namespace hgdcli
