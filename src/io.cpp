// PLY, PCD and OBJ reading and writing with our own bounds-checked parsers (PCL's readers print
// to the console, cannot report why they failed, and load double-coordinate PLY as zeros).
#include "hgdeform/io.h"

#include <fcntl.h>
#include <pcl/io/lzf.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <random>
#include <string_view>
#include <system_error>
#include <type_traits>
#include <utility>
#include <vector>

#include "hgdeform/fields.h"

namespace hgd {
namespace {

namespace fs = std::filesystem;
using Field = pcl::PCLPointField;

constexpr bool kHostBigEndian = __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__;
constexpr std::size_t kMaxHeaderLine = std::size_t{1} << 20;
constexpr std::size_t kFlushBytes = std::size_t{1} << 16;

// ------------------------------------------------------------------------------------------
// Small helpers

[[noreturn]] void fail(const std::string& path, const std::string& problem) {
  throw IoError(path + ": " + problem);
}

std::string errnoText(int e) {
  return std::strerror(e);
}

std::string num(std::uint64_t v) {
  return std::to_string(v);
}

/// A short, printable excerpt of untrusted text for messages.
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

std::vector<std::string_view> splitWords(std::string_view s) {
  std::vector<std::string_view> words;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && isSpace(s[i])) ++i;
    const std::size_t b = i;
    while (i < s.size() && !isSpace(s[i])) ++i;
    if (i > b) words.push_back(s.substr(b, i - b));
  }
  return words;
}

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

bool mulOk(std::uint64_t a, std::uint64_t b, std::uint64_t* r) {
  return !__builtin_mul_overflow(a, b, r);
}
bool addOk(std::uint64_t a, std::uint64_t b, std::uint64_t* r) {
  return !__builtin_add_overflow(a, b, r);
}

std::size_t fieldCount(const Field& f) {
  return std::max<std::size_t>(f.count, 1);
}

bool parseU64(std::string_view s, std::uint64_t* v) {
  if (!s.empty() && s[0] == '+') s.remove_prefix(1);
  if (s.empty()) return false;
  const char* e = s.data() + s.size();
  const auto r = std::from_chars(s.data(), e, *v);
  return r.ec == std::errc() && r.ptr == e;
}

template <typename T>
bool parseFloating(std::string_view s, T* v) {
  if (!s.empty() && s[0] == '+') s.remove_prefix(1);
  if (s.empty()) return false;
  const char* e = s.data() + s.size();
  const auto r = std::from_chars(s.data(), e, *v);
  if (r.ptr != e) return false;
  if (r.ec == std::errc()) return true;
  if (r.ec == std::errc::result_out_of_range) {  // overflow to ±inf or underflow to 0, as strtod
    const std::string copy(s);
    if constexpr (std::is_same_v<T, float>)
      *v = std::strtof(copy.c_str(), nullptr);
    else
      *v = std::strtod(copy.c_str(), nullptr);
    return true;
  }
  return false;
}

enum class Parse { Ok, Bad, Range };

/// An integer token; integral floating-point spellings ("255.0", "1e3") are accepted too.
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

template <typename T>
Parse storeInteger(long long v, std::uint8_t* dst) {
  if (v < static_cast<long long>(std::numeric_limits<T>::min()) ||
      v > static_cast<long long>(std::numeric_limits<T>::max()))
    return Parse::Range;
  const T t = static_cast<T>(v);
  std::memcpy(dst, &t, sizeof t);
  return Parse::Ok;
}

/// A FLOAT32 field called rgb or rgba: a colour packed into a float's bytes, which PCL's ascii
/// PCD writer stores as an unsigned integer (the bits), not as a float.
bool packedColour(const Field& f) {
  return f.datatype == Field::FLOAT32 && (f.name == "rgb" || f.name == "rgba");
}

/// An ascii token of nothing but decimal digits.
bool plainUnsigned(std::string_view tok) {
  return !tok.empty() && std::all_of(tok.begin(), tok.end(), [](char ch) { return ch >= '0' && ch <= '9'; });
}

/// Parses an ascii token into `dst` as a value of pcl datatype `type` (host byte order).
Parse parseInto(std::string_view tok, std::uint8_t type, std::uint8_t* dst) {
  if (type == Field::FLOAT32) {
    float f = 0;
    if (!parseFloating(tok, &f)) return Parse::Bad;
    std::memcpy(dst, &f, sizeof f);
    return Parse::Ok;
  }
  if (type == Field::FLOAT64) {
    double d = 0;
    if (!parseFloating(tok, &d)) return Parse::Bad;
    std::memcpy(dst, &d, sizeof d);
    return Parse::Ok;
  }
  long long v = 0;
  const Parse p = parseInteger(tok, &v);
  if (p != Parse::Ok) return p;
  switch (type) {
    case Field::INT8: return storeInteger<std::int8_t>(v, dst);
    case Field::UINT8: return storeInteger<std::uint8_t>(v, dst);
    case Field::INT16: return storeInteger<std::int16_t>(v, dst);
    case Field::UINT16: return storeInteger<std::uint16_t>(v, dst);
    case Field::INT32: return storeInteger<std::int32_t>(v, dst);
    case Field::UINT32: return storeInteger<std::uint32_t>(v, dst);
    default: return Parse::Bad;
  }
}

template <typename T>
T loadAs(const std::uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

/// A binary value of pcl datatype `type`, byte-swapped if `swap`, as a double.
double loadDouble(const std::uint8_t* p, std::uint8_t type, bool swap) {
  std::uint8_t tmp[8] = {};
  const std::size_t n = datatypeSize(type);
  std::memcpy(tmp, p, n);
  if (swap) std::reverse(tmp, tmp + n);
  switch (type) {
    case Field::INT8: return loadAs<std::int8_t>(tmp);
    case Field::UINT8: return loadAs<std::uint8_t>(tmp);
    case Field::INT16: return loadAs<std::int16_t>(tmp);
    case Field::UINT16: return loadAs<std::uint16_t>(tmp);
    case Field::INT32: return loadAs<std::int32_t>(tmp);
    case Field::UINT32: return loadAs<std::uint32_t>(tmp);
    case Field::FLOAT32: return loadAs<float>(tmp);
    case Field::FLOAT64: return loadAs<double>(tmp);
    default: return std::numeric_limits<double>::quiet_NaN();
  }
}

bool isIntegerType(std::uint8_t type) {
  return type == Field::INT8 || type == Field::UINT8 || type == Field::INT16 || type == Field::UINT16 ||
         type == Field::INT32 || type == Field::UINT32;
}

/// Byte-swaps every value of every field of every point in place.
void swapCloud(pcl::PCLPointCloud2& cloud) {
  const std::size_t n = static_cast<std::size_t>(cloud.width) * cloud.height;
  for (std::size_t i = 0; i < n; ++i) {
    std::uint8_t* pt = cloud.data.data() + i * cloud.point_step;
    for (const auto& f : cloud.fields) {
      const std::size_t sz = datatypeSize(f.datatype);
      if (sz < 2) continue;
      for (std::size_t k = 0; k < fieldCount(f); ++k)
        std::reverse(pt + f.offset + k * sz, pt + f.offset + (k + 1) * sz);
    }
  }
}

/// False if any x, y or z value is NaN or infinite.
bool computeDense(const pcl::PCLPointCloud2& cloud) {
  const XyzFields xyz = findXyzFields(cloud);
  if (!xyz.hasXyz()) return true;
  const std::size_t n = static_cast<std::size_t>(cloud.width) * cloud.height;
  for (const int idx : {xyz.x, xyz.y, xyz.z}) {
    const Field& f = cloud.fields[idx];
    if (f.datatype != Field::FLOAT32 && f.datatype != Field::FLOAT64) continue;
    for (std::size_t i = 0; i < n; ++i)
      if (!std::isfinite(readValue(cloud, i, f))) return false;
  }
  return true;
}

// ------------------------------------------------------------------------------------------
// Input

/// A file opened for reading: header lines through stdio, then the body either read straight
/// into its destination or loaded once into memory. Every read is bounds-checked against the
/// file's size.
class InputFile {
 public:
  explicit InputFile(std::string path) : path_(std::move(path)) {
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
      pos_ = 3;
    else if (::fseeko(f, 0, SEEK_SET) != 0)
      fail(path_, "cannot read: " + errnoText(errno));
  }

  const std::string& path() const { return path_; }
  std::size_t linesRead() const { return lines_; }

  std::uint64_t remaining() const {
    if (buffered_) return buf_.size() - bpos_;
    return pos_ < size_ ? size_ - pos_ : 0;
  }

  /// Reads one header line without its "\n" or "\r\n"; false at the end of the file.
  bool readLine(std::string* line, std::size_t max_len) {
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

  void require(std::uint64_t n, const char* what) const {
    if (n > remaining())
      fail(path_, std::string("truncated data: ") + what + " needs " + num(n) +
                      " more bytes, the file holds " + num(remaining()));
  }

  void read(void* dst, std::size_t n, const char* what) {
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
      fail(path_,
           std::string("truncated data: ") + what + ": expected " + num(n) + " bytes, read " + num(got));
  }

  void skip(std::uint64_t n, const char* what) {
    require(n, what);
    if (buffered_) {
      bpos_ += n;
      return;
    }
    if (::fseeko(file_.get(), static_cast<off_t>(n), SEEK_CUR) != 0)
      fail(path_, "cannot read: " + errnoText(errno));
    pos_ += n;
  }

  /// The next `n` bytes of the (in-memory) body.
  const std::uint8_t* take(std::size_t n, const char* what) {
    loadRest();
    require(n, what);
    const auto* p = reinterpret_cast<const std::uint8_t*>(buf_.data() + bpos_);
    bpos_ += n;
    return p;
  }

  /// The rest of the file, loaded in memory.
  std::string_view rest() {
    loadRest();
    return std::string_view(buf_).substr(bpos_);
  }

 private:
  void loadRest() {
    if (buffered_) return;
    const std::uint64_t n = remaining();
    buf_.resize(n);
    const std::size_t got = n ? std::fread(buf_.data(), 1, n, file_.get()) : 0;
    if (got != n) fail(path_, "truncated data: expected " + num(n) + " bytes, read " + num(got));
    pos_ += got;
    buffered_ = true;
    bpos_ = 0;
  }

  struct Closer {
    void operator()(std::FILE* f) const { std::fclose(f); }
  };
  std::string path_;
  std::unique_ptr<std::FILE, Closer> file_;
  std::uint64_t size_ = 0, pos_ = 0;
  std::size_t lines_ = 0;
  bool buffered_ = false;
  std::string buf_;
  std::size_t bpos_ = 0;
};

/// Whitespace-separated tokens of ascii data, line by line (blank lines skipped).
class Lexer {
 public:
  Lexer(std::string_view text, std::size_t lines_before)
      : p_(text.data()), end_(text.data() + text.size()), line_(lines_before) {}

  bool nextLine() {
    while (p_ < end_) {
      const auto* nl = static_cast<const char*>(std::memchr(p_, '\n', static_cast<std::size_t>(end_ - p_)));
      cur_ = p_;
      lend_ = nl ? nl : end_;
      p_ = nl ? nl + 1 : end_;
      ++line_;
      while (cur_ < lend_ && isSpace(*cur_)) ++cur_;
      lbeg_ = cur_;
      if (cur_ < lend_) return true;
    }
    cur_ = lend_ = end_;
    return false;
  }

  /// The next token of the current line; empty at its end.
  std::string_view token() {
    while (cur_ < lend_ && isSpace(*cur_)) ++cur_;
    const char* b = cur_;
    while (cur_ < lend_ && !isSpace(*cur_)) ++cur_;
    return {b, static_cast<std::size_t>(cur_ - b)};
  }

  bool atLineEnd() {
    while (cur_ < lend_ && isSpace(*cur_)) ++cur_;
    return cur_ == lend_;
  }

  std::size_t countTokens() const {
    std::size_t n = 0;
    for (const char* c = cur_; c < lend_;) {
      while (c < lend_ && isSpace(*c)) ++c;
      if (c == lend_) break;
      ++n;
      while (c < lend_ && !isSpace(*c)) ++c;
    }
    return n;
  }

  char peek() const { return cur_ < lend_ ? *cur_ : '\0'; }
  std::size_t line() const { return line_; }
  /// The current line from its first non-blank character, without the line end.
  std::string_view lineText() const {
    const char* e = lend_;
    if (e > lbeg_ && e[-1] == '\r') --e;
    return {lbeg_, static_cast<std::size_t>(e - lbeg_)};
  }

 private:
  const char* p_;
  const char* end_;
  const char* cur_ = nullptr;
  const char* lend_ = nullptr;
  const char* lbeg_ = nullptr;
  std::size_t line_;
};

// ------------------------------------------------------------------------------------------
// PLY

struct PlyType {
  const char* name;
  std::uint8_t type;
};
constexpr PlyType kPlyTypes[] = {
    {"char", Field::INT8},       {"uchar", Field::UINT8},    {"short", Field::INT16},
    {"ushort", Field::UINT16},   {"int", Field::INT32},      {"uint", Field::UINT32},
    {"float", Field::FLOAT32},   {"double", Field::FLOAT64}, {"int8", Field::INT8},
    {"uint8", Field::UINT8},     {"int16", Field::INT16},    {"uint16", Field::UINT16},
    {"int32", Field::INT32},     {"uint32", Field::UINT32},  {"float32", Field::FLOAT32},
    {"float64", Field::FLOAT64},
};

bool plyTypeFromName(std::string_view name, std::uint8_t* type) {
  for (const auto& t : kPlyTypes)
    if (name == t.name) {
      *type = t.type;
      return true;
    }
  return false;
}

const char* plyTypeName(std::uint8_t type) {
  for (const auto& t : kPlyTypes)
    if (t.type == type) return t.name;  // the first (classic) spelling
  return "?";
}

struct PlyProperty {
  std::string name;
  std::uint8_t type = 0;  // value type (list items for lists)
  bool list = false;
  std::uint8_t count_type = 0;
};

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> props;
  bool allScalar() const {
    return std::none_of(props.begin(), props.end(), [](const PlyProperty& p) { return p.list; });
  }
  /// Bytes of one binary record without list items.
  std::uint64_t minBytes() const {
    std::uint64_t n = 0;
    for (const auto& p : props) n += datatypeSize(p.list ? p.count_type : p.type);
    return n;
  }
};

enum class PlyFormat { Ascii, BinaryLE, BinaryBE };

Shape readPly(const std::string& path) {
  InputFile in(path);
  std::string line;
  if (!in.readLine(&line, 64) || splitWords(line).size() != 1 || splitWords(line)[0] != "ply")
    fail(path, "malformed header: first line is " + excerpt(line) + ", expected 'ply'");

  PlyFormat format = PlyFormat::Ascii;
  bool have_format = false, ended = false;
  std::vector<PlyElement> elements;
  std::vector<std::string> comments;
  while (in.readLine(&line, kMaxHeaderLine)) {
    const auto bad = [&](const std::string& why) {
      fail(path, "malformed header: line " + num(in.linesRead()) + ": " + why + " (" + excerpt(line) + ")");
    };
    const auto words = splitWords(line);
    if (words.empty()) continue;
    const std::string_view kw = words[0];
    if (kw == "comment" || kw == "obj_info") {
      if (line.rfind("comment written by hgdeform", 0) != 0) comments.push_back(line);
      continue;
    }
    if (kw == "end_header") {
      ended = true;
      break;
    }
    if (kw == "format") {
      if (words.size() != 3) bad("expected 'format <type> 1.0'");
      if (have_format) bad("second format line");
      if (words[1] == "ascii")
        format = PlyFormat::Ascii;
      else if (words[1] == "binary_little_endian")
        format = PlyFormat::BinaryLE;
      else if (words[1] == "binary_big_endian")
        format = PlyFormat::BinaryBE;
      else
        fail(path, "unsupported PLY format " + excerpt(words[1]));
      if (words[2] != "1.0" && words[2] != "1") fail(path, "unsupported PLY version " + excerpt(words[2]));
      have_format = true;
    } else if (kw == "element") {
      PlyElement el;
      if (words.size() != 3 || !parseU64(words[2], &el.count)) bad("expected 'element <name> <count>'");
      el.name = std::string(words[1]);
      for (const auto& e : elements)
        if (e.name == el.name) bad("second element '" + el.name + "'");
      elements.push_back(std::move(el));
    } else if (kw == "property") {
      if (elements.empty()) bad("property before any element");
      PlyProperty p;
      if (words.size() == 5 && words[1] == "list") {
        p.list = true;
        if (!plyTypeFromName(words[2], &p.count_type) || !plyTypeFromName(words[3], &p.type))
          fail(path, "unsupported PLY property type in line " + num(in.linesRead()) + " " + excerpt(line));
        if (!isIntegerType(p.count_type))
          fail(path, "unsupported PLY list count type in line " + num(in.linesRead()) + " " + excerpt(line));
        p.name = std::string(words[4]);
      } else if (words.size() == 3 && words[1] != "list") {
        if (!plyTypeFromName(words[1], &p.type))
          fail(path, "unsupported PLY property type in line " + num(in.linesRead()) + " " + excerpt(line));
        p.name = std::string(words[2]);
      } else {
        bad("expected 'property <type> <name>' or 'property list <type> <type> <name>'");
      }
      for (const auto& q : elements.back().props)
        if (q.name == p.name) bad("second property '" + p.name + "'");
      elements.back().props.push_back(std::move(p));
    } else {
      bad("unknown keyword");
    }
  }
  if (!ended) fail(path, "malformed header: no end_header line");
  if (!have_format) fail(path, "malformed header: no format line");

  int vertex_el = -1, face_el = -1, face_prop = -1;
  for (std::size_t e = 0; e < elements.size(); ++e) {
    if (elements[e].name == "vertex") vertex_el = static_cast<int>(e);
    if (elements[e].name == "face") {
      for (std::size_t k = 0; k < elements[e].props.size(); ++k) {
        const auto& p = elements[e].props[k];
        if (p.list && (p.name == "vertex_indices" || p.name == "vertex_index")) {
          face_el = static_cast<int>(e);
          face_prop = static_cast<int>(k);
          break;
        }
      }
    }
  }
  if (vertex_el < 0) fail(path, "no points: the file has no vertex element");
  const PlyElement& vel = elements[vertex_el];
  const auto hasScalar = [&](const char* name) {
    return std::any_of(vel.props.begin(), vel.props.end(),
                       [&](const PlyProperty& p) { return !p.list && p.name == name; });
  };
  if (!hasScalar("x") || !hasScalar("y") || !hasScalar("z"))
    fail(path, "no x/y/z fields: the vertex element has no scalar x, y and z properties");
  if (vel.count == 0) fail(path, "no points: the vertex element is empty");

  // Check the declared counts against the data actually present, before allocating anything.
  const bool binary = format != PlyFormat::Ascii;
  const std::uint64_t avail = in.remaining();
  std::uint64_t total = 0;
  for (const auto& el : elements) {
    const std::uint64_t per = binary ? el.minBytes() : el.props.size();
    std::uint64_t need = 0;
    if (!mulOk(el.count, binary ? per : 2 * per, &need) || !addOk(total, need, &total))
      fail(path, "truncated data: header declares " + num(el.count) + " '" + el.name +
                     "' records, more than any file can hold");
    if ((binary && total > avail) || (!binary && total > avail + 1))
      fail(path, "truncated data: header declares " + num(el.count) + " '" + el.name +
                     "' records (at least " + num(need) + " bytes" + (binary ? "" : " of text") +
                     "), the file holds " + num(avail) + " bytes of data");
  }
  if (vel.count > std::numeric_limits<std::uint32_t>::max())
    fail(path, "unsupported: " + num(vel.count) + " vertices (at most 4294967295)");

  Shape shape;
  pcl::PCLPointCloud2& cloud = shape.cloud;
  // Everything not held in the cloud's fields or the polygons is kept aside (FileExtras).
  std::vector<FileExtras::Element> extra(elements.size());
  bool any_extra = false;
  for (std::size_t e = 0; e < elements.size(); ++e) {
    FileExtras::Element& x = extra[e];
    x.name = elements[e].name;
    x.count = elements[e].count;
    for (std::size_t k = 0; k < elements[e].props.size(); ++k) {
      const PlyProperty& p = elements[e].props[k];
      x.props.push_back({p.name, p.type, p.list, p.count_type});
      const bool held = (static_cast<int>(e) == vertex_el && !p.list) ||
                        (static_cast<int>(e) == face_el && static_cast<int>(k) == face_prop);
      x.kept.push_back(held ? 0 : 1);
      any_extra = any_extra || !held;
    }
    any_extra = any_extra || (static_cast<int>(e) != vertex_el && static_cast<int>(e) != face_el);
  }
  std::vector<std::uint32_t> offsets(vel.props.size(), 0);
  std::uint32_t step = 0;
  for (std::size_t k = 0; k < vel.props.size(); ++k) {
    const auto& p = vel.props[k];
    if (p.list) continue;
    Field f;
    f.name = p.name;
    f.offset = step;
    f.datatype = p.type;
    f.count = 1;
    offsets[k] = step;
    step += static_cast<std::uint32_t>(datatypeSize(p.type));
    cloud.fields.push_back(f);
  }
  const std::uint32_t nverts = static_cast<std::uint32_t>(vel.count);
  cloud.width = nverts;
  cloud.height = 1;
  cloud.point_step = step;
  cloud.row_step = step * nverts;
  cloud.is_bigendian = false;
  cloud.data.resize(static_cast<std::size_t>(nverts) * step);

  if (binary) {
    const bool swap = (format == PlyFormat::BinaryBE) != kHostBigEndian;
    for (std::size_t e = 0; e < elements.size(); ++e) {
      const PlyElement& el = elements[e];
      if (el.props.empty() || el.count == 0) continue;
      const bool is_vertex = static_cast<int>(e) == vertex_el;
      std::vector<double>& kept_values = extra[e].values;
      if (el.allScalar()) {
        if (is_vertex) {
          in.read(cloud.data.data(), cloud.data.size(), "vertex data");
        } else {
          const std::uint8_t* d = in.take(el.count * el.minBytes(), "element data");
          kept_values.reserve(el.count * el.props.size());
          for (std::uint64_t r = 0; r < el.count; ++r)
            for (const PlyProperty& p : el.props) {
              kept_values.push_back(loadDouble(d, p.type, swap));
              d += datatypeSize(p.type);
            }
        }
        continue;
      }
      // Each face takes at least a count and three indices: reserve no more than the data can hold.
      if (static_cast<int>(e) == face_el)
        shape.polygons.reserve(std::min<std::uint64_t>(el.count, in.remaining() / 4));
      for (std::uint64_t r = 0; r < el.count; ++r) {
        std::uint8_t* out = is_vertex ? cloud.data.data() + r * step : nullptr;
        for (std::size_t k = 0; k < el.props.size(); ++k) {
          const PlyProperty& p = el.props[k];
          const std::size_t isz = datatypeSize(p.type);
          if (!p.list) {
            const std::uint8_t* src = in.take(isz, "element data");
            if (out)
              std::memcpy(out + offsets[k], src, isz);
            else if (extra[e].kept[k])
              kept_values.push_back(loadDouble(src, p.type, swap));
            continue;
          }
          const double n = loadDouble(in.take(datatypeSize(p.count_type), "list length"), p.count_type, swap);
          if (n < 0) fail(path, "malformed data: negative list length in '" + el.name + "' record " + num(r));
          const auto len = static_cast<std::uint64_t>(n);
          if (static_cast<int>(e) != face_el || static_cast<int>(k) != face_prop) {
            const std::uint8_t* items = in.take(len * isz, "list data");
            kept_values.push_back(n);
            for (std::uint64_t j = 0; j < len; ++j)
              kept_values.push_back(loadDouble(items + j * isz, p.type, swap));
            continue;
          }
          if (len < 3)
            fail(path, "bad face: face " + num(r) + " has " + num(len) + " vertices, at least 3 needed");
          const std::uint8_t* items = in.take(len * isz, "face data");
          pcl::Vertices poly;
          poly.vertices.resize(len);
          for (std::uint64_t j = 0; j < len; ++j) {
            const double idx = loadDouble(items + j * isz, p.type, swap);
            if (!(idx >= 0 && idx < nverts && idx == std::floor(idx)))
              fail(path, "bad face index " + std::to_string(idx) + " in face " + num(r) + " (" + num(nverts) +
                             " vertices)");
            poly.vertices[j] = static_cast<pcl::index_t>(idx);
          }
          shape.polygons.push_back(std::move(poly));
        }
      }
    }
    if (swap) swapCloud(cloud);
    // Data beyond the last element that could hold another vertex: the header's counts are
    // wrong, and reading on would silently drop points.
    if (in.remaining() > 1 && in.remaining() >= vel.minBytes())
      fail(path, "malformed data: " + num(in.remaining()) +
                     " bytes after the last element: more data than the header declares (" + num(vel.count) +
                     " vertices)");
  } else {
    Lexer lex(in.rest(), in.linesRead());
    for (std::size_t e = 0; e < elements.size(); ++e) {
      const PlyElement& el = elements[e];
      if (el.props.empty()) continue;
      const bool is_vertex = static_cast<int>(e) == vertex_el;
      for (std::uint64_t r = 0; r < el.count; ++r) {
        if (!lex.nextLine())
          fail(path,
               "truncated data: expected " + num(el.count) + " '" + el.name + "' records, found " + num(r));
        std::uint8_t* out = is_vertex ? cloud.data.data() + r * step : nullptr;
        const auto next = [&](const PlyProperty& p) {
          const std::string_view tok = lex.token();
          if (tok.empty())
            fail(path, "truncated data: line " + num(lex.line()) + " has too few values for property '" +
                           p.name + "' of element '" + el.name + "'");
          return tok;
        };
        const auto nonNumeric = [&](std::string_view tok, const PlyProperty& p) {
          fail(path, "non-numeric value " + excerpt(tok) + " at line " + num(lex.line()) + " (property '" +
                         p.name + "' of element '" + el.name + "')");
        };
        for (std::size_t k = 0; k < el.props.size(); ++k) {
          const PlyProperty& p = el.props[k];
          std::uint8_t scratch[8];
          if (!p.list) {
            const std::string_view tok = next(p);
            const Parse st = parseInto(tok, p.type, out ? out + offsets[k] : scratch);
            if (st == Parse::Bad) nonNumeric(tok, p);
            if (st == Parse::Range)
              fail(path, "value out of range " + excerpt(tok) + " at line " + num(lex.line()) +
                             " for property '" + p.name + "' of type " + plyTypeName(p.type));
            if (!out && extra[e].kept[k]) extra[e].values.push_back(loadDouble(scratch, p.type, false));
            continue;
          }
          const std::string_view ctok = next(p);
          long long len = 0;
          if (parseInteger(ctok, &len) != Parse::Ok) nonNumeric(ctok, p);
          if (len < 0)
            fail(path, "malformed data: negative list length at line " + num(lex.line()) + " (element '" +
                           el.name + "')");
          const bool is_face = static_cast<int>(e) == face_el && static_cast<int>(k) == face_prop;
          if (is_face && len < 3)
            fail(path, "bad face: face " + num(r) + " at line " + num(lex.line()) + " has " +
                           std::to_string(len) + " vertices, at least 3 needed");
          pcl::Vertices poly;
          if (!is_face) extra[e].values.push_back(static_cast<double>(len));
          for (long long j = 0; j < len; ++j) {
            const std::string_view tok = next(p);
            if (!is_face) {  // as the declared type holds it (in range; text may carry more digits)
              std::uint8_t item[8];
              const Parse st = parseInto(tok, p.type, item);
              if (st == Parse::Bad) nonNumeric(tok, p);
              if (st == Parse::Range)
                fail(path, "value out of range " + excerpt(tok) + " at line " + num(lex.line()) +
                               " for property '" + p.name + "' of type " + plyTypeName(p.type));
              extra[e].values.push_back(loadDouble(item, p.type, false));
              continue;
            }
            double v = 0;
            if (!parseFloating(tok, &v)) nonNumeric(tok, p);
            if (!(v >= 0 && v < nverts && v == std::floor(v)))
              fail(path, "bad face index " + excerpt(tok) + " at line " + num(lex.line()) + " (" +
                             num(nverts) + " vertices)");
            poly.vertices.push_back(static_cast<pcl::index_t>(v));
          }
          if (is_face) shape.polygons.push_back(std::move(poly));
        }
        if (!lex.atLineEnd())
          fail(path, "malformed data: line " + num(lex.line()) +
                         " has more values than the header declares for " + "element '" + el.name + "'");
      }
    }
    if (lex.nextLine())
      fail(path, "malformed data: line " + num(lex.line()) + ": more data than the header declares (" +
                     num(vel.count) + " vertices)");
  }

  cloud.is_dense = computeDense(cloud);
  shape.extras.ply_comments = std::move(comments);
  if (any_extra) shape.extras.ply_elements = std::move(extra);
  return shape;
}

// ------------------------------------------------------------------------------------------
// PCD

Shape readPcd(const std::string& path) {
  InputFile in(path);
  std::vector<std::string> names;
  std::vector<std::uint64_t> sizes, counts;
  std::vector<char> types;
  bool have_fields = false, have_size = false, have_type = false, have_count = false, have_width = false,
       have_height = false, have_points = false, have_viewpoint = false, have_version = false,
       have_data = false;
  std::uint64_t width = 0, height = 0, points = 0;
  double viewpoint[7] = {0, 0, 0, 1, 0, 0, 0};
  std::string data_kind, line;

  while (in.readLine(&line, kMaxHeaderLine)) {
    const auto bad = [&](const std::string& why) {
      fail(path, "malformed header: line " + num(in.linesRead()) + ": " + why + " (" + excerpt(line) + ")");
    };
    const auto words = splitWords(line);
    if (words.empty() || words[0][0] == '#') continue;
    std::string kw = lower(words[0]);
    const auto once = [&](bool* seen) {
      if (*seen) bad("repeated " + kw);
      *seen = true;
    };
    const auto numbers = [&](std::vector<std::uint64_t>* out) {
      if (words.size() < 2) bad("no values");
      for (std::size_t i = 1; i < words.size(); ++i) {
        std::uint64_t v = 0;
        if (!parseU64(words[i], &v)) bad("bad number " + excerpt(words[i]));
        out->push_back(v);
      }
    };
    const auto single = [&](std::uint64_t* out) {
      if (words.size() != 2 || !parseU64(words[1], out)) bad("expected one non-negative integer");
    };
    if (kw == "version") {
      once(&have_version);
      static const char* const known[] = {"0.7", ".7", "0.6", ".6", "0.5", ".5"};
      if (words.size() != 2) bad("expected 'VERSION <version>'");
      if (std::none_of(std::begin(known), std::end(known), [&](const char* v) { return words[1] == v; }))
        fail(path, "unsupported PCD version " + excerpt(words[1]));
    } else if (kw == "fields" || kw == "columns") {
      once(&have_fields);
      if (words.size() < 2) bad("no field names");
      for (std::size_t i = 1; i < words.size(); ++i) names.emplace_back(words[i]);
    } else if (kw == "size") {
      once(&have_size);
      numbers(&sizes);
    } else if (kw == "type") {
      once(&have_type);
      if (words.size() < 2) bad("no types");
      for (std::size_t i = 1; i < words.size(); ++i) {
        if (words[i].size() != 1) bad("bad type " + excerpt(words[i]));
        types.push_back(static_cast<char>(std::toupper(static_cast<unsigned char>(words[i][0]))));
      }
    } else if (kw == "count") {
      once(&have_count);
      numbers(&counts);
    } else if (kw == "width") {
      once(&have_width);
      single(&width);
    } else if (kw == "height") {
      once(&have_height);
      single(&height);
    } else if (kw == "points") {
      once(&have_points);
      single(&points);
    } else if (kw == "viewpoint") {
      once(&have_viewpoint);
      if (words.size() != 8) bad("expected 7 numbers");
      for (std::size_t i = 0; i < 7; ++i)
        if (!parseFloating(words[i + 1], &viewpoint[i])) bad("bad number " + excerpt(words[i + 1]));
    } else if (kw == "data") {
      if (words.size() != 2) bad("expected 'DATA ascii|binary|binary_compressed'");
      data_kind = lower(words[1]);
      have_data = true;
      break;
    } else {
      bad("unknown keyword");
    }
  }
  if (!have_data) fail(path, "malformed header: no DATA line");
  if (!have_fields) fail(path, "malformed header: no FIELDS line");
  if (!have_size) fail(path, "malformed header: no SIZE line");
  if (!have_type) fail(path, "malformed header: no TYPE line");
  if (!have_count) counts.assign(names.size(), 1);
  if (sizes.size() != names.size() || types.size() != names.size() || counts.size() != names.size())
    fail(path, "malformed header: FIELDS has " + num(names.size()) + " entries but SIZE has " +
                   num(sizes.size()) + ", TYPE " + num(types.size()) + " and COUNT " + num(counts.size()));
  if (have_width) {
    if (!have_height) height = 1;
    std::uint64_t wh = 0;
    if (!mulOk(width, height, &wh)) fail(path, "malformed header: WIDTH x HEIGHT overflows");
    if (have_points && points != wh)
      fail(path, "malformed header: POINTS " + num(points) + " differs from WIDTH x HEIGHT = " + num(wh));
    points = wh;
  } else if (have_points) {
    width = points;
    height = 1;
  } else {
    fail(path, "malformed header: no WIDTH or POINTS line");
  }
  if (data_kind != "ascii" && data_kind != "binary" && data_kind != "binary_compressed")
    fail(path, "unsupported PCD data encoding " + excerpt(data_kind));

  Shape shape;
  pcl::PCLPointCloud2& cloud = shape.cloud;
  std::uint64_t step = 0, pad_bytes = 0, ascii_values = 0, ascii_values_pad = 0;
  for (std::size_t i = 0; i < names.size(); ++i) {
    const char t = types[i];
    const std::uint64_t s = sizes[i];
    std::uint8_t dt = 0;
    if (t == 'I' && s == 1)
      dt = Field::INT8;
    else if (t == 'I' && s == 2)
      dt = Field::INT16;
    else if (t == 'I' && s == 4)
      dt = Field::INT32;
    else if (t == 'U' && s == 1)
      dt = Field::UINT8;
    else if (t == 'U' && s == 2)
      dt = Field::UINT16;
    else if (t == 'U' && s == 4)
      dt = Field::UINT32;
    else if (t == 'F' && s == 4)
      dt = Field::FLOAT32;
    else if (t == 'F' && s == 8)
      dt = Field::FLOAT64;
    else if (t != 'I' && t != 'U' && t != 'F')
      fail(path, "malformed header: field '" + names[i] + "' has type " + std::string(1, t) +
                     " (expected I, U or F)");
    else
      fail(path, "unsupported field type " + std::string(1, t) + num(s) + " for field '" + names[i] + "'");
    if (counts[i] == 0 || counts[i] > std::numeric_limits<std::uint32_t>::max())
      fail(path, "malformed header: field '" + names[i] + "' has COUNT " + num(counts[i]));
    Field f;
    f.name = names[i];
    f.offset =
        static_cast<std::uint32_t>(std::min<std::uint64_t>(step, std::numeric_limits<std::uint32_t>::max()));
    f.datatype = dt;
    f.count = static_cast<std::uint32_t>(counts[i]);
    cloud.fields.push_back(f);
    step += s * counts[i];  // <= 8 * 2^32 per field: no overflow for any plausible number of fields
    ascii_values_pad += counts[i];
    if (f.name == "_")
      pad_bytes += s * counts[i];
    else
      ascii_values += counts[i];
    if (step > std::numeric_limits<std::uint32_t>::max())
      fail(path, "unsupported: points of more than 4294967295 bytes");
  }
  if (points == 0) fail(path, "no points: the header declares 0 points");
  if (!findXyzFields(cloud).hasXyz()) fail(path, "no x/y/z fields: FIELDS has no x, y and z");

  // Check the declared size against the data actually present, before allocating anything.
  const std::uint64_t avail = in.remaining();
  std::uint64_t need = 0;
  const bool need_ok = mulOk(points, step, &need);
  const std::string declared = "header declares " + num(points) + " points of " + num(step) + " bytes";
  if (data_kind == "binary") {
    if (!need_ok || need > avail)
      fail(path, "truncated data: " + declared + " (" + (need_ok ? num(need) : std::string("too many")) +
                     " bytes), the file holds " + num(avail) + " bytes of data");
  } else if (data_kind == "ascii") {
    std::uint64_t tokens = 0;
    if (!mulOk(points, std::max<std::uint64_t>(ascii_values, 1), &tokens) || tokens > avail / 2 + 1)
      fail(path, "truncated data: " + declared + " (" + num(ascii_values) +
                     " values each), the file holds only " + num(avail) + " bytes of text");
    // Padding fields have no text in ascii, yet take memory: a header with a huge padding COUNT
    // must not make a few lines of text allocate gigabytes. A value takes at least two bytes of
    // text and at most eight in memory; padding up to a few times the data is what PCL writes.
    if (!need_ok || need > 16 * avail + (std::uint64_t{1} << 20))
      fail(path, "malformed header: " + declared + " (" + (need_ok ? num(need) : std::string("too many")) +
                     " bytes in memory), implausible for " + num(avail) + " bytes of ascii data");
  }
  std::uint32_t comp = 0, uncomp = 0;
  if (data_kind == "binary_compressed") {
    std::uint32_t block_sizes[2] = {0, 0};
    in.read(block_sizes, sizeof block_sizes, "compressed block sizes");
    comp = block_sizes[0];
    uncomp = block_sizes[1];
    in.require(comp, "compressed block");
    // LZF expands at most ~88x (a 3-byte back reference yields 264 bytes).
    std::uint64_t bound = 0;
    if (!need_ok || !mulOk(comp, 100, &bound) || need > bound + 1024)
      fail(path, "truncated data: " + declared + " (" + (need_ok ? num(need) : std::string("too many")) +
                     " bytes), the compressed block holds only " + num(comp) + " bytes");
  }
  if (width > std::numeric_limits<std::uint32_t>::max() || height > std::numeric_limits<std::uint32_t>::max())
    fail(path, "unsupported: WIDTH or HEIGHT above 4294967295");

  cloud.width = static_cast<std::uint32_t>(width);
  cloud.height = static_cast<std::uint32_t>(height);
  cloud.point_step = static_cast<std::uint32_t>(step);
  cloud.row_step = cloud.point_step * cloud.width;
  cloud.is_bigendian = false;
  shape.sensor_origin = Eigen::Vector4f(static_cast<float>(viewpoint[0]), static_cast<float>(viewpoint[1]),
                                        static_cast<float>(viewpoint[2]), 0.f);
  shape.sensor_orientation =
      Eigen::Quaternionf(static_cast<float>(viewpoint[3]), static_cast<float>(viewpoint[4]),
                         static_cast<float>(viewpoint[5]), static_cast<float>(viewpoint[6]));

  if (data_kind == "binary") {
    cloud.data.resize(need);
    in.read(cloud.data.data(), need, "point data");
    if (in.remaining() >= step)
      fail(path, "malformed data: " + num(in.remaining()) + " bytes after the last point: more data than " +
                     declared);
  } else if (data_kind == "binary_compressed") {
    shape.extras.pcd_compressed = true;
    const std::uint64_t need_nopad = points * (step - pad_bytes);
    if (uncomp != need && uncomp != need_nopad)
      fail(path, "malformed data: the compressed block declares " + num(uncomp) +
                     " bytes, the header implies " + num(need));
    std::vector<std::uint8_t> packed(comp);
    in.read(packed.data(), comp, "compressed block");
    std::vector<std::uint8_t> soa(uncomp);
    if (uncomp > 0) {
      const unsigned got = pcl::lzfDecompress(packed.data(), comp, soa.data(), uncomp);
      if (got != uncomp)
        fail(path, "malformed data: corrupt compressed block (LZF produced " + num(got) +
                       " bytes, expected " + num(uncomp) + ")");
    }
    cloud.data.assign(need, 0);
    const bool has_pad_data = uncomp == need;
    std::size_t toff = 0;
    for (const auto& f : cloud.fields) {
      const std::size_t fb = datatypeSize(f.datatype) * fieldCount(f);
      if (f.name == "_" && !has_pad_data) continue;
      for (std::size_t i = 0; i < points; ++i)
        std::memcpy(cloud.data.data() + i * step + f.offset, soa.data() + toff + i * fb, fb);
      toff += fb * points;
    }
  } else {
    cloud.data.assign(need, 0);
    Lexer lex(in.rest(), in.linesRead());
    const bool has_pad = ascii_values_pad != ascii_values;
    for (std::uint64_t i = 0; i < points; ++i) {
      if (!lex.nextLine()) fail(path, "truncated data: expected " + num(points) + " points, found " + num(i));
      // PCL's writers omit padding values in ascii, some of its readers expect them: accept both.
      const bool pad_tokens = has_pad && lex.countTokens() == ascii_values_pad;
      std::uint8_t* pt = cloud.data.data() + i * step;
      for (const auto& f : cloud.fields) {
        const bool pad = f.name == "_";
        if (pad && !pad_tokens) continue;
        const std::size_t sz = datatypeSize(f.datatype);
        for (std::size_t k = 0; k < fieldCount(f); ++k) {
          const std::string_view tok = lex.token();
          if (tok.empty())
            fail(path, "truncated data: line " + num(lex.line()) + " (point " + num(i) + ") has fewer than " +
                           num(ascii_values) + " values");
          if (pad) continue;
          // A packed colour as PCL writes it (an integer: the bits); a float token as older
          // writers (hgdeform's too) wrote it.
          const std::uint8_t type =
              packedColour(f) && plainUnsigned(tok) ? std::uint8_t{Field::UINT32} : f.datatype;
          const Parse st = parseInto(tok, type, pt + f.offset + k * sz);
          if (st == Parse::Bad)
            fail(path, "non-numeric value " + excerpt(tok) + " at line " + num(lex.line()) + " (point " +
                           num(i) + ", field '" + f.name + "')");
          if (st == Parse::Range)
            fail(path, "value out of range " + excerpt(tok) + " at line " + num(lex.line()) + " (point " +
                           num(i) + ", field '" + f.name + "')");
        }
      }
      if (!lex.atLineEnd())
        fail(path, "malformed data: line " + num(lex.line()) + " (point " + num(i) + ") has more than " +
                       num(ascii_values) + " values");
    }
    if (lex.nextLine())
      fail(path, "malformed data: line " + num(lex.line()) + ": more data than the header declares (" +
                     num(points) + " points)");
  }
  cloud.is_dense = computeDense(cloud);
  return shape;
}

// ------------------------------------------------------------------------------------------
// OBJ

Shape readObj(const std::string& path) {
  InputFile in(path);
  Lexer lex(in.rest(), 0);
  std::vector<double> xyz, rgb;
  bool all_rgb = true;
  Shape shape;
  struct PendingIndex {
    std::size_t line;
    long long value;
  };
  PendingIndex worst{0, 0};             // the largest positive index, checked once all vertices are known
  std::vector<std::string_view> lines;  // every line, kept when the file has more than v and f
  bool extras = false;
  std::vector<Eigen::Vector3f> normals;
  std::vector<int> normal_vertex;
  while (lex.nextLine()) {
    lines.push_back(lex.lineText());
    if (lex.peek() == '#') {
      extras = true;
      continue;
    }
    const std::string_view kw = lex.token();
    if (kw == "v") {
      double vals[7];
      std::size_t n = 0;
      for (std::string_view tok = lex.token(); !tok.empty(); tok = lex.token()) {
        double v = 0;
        if (!parseFloating(tok, &v))
          fail(path, "non-numeric value " + excerpt(tok) + " at line " + num(lex.line()));
        if (n < 7) vals[n] = v;
        ++n;
      }
      if (n < 3)
        fail(path,
             "malformed data: line " + num(lex.line()) + ": a vertex needs 3 coordinates, found " + num(n));
      xyz.insert(xyz.end(), vals, vals + 3);
      if (n == 6)
        rgb.insert(rgb.end(), vals + 3, vals + 6);
      else
        all_rgb = false;
    } else if (kw == "f") {
      pcl::Vertices poly;
      for (std::string_view tok = lex.token(); !tok.empty(); tok = lex.token()) {
        const std::string_view head = tok.substr(0, tok.find('/'));
        if (head.size() != tok.size()) extras = true;  // v/vt/vn corners: kept as written
        long long v = 0;
        const auto r = std::from_chars(head.data(), head.data() + head.size(), v);
        const std::size_t nv = xyz.size() / 3;
        if (r.ec != std::errc() || r.ptr != head.data() + head.size() || v == 0 ||
            (v < 0 && v < -static_cast<long long>(nv)) || v > std::numeric_limits<pcl::index_t>::max())
          fail(path, "bad face index " + excerpt(tok) + " at line " + num(lex.line()) + " (" + num(nv) +
                         " vertices so far)");
        const long long idx = v > 0 ? v - 1 : static_cast<long long>(nv) + v;
        if (v > 0 && v > worst.value) worst = {lex.line(), v};
        poly.vertices.push_back(static_cast<pcl::index_t>(idx));
        // The corner's normal (v/vt/vn or v//vn): the first vertex it is paired with turns it.
        const auto s2 = head.size() < tok.size() ? tok.find('/', head.size() + 1) : std::string_view::npos;
        if (s2 != std::string_view::npos) {
          const std::string_view vn = tok.substr(s2 + 1);
          long long k = 0;
          const auto rk = std::from_chars(vn.data(), vn.data() + vn.size(), k);
          const long long nn = static_cast<long long>(normals.size());
          const long long j = k > 0 ? k - 1 : nn + k;
          if (rk.ec == std::errc() && k != 0 && j >= 0 && j < nn &&
              normal_vertex[static_cast<std::size_t>(j)] < 0)
            normal_vertex[static_cast<std::size_t>(j)] = static_cast<int>(idx);
        }
      }
      if (poly.vertices.size() < 3)
        fail(path, "bad face: line " + num(lex.line()) + " has " + num(poly.vertices.size()) +
                       " vertices, at least 3 needed");
      shape.polygons.push_back(std::move(poly));
    } else {
      // vn, vt, vp, o, g, s, l, usemtl, mtllib and anything else: kept as lines (FileExtras);
      // normals are also read, to be turned with the shape.
      extras = true;
      if (kw == "vn") {
        float vals[3] = {0, 0, 0};
        for (float& v : vals) {
          double d = 0;
          const std::string_view tok = lex.token();
          if (!parseFloating(tok, &d))
            fail(path,
                 "non-numeric value " + excerpt(tok) + " at line " + num(lex.line()) + " (a 'vn' line)");
          v = static_cast<float>(d);
        }
        normals.emplace_back(vals[0], vals[1], vals[2]);
        normal_vertex.push_back(-1);
      }
    }
  }
  const std::size_t nverts = xyz.size() / 3;
  if (nverts == 0) fail(path, "no points: the file has no 'v' lines");
  if (static_cast<unsigned long long>(worst.value) > nverts)
    fail(path, "bad face index " + std::to_string(worst.value) + " at line " + num(worst.line) + " (" +
                   num(nverts) + " vertices)");
  if (nverts > std::numeric_limits<std::uint32_t>::max())
    fail(path, "unsupported: more than 4294967295 vertices");

  pcl::PCLPointCloud2& cloud = shape.cloud;
  const bool colour = all_rgb && rgb.size() == xyz.size();
  std::uint32_t step = 0;
  const auto add = [&](const char* name, std::uint8_t type) {
    Field f;
    f.name = name;
    f.offset = step;
    f.datatype = type;
    f.count = 1;
    step += static_cast<std::uint32_t>(datatypeSize(type));
    cloud.fields.push_back(f);
  };
  add("x", Field::FLOAT64);
  add("y", Field::FLOAT64);
  add("z", Field::FLOAT64);
  if (colour) {
    add("red", Field::FLOAT32);
    add("green", Field::FLOAT32);
    add("blue", Field::FLOAT32);
  }
  cloud.width = static_cast<std::uint32_t>(nverts);
  cloud.height = 1;
  cloud.point_step = step;
  cloud.row_step = step * cloud.width;
  cloud.is_bigendian = false;
  cloud.data.resize(nverts * step);
  for (std::size_t i = 0; i < nverts; ++i) {
    std::uint8_t* pt = cloud.data.data() + i * step;
    std::memcpy(pt, &xyz[3 * i], 3 * sizeof(double));
    if (colour) {
      const float c[3] = {static_cast<float>(rgb[3 * i]), static_cast<float>(rgb[3 * i + 1]),
                          static_cast<float>(rgb[3 * i + 2])};
      std::memcpy(pt + 24, c, sizeof c);
    }
  }
  cloud.is_dense = computeDense(cloud);
  if (extras) {
    shape.extras.obj_lines.assign(lines.begin(), lines.end());
    shape.extras.obj_normals = std::move(normals);
    shape.extras.obj_normal_vertex = std::move(normal_vertex);
  }
  return shape;
}

// ------------------------------------------------------------------------------------------
// Output

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

// Writes a file so that no reader ever sees it half written, and no path is replaced by
// something else: a regular file (or a new one) is written to a temporary file beside it and
// renamed over it; a symbolic link is followed (the temporary file goes beside its target, and
// the link stays); a FIFO, a character or block device or a socket (/dev/stdout, a pipe) is
// written to directly, as no rename could replace it.
class AtomicWriter {
 public:
  explicit AtomicWriter(const std::string& target) : target_(target) {
    struct stat st {};
    if (::stat(target.c_str(), &st) == 0 && !S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode)) {
      const int fd = ::open(target.c_str(), O_WRONLY | O_CLOEXEC);
      if (fd < 0) fail(target_, "cannot write: " + errnoText(errno));
      file_ = ::fdopen(fd, "wb");
      if (!file_) {
        const int e = errno;
        ::close(fd);
        fail(target_, "cannot write: " + errnoText(e));
      }
      return;  // direct: commit only flushes
    }
    if (struct stat lst{}; ::lstat(target.c_str(), &lst) == 0 && S_ISLNK(lst.st_mode)) {
      // Follow the link (and links to links) to the file it names, existing or not.
      fs::path t(target);
      for (int hops = 0; hops < 40 && fs::is_symlink(t); ++hops) {
        std::error_code ec;
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
      char suffix[64];
      std::snprintf(suffix, sizeof suffix, ".tmp-%ld-%08x%08x", static_cast<long>(::getpid()), rd(), rd());
      const fs::path tmp = dir / ("." + t.filename().string() + suffix);
      const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
      if (fd < 0) {
        if (errno == EEXIST) continue;
        fail(target_,
             "cannot write: cannot create a temporary file in " + dir.string() + ": " + errnoText(errno));
      }
      tmp_ = tmp.string();
      slot_ = registerTemp(tmp_);
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
  AtomicWriter(const AtomicWriter&) = delete;
  AtomicWriter& operator=(const AtomicWriter&) = delete;
  ~AtomicWriter() {
    if (file_) std::fclose(file_);
    if (!tmp_.empty()) ::unlink(tmp_.c_str());
    unregisterTemp(slot_);
  }

  void write(const void* p, std::size_t n) {
    if (n && std::fwrite(p, 1, n, file_) != n) failWrite(errno);
  }
  void write(std::string_view s) { write(s.data(), s.size()); }

  void commit() {
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

 private:
  [[noreturn]] void failWrite(int e) { fail(target_, "cannot write: " + errnoText(e)); }
  std::string target_;     ///< as given (for messages)
  std::string rename_to_;  ///< the file the temporary one replaces (a link's target)
  std::string tmp_;
  std::FILE* file_ = nullptr;
  int slot_ = -1;
};

template <typename T>
void appendInt(std::string& out, T v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}

template <typename T>
void appendFloat(std::string& out, T v) {
  if (std::isnan(v)) {
    out += "nan";
  } else if (std::isinf(v)) {
    out += v > 0 ? "inf" : "-inf";
  } else {
    char buf[64];
    const auto r = std::to_chars(buf, buf + sizeof buf, v);  // shortest representation that round-trips
    out.append(buf, r.ptr);
  }
}

void appendValue(std::string& out, const std::uint8_t* p, std::uint8_t type) {
  switch (type) {
    case Field::INT8: appendInt(out, static_cast<int>(loadAs<std::int8_t>(p))); break;
    case Field::UINT8: appendInt(out, static_cast<unsigned>(loadAs<std::uint8_t>(p))); break;
    case Field::INT16: appendInt(out, loadAs<std::int16_t>(p)); break;
    case Field::UINT16: appendInt(out, loadAs<std::uint16_t>(p)); break;
    case Field::INT32: appendInt(out, loadAs<std::int32_t>(p)); break;
    case Field::UINT32: appendInt(out, loadAs<std::uint32_t>(p)); break;
    case Field::FLOAT32: appendFloat(out, loadAs<float>(p)); break;
    case Field::FLOAT64: appendFloat(out, loadAs<double>(p)); break;
    default: break;
  }
}

/// Checks that the shape's cloud is self-consistent and returns the fields to write.
std::vector<const Field*> checkShape(const std::string& path, const Shape& shape, bool keep_padding) {
  const pcl::PCLPointCloud2& c = shape.cloud;
  const std::size_t n = shape.size();
  std::uint64_t need = 0;
  if (!mulOk(n, c.point_step, &need) || c.data.size() < need)
    fail(path, "cannot write: invalid shape: " + num(c.data.size()) + " data bytes for " + num(n) +
                   " points of " + num(c.point_step) + " bytes");
  std::vector<const Field*> out;
  for (const auto& f : c.fields) {
    const std::size_t sz = datatypeSize(f.datatype);
    if (sz == 0) fail(path, "cannot write: unsupported datatype of field '" + f.name + "'");
    if (std::uint64_t{f.offset} + sz * fieldCount(f) > c.point_step)
      fail(path, "cannot write: invalid shape: field '" + f.name + "' lies outside the point");
    if (f.name.empty() || std::any_of(f.name.begin(), f.name.end(),
                                      [](char ch) { return isSpace(ch) || ch == '\n' || ch == '\0'; }))
      fail(path, "cannot write: invalid field name " + excerpt(f.name));
    if (f.name == "_" && !keep_padding) continue;
    out.push_back(&f);
  }
  if (out.empty()) fail(path, "cannot write: the shape has no fields");
  for (const auto& poly : shape.polygons)
    for (const auto idx : poly.vertices)
      if (idx < 0 || static_cast<std::uint64_t>(idx) >= n)
        fail(path, "cannot write: bad face index " + std::to_string(idx) + " (" + num(n) + " points)");
  return out;
}

/// True if the fields, in order, tile the point exactly (then the data can be written as is).
bool isPacked(const std::vector<const Field*>& fields, std::uint32_t point_step) {
  std::uint64_t off = 0;
  for (const Field* f : fields) {
    if (f->offset != off) return false;
    off += datatypeSize(f->datatype) * fieldCount(*f);
  }
  return off == point_step;
}

/// Writes the points' values of `fields` in binary, packed in field order.
void writePackedBinary(AtomicWriter& w, const pcl::PCLPointCloud2& c, std::size_t n,
                       const std::vector<const Field*>& fields) {
  if (isPacked(fields, c.point_step)) {
    w.write(c.data.data(), n * c.point_step);
    return;
  }
  std::vector<std::uint8_t> buf;
  buf.reserve(kFlushBytes + c.point_step);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* pt = c.data.data() + i * c.point_step;
    for (const Field* f : fields)
      buf.insert(buf.end(), pt + f->offset, pt + f->offset + datatypeSize(f->datatype) * fieldCount(*f));
    if (buf.size() >= kFlushBytes) {
      w.write(buf.data(), buf.size());
      buf.clear();
    }
  }
  w.write(buf.data(), buf.size());
}

/// Writes the points' values of `fields` as text, one point per line.
void writeAsciiPoints(AtomicWriter& w, const pcl::PCLPointCloud2& c, std::size_t n,
                      const std::vector<const Field*>& fields) {
  std::string buf;
  buf.reserve(kFlushBytes + 1024);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* pt = c.data.data() + i * c.point_step;
    bool first = true;
    for (const Field* f : fields) {
      const std::size_t sz = datatypeSize(f->datatype);
      // A packed colour declared float is written as its bits, an unsigned integer, as PCL does:
      // fully opaque colours are NaNs as floats, and "nan" would lose them.
      const std::uint8_t type = packedColour(*f) ? std::uint8_t{Field::UINT32} : f->datatype;
      for (std::size_t k = 0; k < fieldCount(*f); ++k) {
        if (!first) buf += ' ';
        first = false;
        appendValue(buf, pt + f->offset + k * sz, type);
      }
    }
    buf += '\n';
    if (buf.size() >= kFlushBytes) {
      w.write(buf);
      buf.clear();
    }
  }
  w.write(buf);
}

/// Appends `v` as a value of `type`: binary (host order) to `bin`, or text to `txt`.
void putValue(double v, std::uint8_t type, std::vector<std::uint8_t>* bin, std::string* txt) {
  if (txt) {
    if (type == Field::FLOAT32)
      appendFloat(*txt, static_cast<float>(v));
    else if (type == Field::FLOAT64)
      appendFloat(*txt, v);
    else
      appendInt(*txt, static_cast<long long>(v));
    return;
  }
  const auto put = [&](auto x) {
    const auto* b = reinterpret_cast<const std::uint8_t*>(&x);
    bin->insert(bin->end(), b, b + sizeof x);
  };
  switch (type) {
    case Field::INT8: put(static_cast<std::int8_t>(v)); break;
    case Field::UINT8: put(static_cast<std::uint8_t>(v)); break;
    case Field::INT16: put(static_cast<std::int16_t>(v)); break;
    case Field::UINT16: put(static_cast<std::uint16_t>(v)); break;
    case Field::INT32: put(static_cast<std::int32_t>(v)); break;
    case Field::UINT32: put(static_cast<std::uint32_t>(v)); break;
    case Field::FLOAT32: put(static_cast<float>(v)); break;
    default: put(v); break;
  }
}

/// Whether a shape's kept PLY elements still fit it (the same vertex and face counts).
bool plyExtrasFit(const Shape& shape) {
  const auto& els = shape.extras.ply_elements;
  if (els.empty()) return false;
  bool vertex = false;
  for (const auto& el : els) {
    if (el.name == "vertex") {
      vertex = true;
      if (el.count != shape.size()) return false;
    }
    const bool indices = std::any_of(el.kept.begin(), el.kept.end(), [](char k) { return !k; });
    if (el.name == "face" && indices && el.count != shape.polygons.size()) return false;
  }
  return vertex;
}

/// A PLY written with every element, property and comment the file it was read from had, in
/// their order: the vertex element's scalars from the cloud (fields added since go last), the
/// faces' vertex lists from the polygons, the rest from FileExtras.
void writePlyWithExtras(const std::string& path, const Shape& shape, bool ascii,
                        const std::vector<const Field*>& fields) {
  const pcl::PCLPointCloud2& c = shape.cloud;
  const std::size_t n = shape.size();
  std::string h = "ply\nformat ";
  h += ascii ? "ascii" : (kHostBigEndian ? "binary_big_endian" : "binary_little_endian");
  h += " 1.0\n";
  for (const auto& line : shape.extras.ply_comments) h += line + "\n";
  h += "comment written by hgdeform\n";
  // What each property of each element is written from.
  struct Source {
    const FileExtras::Property* prop = nullptr;
    const Field* field = nullptr;  // a cloud field (vertex scalars)
    bool indices = false;          // the face's vertex list
    bool kept = false;             // FileExtras values
    std::uint8_t count_type = 0;   // the face lists' length type (widened if a face needs it)
  };
  std::size_t max_face = 0;
  for (const auto& poly : shape.polygons) max_face = std::max(max_face, poly.vertices.size());
  std::vector<std::vector<Source>> sources;
  std::vector<char> used(fields.size(), 0);
  for (const auto& el : shape.extras.ply_elements) {
    const bool is_vertex = el.name == "vertex";
    h += "element " + el.name + " " + num(is_vertex ? n : el.count) + "\n";
    std::vector<Source> src;
    for (std::size_t k = 0; k < el.props.size(); ++k) {
      const FileExtras::Property& p = el.props[k];
      Source so;
      so.prop = &p;
      if (el.kept[k]) {
        so.kept = true;
      } else if (is_vertex) {
        for (std::size_t f = 0; f < fields.size() && !so.field; ++f)
          if (!used[f] && fields[f]->name == p.name && fieldCount(*fields[f]) == 1) {
            so.field = fields[f];
            used[f] = 1;
          }
        if (!so.field) continue;  // the field is gone from the cloud
      } else {
        so.indices = true;
        so.count_type = max_face > 127 ? static_cast<std::uint8_t>(Field::UINT32) : p.count_type;
      }
      if (so.field)
        h += std::string("property ") + plyTypeName(so.field->datatype) + " " + p.name + "\n";
      else if (p.list)
        h += std::string("property list ") + plyTypeName(so.indices ? so.count_type : p.count_type) + " " +
             plyTypeName(p.type) + " " + p.name + "\n";
      else
        h += std::string("property ") + plyTypeName(p.type) + " " + p.name + "\n";
      src.push_back(so);
    }
    if (is_vertex)  // fields the file did not have (a computed field), after its own
      for (std::size_t f = 0; f < fields.size(); ++f) {
        if (used[f]) continue;
        Source so;
        so.field = fields[f];
        src.push_back(so);
        const std::size_t cnt = fieldCount(*fields[f]);
        for (std::size_t k = 0; k < cnt; ++k)
          h += std::string("property ") + plyTypeName(fields[f]->datatype) + " " + fields[f]->name +
               (cnt > 1 ? "_" + num(k) : std::string()) + "\n";
      }
    sources.push_back(std::move(src));
  }
  h += "end_header\n";

  AtomicWriter w(path);
  w.write(h);
  std::vector<std::uint8_t> bin;
  std::string txt;
  std::vector<std::uint8_t>* b = ascii ? nullptr : &bin;
  std::string* t = ascii ? &txt : nullptr;
  for (std::size_t e = 0; e < shape.extras.ply_elements.size(); ++e) {
    const auto& el = shape.extras.ply_elements[e];
    const bool is_vertex = el.name == "vertex";
    const std::uint64_t records = is_vertex ? n : el.count;
    std::size_t at = 0;  // into el.values
    for (std::uint64_t r = 0; r < records; ++r) {
      bool first = true;
      const auto sep = [&] {
        if (t && !first) *t += ' ';
        first = false;
      };
      for (const Source& so : sources[e]) {
        if (so.field) {
          const std::uint8_t* pt = c.data.data() + r * c.point_step + so.field->offset;
          const std::size_t sz = datatypeSize(so.field->datatype);
          for (std::size_t k = 0; k < fieldCount(*so.field); ++k) {
            sep();
            if (t)
              appendValue(*t, pt + k * sz, so.field->datatype);
            else
              b->insert(b->end(), pt + k * sz, pt + (k + 1) * sz);
          }
        } else if (so.indices) {
          const auto& poly = shape.polygons[r];
          sep();
          putValue(static_cast<double>(poly.vertices.size()), so.count_type, b, t);
          for (const auto idx : poly.vertices) {
            sep();
            putValue(static_cast<double>(idx), so.prop->type, b, t);
          }
        } else if (so.prop->list) {
          const auto len = static_cast<std::size_t>(el.values.at(at++));
          sep();
          putValue(static_cast<double>(len), so.prop->count_type, b, t);
          for (std::size_t j = 0; j < len; ++j) {
            sep();
            putValue(el.values.at(at++), so.prop->type, b, t);
          }
        } else {
          sep();
          putValue(el.values.at(at++), so.prop->type, b, t);
        }
      }
      if (t) *t += '\n';
      if (bin.size() >= kFlushBytes || txt.size() >= kFlushBytes) {
        w.write(bin.data(), bin.size());
        w.write(txt);
        bin.clear();
        txt.clear();
      }
    }
  }
  w.write(bin.data(), bin.size());
  w.write(txt);
  w.commit();
}

void writePly(const std::string& path, const Shape& shape, bool ascii) {
  const auto fields = checkShape(path, shape, false);
  if (plyExtrasFit(shape)) return writePlyWithExtras(path, shape, ascii, fields);
  const pcl::PCLPointCloud2& c = shape.cloud;
  const std::size_t n = shape.size();
  if (n > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()) && !shape.polygons.empty())
    fail(path, "cannot write: too many points for int face indices");
  std::size_t max_face = 0;
  for (const auto& poly : shape.polygons) max_face = std::max(max_face, poly.vertices.size());
  const bool wide_count = max_face > 255;

  std::string h = "ply\nformat ";
  h += ascii ? "ascii" : (kHostBigEndian ? "binary_big_endian" : "binary_little_endian");
  h += " 1.0\ncomment written by hgdeform\nelement vertex " + num(n) + "\n";
  for (const Field* f : fields) {
    const std::size_t cnt = fieldCount(*f);
    for (std::size_t k = 0; k < cnt; ++k) {
      h += std::string("property ") + plyTypeName(f->datatype) + " " + f->name;
      if (cnt > 1) h += "_" + num(k);
      h += "\n";
    }
  }
  if (!shape.polygons.empty()) {
    h += "element face " + num(shape.polygons.size()) + "\n";
    h += wide_count ? "property list uint int vertex_indices\n" : "property list uchar int vertex_indices\n";
  }
  h += "end_header\n";

  AtomicWriter w(path);
  w.write(h);
  if (ascii) {
    writeAsciiPoints(w, c, n, fields);
    std::string buf;
    for (const auto& poly : shape.polygons) {
      appendInt(buf, poly.vertices.size());
      for (const auto idx : poly.vertices) {
        buf += ' ';
        appendInt(buf, idx);
      }
      buf += '\n';
      if (buf.size() >= kFlushBytes) {
        w.write(buf);
        buf.clear();
      }
    }
    w.write(buf);
  } else {
    writePackedBinary(w, c, n, fields);
    std::vector<std::uint8_t> buf;
    for (const auto& poly : shape.polygons) {
      if (wide_count) {
        const auto cnt = static_cast<std::uint32_t>(poly.vertices.size());
        const auto* b = reinterpret_cast<const std::uint8_t*>(&cnt);
        buf.insert(buf.end(), b, b + sizeof cnt);
      } else {
        buf.push_back(static_cast<std::uint8_t>(poly.vertices.size()));
      }
      for (const auto idx : poly.vertices) {
        const auto v = static_cast<std::int32_t>(idx);
        const auto* b = reinterpret_cast<const std::uint8_t*>(&v);
        buf.insert(buf.end(), b, b + sizeof v);
      }
      if (buf.size() >= kFlushBytes) {
        w.write(buf.data(), buf.size());
        buf.clear();
      }
    }
    w.write(buf.data(), buf.size());
  }
  w.commit();
}

void writePcd(const std::string& path, const Shape& shape, bool ascii) {
  // Padding fields are kept in binary (the bytes are written as they are) and dropped in ascii,
  // where PCL's own writers and readers disagree about them.
  const auto fields = checkShape(path, shape, !ascii);
  const pcl::PCLPointCloud2& c = shape.cloud;
  const std::size_t n = shape.size();
  std::string h = "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS";
  for (const Field* f : fields) h += " " + f->name;
  h += "\nSIZE";
  for (const Field* f : fields) h += " " + num(datatypeSize(f->datatype));
  h += "\nTYPE";
  for (const Field* f : fields)
    h += f->datatype == Field::FLOAT32 || f->datatype == Field::FLOAT64                               ? " F"
         : (f->datatype == Field::INT8 || f->datatype == Field::INT16 || f->datatype == Field::INT32) ? " I"
                                                                                                      : " U";
  h += "\nCOUNT";
  for (const Field* f : fields) h += " " + num(fieldCount(*f));
  h += "\nWIDTH " + num(c.width) + "\nHEIGHT " + num(c.height) + "\nVIEWPOINT";
  const float vp[7] = {shape.sensor_origin[0],       shape.sensor_origin[1],
                       shape.sensor_origin[2],       shape.sensor_orientation.w(),
                       shape.sensor_orientation.x(), shape.sensor_orientation.y(),
                       shape.sensor_orientation.z()};
  for (const float v : vp) {
    h += ' ';
    appendFloat(h, v);
  }
  // Compressed as it was read (binary_compressed: each field's values together, then LZF).
  const bool compressed = !ascii && shape.extras.pcd_compressed;
  h += "\nPOINTS " + num(n) + "\nDATA " +
       (ascii        ? "ascii"
        : compressed ? "binary_compressed"
                     : "binary") +
       "\n";

  AtomicWriter w(path);
  w.write(h);
  if (ascii) {
    writeAsciiPoints(w, c, n, fields);
  } else if (compressed) {
    std::vector<std::uint8_t> soa;
    for (const Field* f : fields) {
      const std::size_t fb = datatypeSize(f->datatype) * fieldCount(*f);
      for (std::size_t i = 0; i < n; ++i) {
        const std::uint8_t* src = c.data.data() + i * c.point_step + f->offset;
        soa.insert(soa.end(), src, src + fb);
      }
    }
    if (soa.size() > std::numeric_limits<std::uint32_t>::max() / 2)
      fail(path, "cannot write: too much data for one compressed PCD block");
    std::vector<std::uint8_t> packed(soa.size() + soa.size() / 2 + 64);
    const unsigned got = soa.empty() ? 0
                                     : pcl::lzfCompress(soa.data(), static_cast<unsigned>(soa.size()),
                                                        packed.data(), static_cast<unsigned>(packed.size()));
    if (!soa.empty() && got == 0) fail(path, "cannot write: LZF compression failed");
    const std::uint32_t sizes[2] = {got, static_cast<std::uint32_t>(soa.size())};
    w.write(sizes, sizeof sizes);
    w.write(packed.data(), got);
  } else {
    writePackedBinary(w, c, n, fields);
  }
  w.commit();
}

/// " x y z" of the point at `pt`, each at its declared type (an OBJ vertex's coordinates).
void appendXyz(std::string& buf, const pcl::PCLPointCloud2& c, const std::uint8_t* pt, const XyzFields& xyz) {
  for (const int idx : {xyz.x, xyz.y, xyz.z}) {
    buf += ' ';
    appendValue(buf, pt + c.fields[idx].offset, c.fields[idx].datatype);
  }
}

/// An OBJ written line by line as it was read: 'v' lines with the cloud's x/y/z (the rest of
/// the line, colours or a weight, as it was), 'vn' lines with the turned normals, every other
/// line (vt, g, o, usemtl, mtllib, s, l, comments, faces with their v/vt/vn corners) unchanged.
bool writeObjLines(const std::string& path, const Shape& shape, const XyzFields& xyz) {
  const FileExtras& x = shape.extras;
  const std::vector<Eigen::Vector3f>& vn = x.obj_normals_out.empty() ? x.obj_normals : x.obj_normals_out;
  std::size_t nv = 0, nn = 0;
  for (const auto& line : x.obj_lines) {
    nv += line.rfind("v ", 0) == 0 || line.rfind("v\t", 0) == 0;
    nn += line.rfind("vn ", 0) == 0 || line.rfind("vn\t", 0) == 0;
  }
  if (nv != shape.size() || nn != vn.size()) return false;  // the shape no longer fits its lines
  const pcl::PCLPointCloud2& c = shape.cloud;
  AtomicWriter w(path);
  std::string buf;
  std::size_t i = 0, j = 0;
  for (const auto& line : x.obj_lines) {
    const std::vector<std::string_view> words = splitWords(line);
    if (!words.empty() && words[0] == "v") {
      buf += 'v';
      appendXyz(buf, c, c.data.data() + i++ * c.point_step, xyz);
      for (std::size_t k = 4; k < words.size(); ++k) {
        buf += ' ';
        buf += words[k];
      }
    } else if (!words.empty() && words[0] == "vn") {
      buf += "vn";
      for (int a = 0; a < 3; ++a) {
        buf += ' ';
        appendFloat(buf, vn[j][a]);
      }
      ++j;
    } else {
      buf += line;
    }
    buf += '\n';
    if (buf.size() >= kFlushBytes) {
      w.write(buf);
      buf.clear();
    }
  }
  w.write(buf);
  w.commit();
  return true;
}

void writeObj(const std::string& path, const Shape& shape) {
  checkShape(path, shape, false);
  const pcl::PCLPointCloud2& c = shape.cloud;
  const XyzFields xyz = findXyzFields(c);
  if (!xyz.hasXyz()) fail(path, "cannot write: no x/y/z fields");
  if (!shape.extras.obj_lines.empty() && writeObjLines(path, shape, xyz)) return;
  const int r = findField(c, "red"), g = findField(c, "green"), b = findField(c, "blue");
  const bool colour = r >= 0 && g >= 0 && b >= 0;
  const std::size_t n = shape.size();

  AtomicWriter w(path);
  std::string buf = "# written by hgdeform\n";
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* pt = c.data.data() + i * c.point_step;
    buf += 'v';
    appendXyz(buf, c, pt, xyz);
    if (colour) {
      for (const int idx : {r, g, b}) {
        const Field& f = c.fields[idx];
        buf += ' ';
        if (f.datatype == Field::FLOAT32 || f.datatype == Field::FLOAT64)
          appendValue(buf, pt + f.offset, f.datatype);
        else
          appendFloat(buf, static_cast<float>(readValue(c, i, f) / 255.0));
      }
    }
    buf += '\n';
    if (buf.size() >= kFlushBytes) {
      w.write(buf);
      buf.clear();
    }
  }
  for (const auto& poly : shape.polygons) {
    buf += 'f';
    for (const auto idx : poly.vertices) {
      buf += ' ';
      appendInt(buf, static_cast<long long>(idx) + 1);
    }
    buf += '\n';
    if (buf.size() >= kFlushBytes) {
      w.write(buf);
      buf.clear();
    }
  }
  w.write(buf);
  w.commit();
}

}  // namespace

FileFormat formatFromPath(const std::string& path) {
  const std::string ext = lower(fs::path(path).extension().string());
  if (ext == ".ply") return FileFormat::Ply;
  if (ext == ".pcd") return FileFormat::Pcd;
  if (ext == ".obj") return FileFormat::Obj;
  fail(path, "unsupported file extension " + excerpt(ext) + " (expected .ply, .pcd or .obj)");
}

Shape readShape(const std::string& path) {
  const FileFormat format = formatFromPath(path);
  Shape shape;
  switch (format) {
    case FileFormat::Ply: shape = readPly(path); break;
    case FileFormat::Pcd: shape = readPcd(path); break;
    case FileFormat::Obj: shape = readObj(path); break;
  }
  shape.path = path;
  shape.format = format;
  return shape;
}

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

std::string extrasLost(const Shape& shape, FileFormat format) {
  const FileExtras& x = shape.extras;
  if (!x.obj_lines.empty() && format != FileFormat::Obj)
    return "the OBJ's texture coordinates, normals, groups, materials and face corners are kept only when "
           "writing OBJ";
  if (!x.ply_elements.empty() && format != FileFormat::Ply)
    return "the PLY's other elements, face properties and list properties are kept only when writing PLY";
  return "";
}

void writeShape(const std::string& path, const Shape& shape, const WriteOptions& options) {
  const FileFormat format = formatFromPath(path);
  refuseInputs(path, {shape.path});
  const bool ascii = options.encoding == Encoding::Ascii;
  switch (format) {
    case FileFormat::Ply: writePly(path, shape, ascii); break;
    case FileFormat::Pcd: writePcd(path, shape, ascii); break;
    case FileFormat::Obj: writeObj(path, shape); break;
  }
}

void removeTemporaryFiles() noexcept {
  for (auto& slot : g_temp_slots)
    if (slot.state.load() == 2) ::unlink(slot.path);
}

void writeFileAtomically(const std::string& path, std::string_view bytes) {
  AtomicWriter w(path);
  w.write(bytes);
  w.commit();
}

}  // namespace hgd
