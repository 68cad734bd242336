// What the readers and writers of every format share: small text helpers, the bounds-checked
// input file, and the decimals of text columns. (Building and converting clouds: clouds.cpp;
// checking and packing a shape about to be written: output.cpp.)
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>

#include "io/internal.h"

namespace hgd::io_internal {

// ------------------------------------------------------------------------------------------
// Small helpers

void fail(const std::string& path, const std::string& problem) {
  throw IoError(path + ": " + problem);
}

std::string errnoText(int e) {
  return std::strerror(e);
}

std::string num(std::uint64_t v) {
  return std::to_string(v);
}

std::string excerpt(std::string_view s) {
  std::string out = "'";
  const std::size_t n = std::min<std::size_t>(s.size(), 60);
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    out += (c >= 0x20 && c < 0x7f) ? static_cast<char>(c) : '?';
  }
  if (s.size() > n) out += "...";
  return out + "'";
}

bool isSpace(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

namespace {
/// The runs of `s` between separators.
template <class Separator>
std::vector<std::string_view> splitAt(std::string_view s, Separator sep) {
  std::vector<std::string_view> words;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && sep(s[i])) ++i;
    const std::size_t b = i;
    while (i < s.size() && !sep(s[i])) ++i;
    if (i > b) words.push_back(s.substr(b, i - b));
  }
  return words;
}
}  // namespace

std::vector<std::string_view> splitWords(std::string_view s) {
  return splitAt(s, isSpace);
}

std::vector<std::string_view> splitColumns(std::string_view s) {
  return splitAt(s, [](char c) { return isSpace(c) || c == ','; });
}

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

bool parseU64(std::string_view s, std::uint64_t* v) {
  if (!s.empty() && s[0] == '+') s.remove_prefix(1);
  if (s.empty()) return false;
  const char* e = s.data() + s.size();
  const auto r = std::from_chars(s.data(), e, *v);
  return r.ec == std::errc() && r.ptr == e;
}

Parse parseInteger(std::string_view s, long long* v) {
  std::string_view t = s;
  if (!t.empty() && t[0] == '+') t.remove_prefix(1);
  if (t.empty()) return Parse::Bad;
  const char* e = t.data() + t.size();
  const auto r = std::from_chars(t.data(), e, *v);
  if (r.ptr == e && r.ec == std::errc()) return Parse::Ok;
  if (r.ptr == e && r.ec == std::errc::result_out_of_range) return Parse::Range;
  double d = 0;
  if (!parseFloating(s, &d) || !std::isfinite(d) || d != std::floor(d)) return Parse::Bad;
  if (d < -9.2e18 || d > 9.2e18) return Parse::Range;
  *v = static_cast<long long>(d);
  return Parse::Ok;
}
std::size_t xyzCommentStart(std::string_view line) {
  for (std::size_t i = 0; i < line.size(); ++i)
    if (line[i] == '#' && (i == 0 || isSpace(line[i - 1]) || line[i - 1] == ',')) return i;
  return std::string_view::npos;
}

// ------------------------------------------------------------------------------------------
// Input

InputFile::InputFile(std::string path) : path_(std::move(path)) {
  // Non-blocking, so that a FIFO (or a device) given as input is refused instead of waiting
  // for a writer; regular files ignore the flag.
  const int fd = ::open(path_.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) fail(path_, "cannot open: " + errnoText(errno));
  std::FILE* f = ::fdopen(fd, "rb");
  if (!f) {
    const int e = errno;
    ::close(fd);
    fail(path_, "cannot open: " + errnoText(e));
  }
  file_.reset(f);
  struct stat st {};
  if (::fstat(fd, &st) != 0) fail(path_, "cannot open: " + errnoText(errno));
  if (S_ISDIR(st.st_mode)) fail(path_, "cannot open: " + errnoText(EISDIR));
  if (!S_ISREG(st.st_mode)) fail(path_, "cannot open: not a regular file");
  size_ = static_cast<std::uint64_t>(st.st_size);
  if (size_ == 0) fail(path_, "empty file");
  // A UTF-8 byte-order mark (editors on Windows add one) is not part of any format: skip it,
  // so that an OBJ's first vertex is not lost and a PLY's magic line is found.
  unsigned char bom[3] = {0, 0, 0};
  if (size_ >= 3 && std::fread(bom, 1, 3, f) == 3 && bom[0] == 0xEF && bom[1] == 0xBB && bom[2] == 0xBF)
    pos_ = skipped_ = 3;
  else if (::fseeko(f, 0, SEEK_SET) != 0)
    fail(path_, "cannot read: " + errnoText(errno));
}

bool InputFile::readLine(std::string* line, std::size_t max_len) {
  line->clear();
  if (pos_ >= size_) return false;
  std::FILE* f = file_.get();
  for (;;) {
    const int c = std::getc(f);
    if (c == EOF) {
      if (std::ferror(f)) fail(path_, "cannot read: " + errnoText(errno));
      break;
    }
    ++pos_;
    if (c == '\n') break;
    if (line->size() >= max_len) fail(path_, "malformed header: line " + num(lines_ + 1) + " is too long");
    line->push_back(static_cast<char>(c));
  }
  ++lines_;
  if (!line->empty() && line->back() == '\r') line->pop_back();
  return true;
}

void InputFile::require(std::uint64_t n, const char* what) const {
  if (n > remaining())
    fail(path_, std::string("truncated data: ") + what + " needs " + num(n) + " more bytes, the file holds " +
                    num(remaining()));
}

void InputFile::read(void* dst, std::size_t n, const char* what) {
  require(n, what);
  if (n == 0) return;
  if (buffered_) {
    std::memcpy(dst, buf_.data() + bpos_, n);
    bpos_ += n;
    return;
  }
  const std::size_t got = std::fread(dst, 1, n, file_.get());
  pos_ += got;
  if (got != n)
    fail(path_, std::string("truncated data: ") + what + ": expected " + num(n) + " bytes, read " + num(got));
}

void InputFile::skip(std::uint64_t n, const char* what) {
  require(n, what);
  if (buffered_) {
    bpos_ += n;
    return;
  }
  if (::fseeko(file_.get(), static_cast<off_t>(n), SEEK_CUR) != 0)
    fail(path_, "cannot read: " + errnoText(errno));
  pos_ += n;
}

const std::uint8_t* InputFile::take(std::size_t n, const char* what) {
  loadRest();
  require(n, what);
  const auto* p = reinterpret_cast<const std::uint8_t*>(buf_.data() + bpos_);
  bpos_ += n;
  return p;
}

std::string_view InputFile::rest() {
  loadRest();
  return std::string_view(buf_).substr(bpos_);
}

void InputFile::loadRest() {
  if (buffered_) return;
  const std::uint64_t n = remaining();
  buf_.resize(n);
  const std::size_t got = n ? std::fread(buf_.data(), 1, n, file_.get()) : 0;
  if (got != n) fail(path_, "truncated data: expected " + num(n) + " bytes, read " + num(got));
  pos_ += got;
  buffered_ = true;
  bpos_ = 0;
}

// ------------------------------------------------------------------------------------------
// The decimals of text columns

int fixedDecimals(std::string_view token) {
  if (token.find_first_of("eE") != std::string_view::npos &&
      token.find_first_of("nNiIxX") == std::string_view::npos)
    return -1;
  const std::size_t dot = token.find('.');
  if (dot == std::string_view::npos || token.find_first_of("nNiIxX") != std::string_view::npos) return 0;
  std::size_t k = dot + 1;
  while (k < token.size() && token[k] >= '0' && token[k] <= '9') ++k;
  return k == token.size() ? static_cast<int>(k - dot - 1) : 0;
}

void DecimalsSeen::store(FileExtras& extras, const std::vector<std::string>& names) const {
  extras.text_decimals.clear();
  for (std::size_t k = 0; k < least.size() && k < names.size(); ++k) {
    const std::vector<std::int8_t>& rows = each[k];
    const bool mixed =
        std::any_of(rows.begin(), rows.end(), [&](std::int8_t d) { return d != rows.front(); });
    const int fewest = least[k] == std::numeric_limits<int>::max() ? 0 : least[k];
    if (mixed)  // (a mixed column written with its fewest decimals respelt the others: 780 of 900 rows)
      extras.text_decimals.push_back({names[k], fewest, exponents[k] != 0, rows});
    else if (fewest > 0)
      extras.text_decimals.push_back({names[k], fewest, exponents[k] != 0, {}});
  }
}

std::vector<FileExtras::TextColumn> decimalsOf(const FileExtras& extras,
                                               const std::vector<const pcl::PCLPointField*>& fields) {
  std::vector<FileExtras::TextColumn> out(fields.size());
  if (extras.text_decimals.empty()) return out;
  for (std::size_t k = 0; k < fields.size(); ++k)
    for (const auto& col : extras.text_decimals)
      if (fields[k] && fields[k]->name == col.field) out[k] = col;
  return out;
}

}  // namespace hgd::io_internal
