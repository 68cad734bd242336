// Blocks of a file's fixed-size point records, read in place (hgdeform/io/records.h).
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <stdexcept>
#include <utility>

#include "io/internal.h"

namespace hgd {

using io_internal::errnoText;
using io_internal::fail;
using io_internal::num;

namespace {
thread_local std::function<void(const RecordProgress&)> t_progress;
thread_local const char* t_pass = "";
thread_local std::uint64_t t_share_first = 0, t_share_last = 0;  // 0, 0: the whole file
}  // namespace

std::function<void(const RecordProgress&)> setRecordProgress(
    std::function<void(const RecordProgress&)> hook) {
  std::swap(hook, t_progress);
  return hook;
}

void streamPass(const char* name) {
  t_pass = name;
}

void streamShare(std::uint64_t first, std::uint64_t last) {
  t_share_first = last > 0 ? first : 0;
  t_share_last = last;
}

RecordShare shareOf(std::uint64_t records, int rank, int ranks) {
  const auto n = static_cast<std::uint64_t>(std::max(1, ranks));
  const auto r = static_cast<std::uint64_t>(std::clamp(rank, 0, std::max(0, ranks - 1)));
  const std::uint64_t base = records / n, extra = records % n;
  const std::uint64_t first = r * base + std::min(r, extra);
  return {first, first + base + (r < extra ? 1 : 0)};
}

RecordReader::RecordReader(const RecordLayout& layout) : layout_(layout) {
  const std::string& path = layout.shape.path;
  fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd_ < 0) fail(path, "cannot open: " + errnoText(errno));
}

RecordReader::~RecordReader() {
  if (fd_ >= 0) ::close(fd_);
}

void RecordReader::read(std::uint64_t first, std::size_t count, std::uint8_t* out) const {
  const std::string& path = layout_.shape.path;
  if (first > layout_.count || count > layout_.count - first)
    fail(path, "records " + num(first) + " to " + num(first + count) + " asked of " + num(layout_.count));
  std::uint64_t at = layout_.offset + first * layout_.bytes;
  std::size_t left = count * layout_.bytes;
  while (left > 0) {
    const ssize_t got = ::pread(fd_, out, left, static_cast<off_t>(at));
    if (got < 0 && errno == EINTR) continue;
    if (got < 0) fail(path, "cannot read: " + errnoText(errno));
    if (got == 0)
      fail(path, "truncated data: the file ends at byte " + num(at) + ", record " + num(first + count) +
                     " ends at " + num(layout_.offset + (first + count) * layout_.bytes));
    out += got;
    left -= static_cast<std::size_t>(got);
    at += static_cast<std::uint64_t>(got);
  }
  if (!t_progress) return;
  if (t_share_last > 0)
    t_progress(RecordProgress{t_pass, first + count > t_share_first ? first + count - t_share_first : 0,
                              t_share_last - t_share_first});
  else
    t_progress(RecordProgress{t_pass, first + count, layout_.count});
}

}  // namespace hgd
