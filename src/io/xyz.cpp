// ASCII point lists (.xyz, .txt): one point per row, `x y z` and any further columns, separated
// by blanks or commas; '#' comments (whole lines, or after a row's values) and blank lines
// skipped.
//
// Column names, conservatively:
//   - a first row that is not all numbers names the columns (a leading "//", as CloudCompare
//     writes, is dropped). Columns named x, y and z (any case) are the coordinates; if it names
//     no x, y and z the first three columns are. The others keep their names, as float fields
//     (double where a value needs it, below).
//   - without such a row the first three columns are x, y, z. With exactly 6 columns, columns
//     4-6 are normals nx ny nz when every row's is a unit vector (within 1e-3); else colours
//     red green blue when every row's are integers 0..255 (stored as uchar, as in PLY) or numbers
//     in 0..1 (floats, as in OBJ). Any other column k (counted from 0) is the float field
//     "field<k>".
// A column other than the coordinates is float32 unless one of its values does not fit one
// (more digits than a float holds: a GPS time 1634567890.123456, an integer above 2^24): such a
// column is double, so that every value is written back as it was read.
// Written back with the same columns in the same order, the same separator (as between the
// first row's first two values) and the row of names as it was written.
//
// Leica PTS (.pts, as scanners and Open3D write it) is the same with a first line holding the
// point count (checked against the rows) and no row of names: 4 columns are x y z intensity,
// 7 are x y z intensity red green blue, 6 as above (Open3D reads them as x y z red green blue).
// Written as PTS, a shape gives x y z, its intensity and its red green blue; what else it has
// is said lost.
#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <unordered_set>
#include <vector>

#include "io/internal.h"

namespace hgd::io_internal {
namespace {

/// Names and types of the columns of a file without a row of names (see the top of the file).
std::vector<std::pair<std::string, std::uint8_t>> inferColumns(std::size_t cols, const std::vector<double>& v,
                                                               const std::vector<char>& wide, bool pts) {
  const auto real = [&](std::size_t k) {
    return static_cast<std::uint8_t>(wide[k] ? Field::FLOAT64 : Field::FLOAT32);
  };
  std::vector<std::pair<std::string, std::uint8_t>> out = {
      {"x", Field::FLOAT64}, {"y", Field::FLOAT64}, {"z", Field::FLOAT64}};
  const std::size_t n = v.size() / cols;
  // PTS: an intensity in the fourth column of 4 or 7; the colours after it.
  const std::size_t first = pts && (cols == 4 || cols == 7) ? 4 : 3;
  if (first == 4) out.emplace_back("intensity", real(3));
  const bool three = pts ? cols == 7 || cols == 6 : cols == 6;
  bool unit = three && !pts, bytes = three, unit_range = three;
  for (std::size_t i = 0; i < n && (unit || bytes || unit_range); ++i) {
    const double* c = &v[i * cols + first];
    if (unit) unit = std::abs(std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]) - 1.0) <= 1e-3;
    for (int k = 0; k < 3; ++k) {
      bytes = bytes && c[k] >= 0 && c[k] <= 255 && c[k] == std::floor(c[k]);
      unit_range = unit_range && c[k] >= 0 && c[k] <= 1;
    }
  }
  if (unit) {
    for (const char* name : {"nx", "ny", "nz"}) out.emplace_back(name, real(out.size()));
  } else if (bytes || unit_range) {
    for (const char* name : {"red", "green", "blue"})
      out.emplace_back(name, bytes ? std::uint8_t{Field::UINT8} : real(out.size()));
  }
  for (std::size_t k = out.size(); k < cols; ++k) out.emplace_back("field" + num(k), real(k));
  return out;
}

}  // namespace

Shape readXyz(const std::string& path) {
  TextFile xyz(path);
  std::vector<std::string> names;
  std::vector<double> values;
  DecimalsSeen decimals;   // per column, for writing the values back as spelt
  std::vector<char> wide;  // per column: a value float32 does not hold
  std::size_t cols = 0, first_row = 0, count_row = 0;
  std::uint64_t count = 0;  // PTS: the point count on the first line
  std::string separator = " ", header;
  while (xyz.lex.nextLine()) {
    if (xyz.lex.peek() == '#') continue;
    const std::string_view text = xyz.lex.lineText();
    std::string_view line = text.substr(0, xyzCommentStart(text));  // "1 2 3 # a note"
    const std::vector<std::string_view> words = splitColumns(line);
    if (words.empty()) continue;
    std::size_t bad = words.size();  // the first value that is no number
    bool any_number = false;
    for (std::size_t k = 0; k < words.size(); ++k) {
      double d = 0;
      if (parseFloating(words[k], &d)) {
        any_number = true;
      } else {
        if (bad == words.size()) bad = k;
        // A number in a spelling not read (a hexadecimal float, which strtod takes) is no name.
        const std::string w(words[k]);
        char* end = nullptr;
        std::strtod(w.c_str(), &end);
        any_number = any_number || (end == w.c_str() + w.size());
      }
    }
    // A first row of names: none of them a number (a row with numbers is data, however malformed).
    if (bad < words.size() && !any_number && cols == 0) {
      header = std::string(text);
      if (line.rfind("//", 0) == 0) line.remove_prefix(2);
      std::unordered_set<std::string_view> seen;
      for (const auto w : splitColumns(line)) {
        if (!seen.insert(w).second)
          fail(path, "malformed header: line " + num(xyz.lex.line()) + " names column '" + std::string(w) +
                         "' twice");
        names.emplace_back(w);
      }
      if (names.size() < 3)
        fail(path, "malformed header: line " + num(xyz.lex.line()) + " names " + num(names.size()) +
                       " columns, at least 3 (x y z) needed");
      cols = names.size();
      first_row = xyz.lex.line();
      continue;
    }
    // PTS: a first line with one whole number, the count of the rows that follow.
    if (cols == 0 && count_row == 0 && words.size() == 1 && plainUnsigned(words[0]) &&
        parseU64(words[0], &count)) {
      count_row = xyz.lex.line();
      continue;
    }
    if (values.empty()) {
      if (cols == 0) {
        cols = words.size();
        first_row = xyz.lex.line();
        if (cols < 3)
          fail(path, "malformed data: line " + num(xyz.lex.line()) + ": a point needs 3 coordinates, found " +
                         num(cols));
      }
      if (words.size() >= 2)  // what lies between the first two values, kept for writing back
        separator = std::string(
            line.substr(static_cast<std::size_t>(words[0].data() + words[0].size() - line.data()),
                        static_cast<std::size_t>(words[1].data() - words[0].data()) - words[0].size()));
    }
    if (words.size() != cols)
      fail(path, "malformed data: line " + num(xyz.lex.line()) + " has " + num(words.size()) +
                     " values, expected " + num(cols) +
                     (names.empty() ? " (as line " : " (as named on line ") + num(first_row) + ")");
    if (bad < words.size()) {
      const std::string_view w = words[bad];
      const bool hex = w.find("0x") != std::string_view::npos || w.find("0X") != std::string_view::npos;
      fail(path, "non-numeric value " + excerpt(w) + " at line " + num(xyz.lex.line()) + " (column " +
                     num(bad + 1) + (hex ? "; hexadecimal numbers are not read" : "") + ")");
    }
    wide.resize(cols, 0);
    for (std::size_t k = 0; k < words.size(); ++k) {
      double d = 0;
      parseFloating(words[k], &d);
      if (overflowed(words[k], d))
        fail(path, "value out of range " + excerpt(words[k]) + " at line " + num(xyz.lex.line()) +
                       " (column " + num(k + 1) + "): beyond a double's range");
      values.push_back(d);
      decimals.see(k, words[k]);
      if (!wide[k] && !floatHolds(d)) wide[k] = 1;
    }
  }
  if (values.empty()) fail(path, "no points: the file has no rows of numbers");
  const std::size_t n = values.size() / cols;
  if (count_row != 0 && count != n)
    fail(path, "malformed data: line " + num(count_row) + " gives the point count " + num(count) +
                   ", the file has " + num(n) + " rows of points");
  if (n > std::numeric_limits<std::uint32_t>::max()) fail(path, "unsupported: more than 4294967295 points");

  std::vector<std::pair<std::string, std::uint8_t>> fields;
  if (names.empty()) {
    fields = inferColumns(cols, values, wide, count_row != 0);
  } else {
    std::vector<std::string> low(names.size());
    std::transform(names.begin(), names.end(), low.begin(), [](const std::string& s) { return lower(s); });
    const auto at = [&](const char* c) { return std::find(low.begin(), low.end(), c) - low.begin(); };
    const bool named_xyz = at("x") < static_cast<long>(cols) && at("y") < static_cast<long>(cols) &&
                           at("z") < static_cast<long>(cols);
    for (std::size_t k = 0; k < cols; ++k) {
      const bool coord = named_xyz ? (low[k] == "x" || low[k] == "y" || low[k] == "z") : k < 3;
      if (coord)
        fields.emplace_back(named_xyz ? low[k] : std::string(1, "xyz"[k]), Field::FLOAT64);
      else
        fields.emplace_back(names[k], wide[k] ? Field::FLOAT64 : Field::FLOAT32);
    }
    // CloudCompare's spellings: Nx Ny Nz are the normals and R G B (or Red Green Blue, any case)
    // the colours, uchar when every value is a whole number 0..255, under the names the other
    // formats' readers know. The row of names is kept as written (xyz_header).
    const auto triple = [&](std::initializer_list<std::array<const char*, 3>> spellings,
                            const char* const to[3], bool colour) {
      for (const auto& sp : spellings) {
        long k[3];
        for (int a = 0; a < 3; ++a) k[a] = at(sp[static_cast<std::size_t>(a)]);
        if (k[0] >= static_cast<long>(cols) || k[1] >= static_cast<long>(cols) ||
            k[2] >= static_cast<long>(cols))
          continue;
        if (std::any_of(low.begin(), low.end(), [&](const std::string& l) {
              return (l == to[0] || l == to[1] || l == to[2]) && l != sp[0] && l != sp[1] && l != sp[2];
            }))
          return;  // another column has the name already
        bool bytes = colour;
        for (int a = 0; a < 3 && bytes; ++a)
          for (std::size_t i = 0; i < n && bytes; ++i) {
            const double v = values[i * cols + static_cast<std::size_t>(k[a])];
            bytes = v >= 0 && v <= 255 && v == std::floor(v);
          }
        for (int a = 0; a < 3; ++a) {
          auto& f = fields[static_cast<std::size_t>(k[a])];
          f.first = to[a];
          if (bytes) f.second = Field::UINT8;
        }
        return;
      }
    };
    static const char* const kNormals[3] = {"nx", "ny", "nz"};
    static const char* const kColours[3] = {"red", "green", "blue"};
    triple({{"nx", "ny", "nz"}}, kNormals, false);
    triple({{"r", "g", "b"}, {"red", "green", "blue"}}, kColours, true);
    // CloudCompare's A beside its R G B: the alpha, uchar with them when its values are bytes.
    const long red = static_cast<long>(
        std::find_if(fields.begin(), fields.end(), [](const auto& f) { return f.first == "red"; }) -
        fields.begin());
    const long a = std::min(at("a"), at("alpha"));
    if (red < static_cast<long>(cols) && a < static_cast<long>(cols)) {
      bool bytes = fields[static_cast<std::size_t>(red)].second == Field::UINT8;
      for (std::size_t i = 0; i < n && bytes; ++i) {
        const double v = values[i * cols + static_cast<std::size_t>(a)];
        bytes = v >= 0 && v <= 255 && v == std::floor(v);
      }
      fields[static_cast<std::size_t>(a)].first = "alpha";
      if (bytes) fields[static_cast<std::size_t>(a)].second = Field::UINT8;
    }
    std::unordered_set<std::string_view> seen;  // "x" renamed from "X" may meet another column "x"
    for (const auto& f : fields)
      if (!seen.insert(f.first).second)
        fail(path, "malformed header: line " + num(first_row) + " names column '" + f.first + "' twice");
  }
  Shape shape;
  shape.cloud = makeCloud(n, fields, values);
  for (const auto& f : fields) shape.extras.xyz_names.push_back(f.first);
  decimals.store(shape.extras, shape.extras.xyz_names);
  shape.extras.xyz_header = std::move(header);
  shape.extras.xyz_separator = separator;
  shape.extras.xyz_count_line = count_row != 0;
  return shape;
}

int ptsIntensity(const pcl::PCLPointCloud2& cloud, const XyzFields& xyz) {
  for (std::size_t k = 0; k < cloud.fields.size(); ++k) {
    const Field& f = cloud.fields[k];
    const int i = static_cast<int>(k);
    if (lower(f.name) == "intensity" && fieldCount(f) == 1 && i != xyz.x && i != xyz.y && i != xyz.z)
      return i;
  }
  return -1;
}

void writeXyz(const std::string& path, const Shape& shape, bool pts) {
  std::vector<const Field*> fields = checkShape(path, shape, false);
  const pcl::PCLPointCloud2& c = shape.cloud;
  const XyzFields xyz = findXyzFields(c);
  if (!xyz.hasXyz()) fail(path, "cannot write: no x/y/z fields");
  if (pts) {  // x y z, intensity, red green blue: the columns PTS readers know (extrasLost says the rest)
    const auto at = [&](int k) { return &c.fields[static_cast<std::size_t>(k)]; };
    std::vector<const Field*> kept = {at(xyz.x), at(xyz.y), at(xyz.z)};
    if (const int i = ptsIntensity(c, xyz); i >= 0) kept.push_back(at(i));
    const int r = findField(c, "red"), g = findField(c, "green"), b = findField(c, "blue");
    if (r >= 0 && g >= 0 && b >= 0 && fieldCount(*at(r)) == 1 && fieldCount(*at(g)) == 1 &&
        fieldCount(*at(b)) == 1)
      kept.insert(kept.end(), {at(r), at(g), at(b)});
    fields = kept;
  }
  // The separator the file was read with: blanks and at most one comma, else a space.
  std::string sep = shape.extras.xyz_separator;
  if (sep.empty() || std::count(sep.begin(), sep.end(), ',') > 1 ||
      !std::all_of(sep.begin(), sep.end(), [](char ch) { return ch == ',' || ch == ' ' || ch == '\t'; }))
    sep = " ";
  std::vector<std::string> names;
  for (const Field* f : fields)
    for (std::size_t k = 0; k < fieldCount(*f); ++k)
      names.push_back(fieldCount(*f) > 1 ? f->name + "_" + num(k) : f->name);
  for (const std::string& name : names)
    if (name.find(',') != std::string::npos || name[0] == '#' || name.rfind("//", 0) == 0)
      fail(path, "cannot write: field name " + excerpt(name) + " cannot name an XYZ column");
  // The file's own row of names, as it was written, while the columns keep the names read from
  // it; else a row of names unless the reader would give the columns these names without one.
  const bool plain = names == std::vector<std::string>{"x", "y", "z"};
  // A file read as PTS names its columns by their count alone: written as XYZ it gets a row of
  // names. PTS has none.
  std::string buf;
  if (pts) {
    buf = num(shape.size()) + "\n";
  } else if (names == shape.extras.xyz_names && !shape.extras.xyz_header.empty()) {
    buf = shape.extras.xyz_header + "\n";
  } else if (!plain && (names != shape.extras.xyz_names || shape.extras.xyz_count_line)) {
    // As CloudCompare writes and reads one: "//X Y Z R G B Nx Ny Nz ...", its spellings for the
    // columns it knows (it ignores a row of names without the "//"); read back as these fields.
    static const char* const cc[][2] = {{"x", "X"},     {"y", "Y"},    {"z", "Z"},     {"red", "R"},
                                        {"green", "G"}, {"blue", "B"}, {"alpha", "A"}, {"nx", "Nx"},
                                        {"ny", "Ny"},   {"nz", "Nz"}};
    buf = "//";
    for (std::size_t k = 0; k < names.size(); ++k) {
      if (k) buf += sep;
      std::string name = names[k];
      for (const auto& m : cc)
        if (name == m[0]) name = m[1];
      buf += name;
    }
    buf += '\n';
  }
  AtomicWriter w(path);
  w.write(buf);
  writeAsciiPoints(w, c, shape.size(), fields, false, decimalsOf(shape.extras, fields), sep);
  w.commit();
}

}  // namespace hgd::io_internal
