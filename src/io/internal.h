// Private to src/io/ (not installed): what the readers and writers of the formats share. The
// input file and lexer, the atomic writer, the checks of a shape about to be written, the
// small text helpers; the datatype codec is io/field_codec.h.
#pragma once

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <string_view>
#include <system_error>
#include <type_traits>
#include <utility>
#include <vector>

#include "hgdeform/io/fields.h"
#include "hgdeform/io/io.h"
#include "hgdeform/io/records.h"
#include "io/field_codec.h"

namespace hgd::io_internal {

using Field = pcl::PCLPointField;

constexpr bool kHostBigEndian = __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__;
constexpr std::size_t kMaxHeaderLine = std::size_t{1} << 20;
constexpr std::size_t kFlushBytes = std::size_t{1} << 16;

// ------------------------------------------------------------------------------------------
// Small helpers (common.cpp; the clouds made and converted: clouds.cpp)

/// Throws IoError("<path>: <problem>").
[[noreturn]] void fail(const std::string& path, const std::string& problem);
std::string errnoText(int e);
std::string num(std::uint64_t v);
/// A short, printable excerpt of untrusted text for messages.
std::string excerpt(std::string_view s);
bool isSpace(char c);
std::vector<std::string_view> splitWords(std::string_view s);
/// The values of an XYZ row: split at blanks and commas.
std::vector<std::string_view> splitColumns(std::string_view s);
std::string lower(std::string_view s);
bool parseU64(std::string_view s, std::uint64_t* v);

inline bool mulOk(std::uint64_t a, std::uint64_t b, std::uint64_t* r) {
  return !__builtin_mul_overflow(a, b, r);
}
inline bool addOk(std::uint64_t a, std::uint64_t b, std::uint64_t* r) {
  return !__builtin_add_overflow(a, b, r);
}

inline std::size_t fieldCount(const Field& f) {
  return f.count > 1 ? f.count : 1;
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

/// Whether `v`, read from `token`, is an infinity the text did not spell ("1e400", not "inf").
template <typename T>
bool overflowed(std::string_view token, T v) {
  return std::isinf(v) && token.find_first_of("iI") == std::string_view::npos;
}

/// Whether float32 holds the number `v` was read as: its shortest float spelling reads back as
/// the same double (so "0.25" and "255" fit, "1634567890.123456" and "16777217" do not).
/// Not-a-numbers and infinities fit.
inline bool floatHolds(double v) {
  if (!std::isfinite(v)) return true;
  const float f = static_cast<float>(v);
  if (!std::isfinite(f)) return false;
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, f);
  double back = 0;
  return std::from_chars(buf, r.ptr, back).ec == std::errc() && back == v;
}

/// An integer token; integral floating-point spellings ("255.0", "1e3") are accepted too.
Parse parseInteger(std::string_view s, long long* v);

template <typename T>
void appendInt(std::string& out, T v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}

/// `v` in the shortest spelling that reads back to the same value, padded with zeros to at
/// least `decimals` digits after the point when it is written without an exponent (so that a
/// file whose column was written with six decimals keeps them: "1.500000", not "1.5").
template <typename T>
void appendFloat(std::string& out, T v, int decimals = 0, bool exponents = true) {
  if (std::isnan(v)) {
    out += "nan";
  } else if (std::isinf(v)) {
    out += v > 0 ? "inf" : "-inf";
  } else {
    char buf[512];
    // The shortest spelling that reads back to the same value; in fixed notation when the
    // column never used exponents (and the value is not huge).
    const bool fixed = decimals > 0 && !exponents && std::abs(v) < T(1e16);
    const auto r = fixed ? std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed)
                         : std::to_chars(buf, buf + sizeof buf, v);
    out.append(buf, r.ptr);
    if (decimals > 0 && std::find(buf, r.ptr, 'e') == r.ptr) {
      const char* dot = std::find(buf, r.ptr, '.');
      const long have = dot == r.ptr ? -1 : static_cast<long>(r.ptr - dot - 1);
      if (have < 0) out += '.';
      for (long k = std::max(have, 0L); k < decimals; ++k) out += '0';
    }
  }
}

/// The number of digits after the decimal point of a number written in fixed notation ("1.500"
/// has 3); 0 for one without a point or not a number; -1 for one with an exponent.
int fixedDecimals(std::string_view token);

/// The fewest decimals seen in each text column (fixedDecimals of every value), and whether it
/// had exponents, for writing the column back as it was spelt (FileExtras::text_decimals).
struct DecimalsSeen {
  std::vector<int> least;
  std::vector<char> exponents;
  std::vector<std::vector<std::int8_t>> each;  // per column, every value's (-1: an exponent)
  void see(std::size_t column, std::string_view token) {
    if (column >= least.size()) {
      least.resize(column + 1, std::numeric_limits<int>::max());
      exponents.resize(column + 1, 0);
      each.resize(column + 1);
    }
    const int d = fixedDecimals(token);
    each[column].push_back(static_cast<std::int8_t>(std::min(d, 127)));
    if (d < 0)
      exponents[column] = 1;
    else
      least[column] = std::min(least[column], d);
  }
  /// Stores column k's spelling under `names[k]`: columns that always had decimals, and columns
  /// whose rows were spelt differently (with each row's).
  void store(FileExtras& extras, const std::vector<std::string>& names) const;
};

/// How value `row` of column `d` is spelt: its row's decimals when the column kept them for
/// `rows` rows, else the column's.
inline void rowSpelling(const FileExtras::TextColumn& d, std::size_t row, std::size_t rows, int* decimals,
                        bool* exponents) {
  if (d.rows.size() == rows && row < rows) {
    const int r = d.rows[row];
    *decimals = r < 0 ? 0 : r;
    *exponents = r < 0;
  } else {
    *decimals = d.decimals;
    *exponents = d.exponents;
  }
}

/// How each of `fields` is to be spelt when written as text (decimals 0: shortest).
std::vector<FileExtras::TextColumn> decimalsOf(const FileExtras& extras,
                                               const std::vector<const pcl::PCLPointField*>& fields);

/// A cloud of `n` points (height 1) with scalar fields of these names and types, packed in
/// order, filled from `values` (point by point, field by field) converted to each type.
pcl::PCLPointCloud2 makeCloud(std::size_t n, const std::vector<std::pair<std::string, std::uint8_t>>& fields,
                              const std::vector<double>& values);

/// Where a '#' comment starts in an XYZ row: at a '#' that begins a value (at the start of the
/// line, or after a blank or a comma); npos if the row has none.
std::size_t xyzCommentStart(std::string_view line);

/// The cloud of `shape` with its fields under the names and layouts the readers of `target`
/// expect, when the shape was read from a file of another format, or made in memory as one
/// (`shape.format` not `target`): normals normal_x/normal_y/normal_z (PCD) or nx/ny/nz (PLY),
/// intensity and curvature (also from CloudCompare's scalar_intensity, scalar_curvature), a
/// packed rgb/rgba split into uchar red/green/blue(/alpha) for the text and mesh formats (PLY,
/// XYZ, OBJ, OFF) and uchar red/green/blue(/alpha) packed into rgb (float, as PCL's PointXYZRGB)
/// or rgba (uint32) for PCD. A name is given only when no other field has it. False (and `out`
/// untouched) when nothing changes: a shape written in its own format is written as read.
bool conventionalCloud(const Shape& shape, FileFormat target, pcl::PCLPointCloud2* out);
/// Whether these fields (red, green, blue) are floats, every value in 0..1.
bool unitColours(const pcl::PCLPointCloud2& c, std::initializer_list<long> channels);

/// PCL's organized PLY (its PLYWriter of an organized cloud): an element range_grid of one list
/// per pixel, each empty (a NaN point) or naming one vertex, every one of `vertices` vertices
/// named once. Per vertex, the pixel that names it; empty if `extras` holds no such grid.
std::vector<std::size_t> rangeGridPixels(const FileExtras& extras, std::uint64_t vertices);

/// False if any x, y or z value is NaN or infinite.
bool computeDense(const pcl::PCLPointCloud2& cloud);

// ------------------------------------------------------------------------------------------
// Input (common.cpp)

/// A file opened for reading: header lines through stdio, then the body either read straight
/// into its destination or loaded once into memory. Every read is bounds-checked against the
/// file's size.
class InputFile {
 public:
  explicit InputFile(std::string path);

  const std::string& path() const { return path_; }
  std::size_t linesRead() const { return lines_; }

  std::uint64_t remaining() const {
    if (buffered_) return buf_.size() - bpos_;
    return pos_ < size_ ? size_ - pos_ : 0;
  }
  /// Where the next byte is read from, in the file.
  std::uint64_t offset() const { return size_ - remaining(); }
  /// The file's size (without a skipped UTF-8 byte-order mark).
  std::uint64_t size() const { return size_ - skipped_; }

  /// Reads one header line without its "\n" or "\r\n"; false at the end of the file.
  bool readLine(std::string* line, std::size_t max_len);
  void require(std::uint64_t n, const char* what) const;
  void read(void* dst, std::size_t n, const char* what);
  void skip(std::uint64_t n, const char* what);
  /// The next `n` bytes of the (in-memory) body.
  const std::uint8_t* take(std::size_t n, const char* what);
  /// The rest of the file, loaded in memory.
  std::string_view rest();

 private:
  void loadRest();

  struct Closer {
    void operator()(std::FILE* f) const { std::fclose(f); }
  };
  std::string path_;
  std::unique_ptr<std::FILE, Closer> file_;
  std::uint64_t size_ = 0, pos_ = 0, skipped_ = 0;
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

/// A whole text file lexed line by line from its start (the OFF and XYZ readers).
struct TextFile {
  explicit TextFile(const std::string& path) : in(path), lex(in.rest(), 0) {}
  InputFile in;
  Lexer lex;
};

// ------------------------------------------------------------------------------------------
// Output (checking and packing a shape: output.cpp)

/// Whether `size` bytes make a binary STL whose bytes 80-83 (`count`, little-endian) are its
/// triangle count: an 80-byte header, the count, 50 bytes per triangle, nothing else.
bool binaryStlSizeFits(const unsigned char* count, std::uint64_t size);

/// What an STL of `shape` (a mesh) cannot hold, each as a phrase for extrasLost ("" when
/// nothing): points on no face, and points at the position (as float, the way STL's reader welds
/// corners) of another, which come back as one vertex. (stl.cpp)
std::string stlLosses(const Shape& shape);

/// Writes a file so that no reader ever sees it half written, and no path is replaced by
/// something else: a regular file (or a new one) is written to a temporary file beside it and
/// renamed over it; a symbolic link is followed (the temporary file goes beside its target, and
/// the link stays); a FIFO, a character or block device or a socket (a pipe) is written to
/// directly, as no rename could replace it; a path naming a descriptor (/dev/stdout,
/// /dev/stderr, /dev/fd/N, /proc/self/fd/N: descriptorPath) is written to that descriptor,
/// whatever it is open on. Destroyed without commit(), it removes
/// the temporary file: a failed write leaves no output. (atomic_file.cpp)
class AtomicWriter {
 public:
  explicit AtomicWriter(const std::string& target);
  AtomicWriter(const AtomicWriter&) = delete;
  AtomicWriter& operator=(const AtomicWriter&) = delete;
  ~AtomicWriter();

  void write(const void* p, std::size_t n);
  void write(std::string_view s) { write(s.data(), s.size()); }
  void commit();
  const std::string& path() const { return target_; }
  /// The temporary file being written (renamed to the target by commit), or "" when the
  /// writer writes to a descriptor or a device directly.
  const std::string& temporary() const { return tmp_; }
  /// Bytes written so far (skipped ones included).
  std::uint64_t written() const { return written_; }
  /// Moves `n` bytes further in the temporary file without writing them (another process
  /// writes them there before commit).
  void skip(std::uint64_t n);
  /// Whether what was written so far has a binary STL's size (84 + 50 n bytes, n in bytes
  /// 80-83), which makes a reader that knows formats by their content take it for one.
  bool hasBinaryStlSize() const;

 private:
  [[noreturn]] void failWrite(int e);
  std::uint64_t written_ = 0;
  unsigned char count_bytes_[4] = {0, 0, 0, 0};  ///< bytes 80-83 of the output
  std::string target_;                           ///< as given (for messages)
  std::string rename_to_;                        ///< the file the temporary one replaces (a link's target)
  std::string tmp_;
  std::FILE* file_ = nullptr;
  int slot_ = -1;
};

/// The descriptor `path` names, possibly through symbolic links: 0, 1, 2 for /dev/stdin,
/// /dev/stdout, /dev/stderr, N for /dev/fd/N, /proc/self/fd/N, /proc/thread-self/fd/N and
/// /proc/<this process>/fd/N; -1 for any other path. Such a path leads to whatever the
/// descriptor is open on (a file stdout was redirected to), so the writers write to the
/// descriptor, as they do for "-", and never replace or remove it. (atomic_file.cpp)
int descriptorPath(const std::string& path);

/// Checks that the shape's cloud is self-consistent and returns the fields to write.
std::vector<const Field*> checkShape(const std::string& path, const Shape& shape, bool keep_padding);
/// True if the fields, in order, tile the point exactly (then the data can be written as is).
bool isPacked(const std::vector<const Field*>& fields, std::uint32_t point_step);
/// Writes `buf` (text or bytes) out once it holds kFlushBytes: the writers' one buffering rule.
template <typename Buffer>
void flushIfFull(AtomicWriter& w, Buffer& buf) {
  if (buf.size() >= kFlushBytes) {
    w.write(buf.data(), buf.size());
    buf.clear();
  }
}

/// Appends faces as text lines "count i j k ..." (ascii PLY, OFF), flushing through `w`.
void appendFaceLines(AtomicWriter& w, std::string& buf, const std::vector<pcl::Vertices>& polygons);

/// While set (writeRecords), the binary writers take the points' records from here instead of
/// the cloud's data (which is empty).
extern thread_local const std::function<void(AtomicWriter&)>* t_streamed_records;
/// Writes the points' values of `fields` in binary, packed in field order.
void writePackedBinary(AtomicWriter& w, const pcl::PCLPointCloud2& c, std::size_t n,
                       const std::vector<const Field*>& fields);
/// Writes the points' values of `fields` as text, one point per line. With `colour_bits`, a
/// packed colour declared float (see packedColour) is written as its bits, an unsigned integer,
/// as PCL's ascii PCD writer does: fully opaque colours are NaNs as floats, and "nan" loses them.
/// `decimals`: per field, the decimals to pad floating values to (decimalsOf), or empty.
/// `separator` goes between values (an XYZ file's own, e.g. ", ").
void writeAsciiPoints(AtomicWriter& w, const pcl::PCLPointCloud2& c, std::size_t n,
                      const std::vector<const Field*>& fields, bool colour_bits = false,
                      const std::vector<FileExtras::TextColumn>& decimals = {},
                      std::string_view separator = " ");

/// A FLOAT32 field called rgb or rgba: a colour packed into a float's bytes, which PCL's ascii
/// PCD writer stores as an unsigned integer (the bits), not as a float.
inline bool packedColour(const Field& f) {
  return f.datatype == Field::FLOAT32 && (f.name == "rgb" || f.name == "rgba");
}

/// An ascii token of nothing but decimal digits.
inline bool plainUnsigned(std::string_view tok) {
  return !tok.empty() && std::all_of(tok.begin(), tok.end(), [](char ch) { return ch >= '0' && ch <= '9'; });
}

// ------------------------------------------------------------------------------------------
// The formats (ply.cpp, pcd.cpp, obj.cpp, xyz.cpp, off.cpp, stl.cpp)

/// `layout`: when given, the vertex records are not read but placed (readRecordLayout): the
/// shape comes back without its points' data, or IoError says why the file cannot be read so.
Shape readPly(const std::string& path, RecordLayout* layout = nullptr);
Shape readPcd(const std::string& path, RecordLayout* layout = nullptr);
Shape readObj(const std::string& path);
void writePly(const std::string& path, const Shape& shape, bool ascii);
void writePcd(const std::string& path, const Shape& shape, bool ascii);
void writeObj(const std::string& path, const Shape& shape);
Shape readXyz(const std::string& path);
Shape readOff(const std::string& path);
Shape readStl(const std::string& path);
/// ASPRS LAS 1.0-1.4 (las.cpp, las_write.cpp). lasLosses: what writing `shape` as LAS would not keep, or move
/// (fields LAS has no place for; an offset moved so that moved points fit), "" if nothing.
Shape readLas(const std::string& path);
void writeLas(const std::string& path, const Shape& shape);
std::string lasLosses(const Shape& shape);
/// Whether a path names a LAZ file (.laz, any case).
bool isLaz(const std::string& path);

/// The field a PTS file's intensity column is written from: a scalar named intensity (any
/// case), or -1.
int ptsIntensity(const pcl::PCLPointCloud2& cloud, const XyzFields& xyz);

/// `pts`: as Leica PTS (the point count first; x y z, intensity, red green blue; no row of names).
void writeXyz(const std::string& path, const Shape& shape, bool pts);
void writeOff(const std::string& path, const Shape& shape);
void writeStl(const std::string& path, const Shape& shape, bool ascii);

}  // namespace hgd::io_internal
