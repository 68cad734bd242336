// Blocks of a file's fixed-size point records, read in place (hgdeform/io/records.h).
#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <utility>

#include "io/internal.h"

namespace hgd {

using io_internal::errnoText;
using io_internal::fail;
using io_internal::num;

namespace {
thread_local std::function<void(const RecordProgress&)> t_progress;
thread_local const char* t_pass = "";
}  // namespace

std::function<void(const RecordProgress&)> setRecordProgress(
    std::function<void(const RecordProgress&)> hook) {
  std::swap(hook, t_progress);
  return hook;
}

void streamPass(const char* name) {
  t_pass = name;
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
  if (t_progress) t_progress(RecordProgress{t_pass, first + count, layout_.count});
}

}  // namespace hgd
