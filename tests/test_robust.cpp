// Robustness: "scans are messy and files come from anywhere; hgdeform must never crash, hang,
// write garbage or lose a file."
//
//  - A corpus of bad PLY, PCD, OBJ and scenario files, generated here (many variants of each:
//    truncations, wrong counts, absurd sizes, non-numeric values, non-finite points, garbage,
//    odd file names), each rejected by the library and by the CLI with a message that names the
//    file and the problem; the CLI exits non-zero and leaves no output and no temporary file.
//  - Odd but readable input: NaN/inf points kept in place, duplicated points, non-ASCII paths.
//  - Degenerate geometry and numerical trouble through the library and the CLI: finite output
//    or a clear error, never a crash, a hang (CLI runs under `timeout 60`) or a NaN.
//  - Georeferenced coordinates (1e6 offsets, double PLY) deform like the centred shape.
//  - Out of memory under `ulimit -v` ends with a message, not a kill.
//  - Inputs found by the fuzzers (fuzz/) stay fixed.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "hgdeform/app/regions.h"
#include "hgdeform/app/runner.h"
#include "hgdeform/app/scenario.h"
#include "hgdeform/deformer/deformer.h"
#include "hgdeform/field/harmonic_field.h"
#include "hgdeform/io/fields.h"
#include "hgdeform/io/geometry.h"
#include "hgdeform/io/io.h"
#include "hgdeform/solve/solver.h"
#include "support/shapes.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;
using hgd::Shape;
using hgdtest::contains;
using hgdtest::put;
using hgdtest::quote;
using hgdtest::shell;
using hgdtest::slurp;
using hgdtest::TempDir;
using CliRun = hgdtest::CommandResult;
using Field = pcl::PCLPointField;

// --- helpers ---------------------------------------------------------------------------------

std::string floats(std::initializer_list<float> v, bool big_endian = false) {
  std::string s;
  for (const float f : v) put(s, f, big_endian);
  return s;
}

std::string repeat(const std::string& s, std::size_t n) {
  std::string out;
  out.reserve(s.size() * n);
  for (std::size_t i = 0; i < n; ++i) out += s;
  return out;
}

void writeBytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  out.close();
  ASSERT_TRUE(out.good()) << path;
}

std::set<std::string> listing(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.insert(e.path().filename().string());
  return names;
}

/// `hgdeform ARGS` under `timeout 60`: a hang is exit status 124, a crash 128 + signal.
CliRun cli(const std::string& args) {
  return shell("timeout 60 " + quote(HGD_TOOL) + " " + args);
}

/// The x/y/z of every point of a shape (world coordinates, file order).
std::vector<Eigen::Vector3d> positions(const Shape& s) {
  const hgd::XyzFields f = hgd::findXyzFields(s.cloud);
  std::vector<Eigen::Vector3d> p(s.size());
  for (std::size_t i = 0; i < s.size(); ++i)
    p[i] = {hgd::readValue(s.cloud, i, s.cloud.fields[static_cast<std::size_t>(f.x)]),
            hgd::readValue(s.cloud, i, s.cloud.fields[static_cast<std::size_t>(f.y)]),
            hgd::readValue(s.cloud, i, s.cloud.fields[static_cast<std::size_t>(f.z)])};
  return p;
}

/// Number of points with a non-finite coordinate.
std::size_t nonFinite(const std::vector<Eigen::Vector3d>& p) {
  return static_cast<std::size_t>(
      std::count_if(p.begin(), p.end(), [](const Eigen::Vector3d& v) { return !v.allFinite(); }));
}

/// A point cloud Shape with x/y/z of the given type (and no other field).
Shape xyzShape(const std::vector<Eigen::Vector3d>& pts, std::uint8_t type = Field::FLOAT32) {
  Shape s;
  const std::uint32_t size = static_cast<std::uint32_t>(hgd::datatypeSize(type));
  for (const char* n : {"x", "y", "z"}) {
    Field f;
    f.name = n;
    f.offset = static_cast<std::uint32_t>(s.cloud.fields.size()) * size;
    f.datatype = type;
    f.count = 1;
    s.cloud.fields.push_back(f);
  }
  s.cloud.width = static_cast<std::uint32_t>(pts.size());
  s.cloud.height = 1;
  s.cloud.point_step = 3 * size;
  s.cloud.row_step = s.cloud.point_step * s.cloud.width;
  s.cloud.data.assign(pts.size() * s.cloud.point_step, 0);
  for (std::size_t i = 0; i < pts.size(); ++i)
    for (int k = 0; k < 3; ++k)
      hgd::writeValue(s.cloud, i, s.cloud.fields[static_cast<std::size_t>(k)], pts[i][k]);
  return s;
}

/// Adds `offset` to every x/y/z of a shape, converting x/y/z to FLOAT64 (as georeferenced
/// scans are written) and keeping every other field.
Shape withOffset(const Shape& in, const Eigen::Vector3d& offset) {
  const std::vector<Eigen::Vector3d> p = positions(in);
  Shape out = in;
  pcl::PCLPointCloud2& c = out.cloud;
  // New layout: x y z as doubles first, then the other fields as they were.
  std::vector<Field> fields;
  std::uint32_t step = 0;
  for (const char* n : {"x", "y", "z"}) {
    Field f;
    f.name = n;
    f.offset = step;
    f.datatype = Field::FLOAT64;
    f.count = 1;
    fields.push_back(f);
    step += 8;
  }
  std::vector<std::pair<const Field*, Field>> kept;
  for (const auto& f : in.cloud.fields) {
    if (f.name == "x" || f.name == "y" || f.name == "z") continue;
    Field g = f;
    g.offset = step;
    step += static_cast<std::uint32_t>(hgd::datatypeSize(f.datatype) * std::max<std::uint32_t>(f.count, 1));
    fields.push_back(g);
    kept.emplace_back(&f, g);
  }
  c.fields = fields;
  c.point_step = step;
  c.row_step = step * c.width;
  c.data.assign(in.size() * step, 0);
  for (std::size_t i = 0; i < in.size(); ++i) {
    for (int k = 0; k < 3; ++k)
      hgd::writeValue(c, i, c.fields[static_cast<std::size_t>(k)], p[i][k] + offset[k]);
    for (const auto& [from, to] : kept)
      std::memcpy(c.data.data() + i * step + to.offset,
                  in.cloud.data.data() + i * in.cloud.point_step + from->offset,
                  hgd::datatypeSize(from->datatype) * std::max<std::uint32_t>(from->count, 1));
  }
  return out;
}

std::string vec(const Eigen::Vector3d& v) {
  std::ostringstream s;
  s.precision(17);
  s << "[" << v.x() << ", " << v.y() << ", " << v.z() << "]";
  return s.str();
}

std::string boxJson(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  return R"({"box": {"min": )" + vec(lo) + R"(, "max": )" + vec(hi) + "}}";
}

// The bar (shapes::bar(): [0, 1] x [-0.05, 0.05]^2), fixed at x = 0, manipulated at x = 1.
const std::string kBarHandles = R"("fixed": [ { "box": { "min": [-1, -1, -1], "max": [0.045, 1, 1] } } ],
  "manipulated": { "box": { "min": [0.955, -1, -1], "max": [2, 1, 1] } })";
const std::string kBarScenario = "{" + kBarHandles + R"(, "move": {"frame": {"translate": [0, 0.2, 0]}}})";

// --- the corpus of bad files ------------------------------------------------------------------

enum class Kind { Ply, Pcd, Obj, Scenario };

const char* kindName(Kind k) {
  switch (k) {
    case Kind::Ply: return "PLY";
    case Kind::Pcd: return "PCD";
    case Kind::Obj: return "OBJ";
    case Kind::Scenario: return "scenario";
  }
  return "?";
}

struct BadInput {
  std::string name;    ///< what the variant is (also the base of its file name)
  std::string bytes;   ///< the file's content
  std::string phrase;  ///< expected in the error message, besides the path
};

/// Bad inputs of one kind, each with the phrase its error must contain.
class Corpus {
 public:
  explicit Corpus(Kind kind) : kind_(kind) {}
  void add(const std::string& name, const std::string& bytes, const std::string& phrase) {
    inputs_.push_back({name, bytes, phrase});
  }
  Kind kind() const { return kind_; }
  const std::vector<BadInput>& inputs() const { return inputs_; }

 private:
  Kind kind_;
  std::vector<BadInput> inputs_;
};

std::string garbage(std::size_t n, unsigned seed, int lo = 0, int hi = 255) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> byte(lo, hi);
  std::string s(n, '\0');
  for (char& c : s) c = static_cast<char>(byte(rng));
  return s;
}

const std::string kXyz = "property float x\nproperty float y\nproperty float z\n";

std::string plyHead(const std::string& format, const std::string& count, const std::string& props = kXyz,
                    const std::string& extra = "") {
  return "ply\nformat " + format + " 1.0\nelement vertex " + count + "\n" + props + extra + "end_header\n";
}

const std::string kFaceList = "element face 1\nproperty list uchar int vertex_indices\n";

Corpus plyCorpus() {
  Corpus c(Kind::Ply);
  const std::string three = "0 0 0\n1 0 0\n0 1 0\n";
  const std::string le3 = floats({0, 0, 0, 1, 0, 0, 0, 1, 0});
  const std::string be3 = floats({0, 0, 0, 1, 0, 0, 0, 1, 0}, true);
  const std::string tera = "1000000000000";
  // Empty, magic and header structure.
  c.add("empty", "", "empty file");
  c.add("magic-only-no-newline", "ply", "malformed header");
  c.add("magic-only", "ply\n", "no end_header");
  c.add("wrong-magic", "plx\nformat ascii 1.0\nend_header\n", "malformed header");
  c.add("magic-with-trailing-word", "ply x\nformat ascii 1.0\nend_header\n", "malformed header");
  c.add("utf16-text", std::string("\xff\xfep\0l\0y\0\n\0", 10), "malformed header");
  c.add("no-format", "ply\nelement vertex 1\n" + kXyz + "end_header\n1 2 3\n", "no format line");
  c.add("two-formats",
        "ply\nformat ascii 1.0\nformat ascii 1.0\nelement vertex 1\n" + kXyz + "end_header\n1 2 3\n",
        "second format line");
  c.add("middle-endian", plyHead("binary_middle_endian", "3") + le3, "unsupported PLY format");
  c.add("version-2", "ply\nformat ascii 2.0\nelement vertex 3\n" + kXyz + "end_header\n" + three,
        "unsupported PLY version");
  c.add("no-end-header", "ply\nformat ascii 1.0\nelement vertex 3\n" + kXyz + three, "malformed header");
  c.add("unknown-keyword", plyHead("ascii", "3", kXyz, "bogus line\n") + three, "unknown keyword");
  c.add("nul-bytes-in-header", plyHead("ascii", "3", kXyz, std::string("\0\0\0\n", 4)) + three,
        "malformed header");
  c.add("header-line-of-2MB", "ply\nformat ascii 1.0\ncomment " + std::string(2 << 20, 'a') + "\n",
        "too long");
  c.add("property-before-element", "ply\nformat ascii 1.0\nproperty float x\nend_header\n",
        "property before any element");
  c.add("unknown-type",
        plyHead("ascii", "3", "property quad x\nproperty float y\nproperty float z\n") + three,
        "unsupported PLY property type");
  c.add("list-count-float",
        plyHead("ascii", "3", kXyz, "element face 1\nproperty list float int vertex_indices\n") + three +
            "3 0 1 2\n",
        "unsupported PLY list count type");
  c.add("duplicate-property", plyHead("ascii", "3", kXyz + "property float x\n") + three, "second property");
  c.add("duplicate-element", plyHead("ascii", "3", kXyz, "element vertex 3\n") + three, "second element");
  // Counts.
  c.add("count-not-a-number", plyHead("ascii", "abc") + three, "malformed header");
  c.add("count-negative", plyHead("ascii", "-3") + three, "malformed header");
  c.add("count-fraction", plyHead("ascii", "2.5") + three, "malformed header");
  c.add("count-beyond-uint64", plyHead("ascii", "18446744073709551616") + three, "malformed header");
  c.add("count-zero", plyHead("ascii", "0"), "no points");
  c.add("no-vertex-element",
        "ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n",
        "no points");
  c.add("ascii-fewer-lines", plyHead("ascii", "5") + three, "truncated data");
  c.add("ascii-more-lines", plyHead("ascii", "2") + three, "more data than the header declares");
  c.add("ascii-short-line", plyHead("ascii", "3") + "0 0 0\n1 0\n0 1 0\n", "truncated data");
  c.add("ascii-long-line", plyHead("ascii", "3") + "0 0 0 7\n1 0 0\n0 1 0\n",
        "more values than the header declares");
  c.add("ascii-10^12-points", plyHead("ascii", tera) + three, "truncated data");
  // Records of no properties take no bytes, yet writing them back takes a line each: 10^18 of
  // them filled the disk (ascii) or spun for ever (binary).
  c.add("ascii-10^18-empty-records",
        plyHead("ascii", "3", kXyz, "element junk 1000000000000000000\n") + three, "truncated data");
  c.add("binary-10^18-empty-records",
        plyHead("binary_little_endian", "3", kXyz, "element junk 1000000000000000000\n") + le3,
        "truncated data");
  c.add("binary-le-cut", plyHead("binary_little_endian", "3") + le3.substr(0, 30), "truncated data");
  c.add("binary-be-cut", plyHead("binary_big_endian", "3") + be3.substr(0, 35), "truncated data");
  c.add("binary-nothing-after-header", plyHead("binary_little_endian", "3"), "truncated data");
  c.add("binary-more-data", plyHead("binary_little_endian", "2") + le3, "more data than the header declares");
  c.add("binary-10^12-points", plyHead("binary_little_endian", tera) + le3, "truncated data");
  c.add("binary-2^64-1-double-points",
        plyHead("binary_little_endian", "18446744073709551615",
                "property double x\nproperty double y\nproperty double z\n") +
            le3,
        "truncated data");
  c.add("binary-10^12-faces",
        plyHead("binary_little_endian", "3", kXyz,
                "element face " + tera + "\nproperty list uchar int vertex_indices\n") +
            le3 + "\x03",
        "truncated data");
  {
    std::string face = le3 + "\xff";  // a face of 255 indices, none present
    put(face, std::int32_t{0});
    c.add("binary-face-list-longer-than-file", plyHead("binary_little_endian", "3", kXyz, kFaceList) + face,
          "truncated data");
    std::string wide = le3;
    put(wide, std::uint32_t{0xffffffffu});
    c.add("binary-face-count-uint-max",
          plyHead("binary_little_endian", "3", kXyz,
                  "element face 1\nproperty list uint int vertex_indices\n") +
              wide,
          "truncated data");
    std::string neg = le3 + "\xff";  // char count -1
    c.add("binary-negative-list-length",
          plyHead("binary_little_endian", "3", kXyz,
                  "element face 1\nproperty list char int vertex_indices\n") +
              neg,
          "negative list length");
    std::string bad = le3 + "\x03";
    put(bad, std::int32_t{0});
    put(bad, std::int32_t{1});
    put(bad, std::int32_t{-7});
    c.add("binary-negative-face-index", plyHead("binary_little_endian", "3", kXyz, kFaceList) + bad,
          "bad face index");
  }
  c.add("ascii-face-index-out-of-range", plyHead("ascii", "3", kXyz, kFaceList) + three + "3 0 1 3\n",
        "bad face index");
  c.add("ascii-face-of-two", plyHead("ascii", "3", kXyz, kFaceList) + three + "2 0 1\n", "bad face");
  c.add("ascii-face-count-word", plyHead("ascii", "3", kXyz, kFaceList) + three + "three 0 1 2\n",
        "non-numeric value");
  // Values.
  c.add("non-numeric-word", plyHead("ascii", "3") + "0 0 0\n1 zero 0\n0 1 0\n", "non-numeric value");
  c.add("non-numeric-two-dots", plyHead("ascii", "3") + "0 0 0\n1.2.3 0 0\n0 1 0\n", "non-numeric value");
  c.add("non-numeric-comma", plyHead("ascii", "3") + "0 0 0\n1,5 0 0\n0 1 0\n", "non-numeric value");
  c.add("non-numeric-hex", plyHead("ascii", "3") + "0 0 0\n0x10 0 0\n0 1 0\n", "non-numeric value");
  c.add("non-numeric-latin1", plyHead("ascii", "3") + "0 0 0\n1\xb5 0 0\n0 1 0\n", "non-numeric value");
  c.add("uchar-out-of-range",
        plyHead("ascii", "3", kXyz + "property uchar red\n") + "0 0 0 1\n1 0 0 300\n0 1 0 2\n",
        "value out of range");
  // A finite number beyond a float's or a double's range became an infinity, silently.
  c.add("float-1e39", plyHead("ascii", "3") + "0 0 0\n1e39 0 0\n0 1 0\n", "value out of range");
  c.add("double-1e400",
        plyHead("ascii", "3", "property double x\nproperty double y\nproperty double z\n") +
            "0 0 0\n1 -1e400 0\n0 1 0\n",
        "value out of range");
  c.add("int-with-fraction",
        plyHead("ascii", "3", kXyz + "property int label\n") + "0 0 0 1\n1 0 0 1.5\n0 1 0 2\n",
        "non-numeric value");
  // Fields and points.
  c.add("no-xyz", plyHead("ascii", "3", "property float a\nproperty float b\nproperty float c\n") + three,
        "no x/y/z fields");
  c.add("no-z", plyHead("ascii", "3", "property float x\nproperty float y\n") + "0 0\n1 0\n0 1\n",
        "no x/y/z fields");
  c.add("x-is-a-list",
        plyHead("ascii", "1", "property list uchar float x\nproperty float y\nproperty float z\n") +
            "1 5 0 0\n",
        "no x/y/z fields");
  c.add("all-nan-ascii", plyHead("ascii", "3") + "nan 0 0\n0 NaN 0\n0 0 nan\n", "no finite points");
  c.add("all-inf-binary",
        plyHead("binary_little_endian", "2") + floats({std::numeric_limits<float>::infinity(), 0, 0, 0,
                                                       -std::numeric_limits<float>::infinity(), 0}),
        "no finite points");
  // Issue 48: a finite number a float cannot hold is out of range (it was read as an infinity).
  c.add("all-overflowing-floats", plyHead("ascii", "2") + "1e39 0 0\n0 -1e40 0\n", "value out of range");
  c.add(
      "all-nan-double-be",
      plyHead("binary_big_endian", "1", "property double x\nproperty double y\nproperty double z\n") +
          [] {
            std::string s;
            for (int k = 0; k < 3; ++k) put(s, std::numeric_limits<double>::quiet_NaN(), true);
            return s;
          }(),
      "no finite points");
  // Garbage.
  c.add("random-bytes", garbage(4096, 1), "malformed header");
  c.add("png-signature", std::string("\x89PNG\r\n\x1a\n\0\0\0\rIHDR", 16), "malformed header");
  c.add("utf8-text",
        "ply\nformat ascii 1.0\n\xc3\xa9l\xc3\xa9ment vertex 3\n" + kXyz + "end_header\n" + three,
        "unknown keyword");
  return c;
}

std::string pcdHead(const std::string& data, const std::string& width = "3", const std::string& height = "1",
                    const std::string& points = "3",
                    const std::string& fields = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n") {
  return "# .PCD v0.7\nVERSION 0.7\n" + fields + "WIDTH " + width + "\nHEIGHT " + height +
         "\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + points + "\nDATA " + data + "\n";
}

/// An LZF stream of literal runs only (what pcl::lzfDecompress accepts).
std::string lzfLiterals(const std::string& raw) {
  std::string out;
  for (std::size_t i = 0; i < raw.size(); i += 32) {
    const std::string chunk = raw.substr(i, 32);
    out += static_cast<char>(chunk.size() - 1);
    out += chunk;
  }
  return out;
}

std::string compressedBlock(const std::string& lzf, std::uint32_t uncompressed) {
  std::string s;
  put(s, static_cast<std::uint32_t>(lzf.size()));
  put(s, uncompressed);
  return s + lzf;
}

Corpus pcdCorpus() {
  Corpus c(Kind::Pcd);
  const std::string three = "0 0 0\n1 0 0\n0 1 0\n";
  const std::string bin3 = floats({0, 0, 0, 1, 0, 0, 0, 1, 0});
  const std::string tera = "1000000000000";
  const std::string xyz = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n";
  c.add("empty", "", "empty file");
  c.add("no-data-line", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 3\n", "no DATA line");
  c.add("no-fields", "SIZE 4 4 4\nTYPE F F F\nWIDTH 3\nDATA ascii\n" + three, "no FIELDS line");
  c.add("no-size", "FIELDS x y z\nTYPE F F F\nWIDTH 3\nDATA ascii\n" + three, "no SIZE line");
  c.add("no-type", "FIELDS x y z\nSIZE 4 4 4\nWIDTH 3\nDATA ascii\n" + three, "no TYPE line");
  c.add("no-width-or-points", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nDATA ascii\n" + three,
        "no WIDTH or POINTS");
  c.add("size-count-mismatch",
        pcdHead("ascii", "3", "1", "3", "FIELDS x y z\nSIZE 4 4\nTYPE F F F\n") + three, "malformed header");
  c.add("type-count-mismatch",
        pcdHead("ascii", "3", "1", "3", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F\n") + three, "malformed header");
  c.add("count-count-mismatch",
        pcdHead("ascii", "3", "1", "3", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1\n") + three,
        "malformed header");
  c.add("type-letter", pcdHead("ascii", "3", "1", "3", "FIELDS x y z\nSIZE 4 4 4\nTYPE F X F\n") + three,
        "expected I, U or F");
  c.add("type-word", pcdHead("ascii", "3", "1", "3", "FIELDS x y z\nSIZE 4 4 4\nTYPE F FF F\n") + three,
        "malformed header");
  c.add("float-of-3-bytes", pcdHead("ascii", "3", "1", "3", "FIELDS x y z\nSIZE 4 3 4\nTYPE F F F\n") + three,
        "unsupported field type");
  c.add("int-of-8-bytes", pcdHead("ascii", "3", "1", "3", "FIELDS x y z\nSIZE 8 8 8\nTYPE I I I\n") + three,
        "unsupported field type");
  c.add("count-zero",
        pcdHead("ascii", "3", "1", "3", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 0 1\n") + three,
        "COUNT 0");
  c.add("size-not-a-number",
        pcdHead("ascii", "3", "1", "3", "FIELDS x y z\nSIZE 4 four 4\nTYPE F F F\n") + three, "bad number");
  c.add("points-differ-from-width", pcdHead("ascii", "3", "1", "2") + three, "differs from WIDTH x HEIGHT");
  c.add("width-negative", pcdHead("ascii", "-3", "1", "3") + three, "malformed header");
  c.add("width-word", pcdHead("ascii", "three", "1", "3") + three, "malformed header");
  c.add("width-exponent", pcdHead("ascii", "3e0", "1", "3") + three, "malformed header");
  c.add("repeated-width", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 3\nWIDTH 3\nDATA ascii\n" + three,
        "repeated width");
  c.add("unknown-keyword", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 3\nDEPTH 2\nDATA ascii\n" + three,
        "unknown keyword");
  c.add("version-9", "VERSION 9.9\n" + xyz + "WIDTH 3\nDATA ascii\n" + three, "unsupported PCD version");
  c.add("data-zip", pcdHead("zip") + three, "unsupported PCD data encoding");
  c.add("viewpoint-six-numbers", xyz + "WIDTH 3\nVIEWPOINT 0 0 0 1 0 0\nDATA ascii\n" + three,
        "expected 7 numbers");
  c.add("viewpoint-word", xyz + "WIDTH 3\nVIEWPOINT 0 0 zero 1 0 0 0\nDATA ascii\n" + three, "bad number");
  c.add("zero-points", pcdHead("binary", "0", "1", "0"), "no points");
  c.add("height-zero", pcdHead("ascii", "3", "0", "0") + three, "no points");
  c.add("no-xyz", pcdHead("ascii", "3", "1", "3", "FIELDS a b c\nSIZE 4 4 4\nTYPE F F F\n") + three,
        "no x/y/z fields");
  c.add("binary-cut", pcdHead("binary") + bin3.substr(0, 35), "truncated data");
  c.add("binary-more-data", pcdHead("binary", "2", "1", "2") + bin3, "more data than");
  c.add("binary-10^12-points", pcdHead("binary", tera, "1", tera) + bin3, "truncated data");
  c.add("binary-2^32-squared-points",
        pcdHead("binary", "4294967295", "4294967295", "18446744065119617025") + bin3, "truncated data");
  c.add("ascii-10^12-points", pcdHead("ascii", tera, "1", tera) + three, "truncated data");
  c.add("ascii-huge-padding",
        pcdHead("ascii", "3", "1", "3",
                "FIELDS x y z _\nSIZE 4 4 4 1\nTYPE F F F U\nCOUNT 1 1 1 2000000000\n") +
            three,
        "implausible");
  const std::string raw = bin3.substr(0, 12) + bin3.substr(12, 12) + bin3.substr(24, 12);
  c.add("compressed-10^12-points",
        pcdHead("binary_compressed", tera, "1", tera) + compressedBlock(lzfLiterals(raw), 36),
        "truncated data");
  c.add("compressed-block-beyond-file",
        pcdHead("binary_compressed") + compressedBlock(lzfLiterals(raw), 36).substr(0, 20), "truncated data");
  c.add("compressed-no-block-sizes", pcdHead("binary_compressed") + "\x05", "truncated data");
  c.add("compressed-wrong-size", pcdHead("binary_compressed") + compressedBlock(lzfLiterals(raw), 40),
        "the compressed block declares");
  c.add("compressed-corrupt", pcdHead("binary_compressed") + compressedBlock(std::string("\x20\xff", 2), 36),
        "corrupt compressed block");
  c.add("ascii-non-numeric", pcdHead("ascii") + "0 0 0\n1 zero 0\n0 1 0\n", "non-numeric value");
  c.add("ascii-comma-decimal", pcdHead("ascii") + "0 0 0\n1,5 0 0\n0 1 0\n", "non-numeric value");
  c.add("ascii-too-many-values", pcdHead("ascii") + "0 0 0\n1 0 0 1\n0 1 0\n", "has more than 3 values");
  c.add("ascii-too-few-values", pcdHead("ascii") + "0 0 0\n1 0\n0 1 0\n", "truncated data");
  c.add("ascii-fewer-lines", pcdHead("ascii") + "0 0 0\n1 0 0\n", "truncated data");
  c.add("ascii-more-lines", pcdHead("ascii", "2", "1", "2") + three, "more data than the header declares");
  c.add("ascii-float-1e39", pcdHead("ascii") + "0 0 0\n1 0 1e39\n0 1 0\n", "value out of range");
  c.add("ascii-uchar-256",
        pcdHead("ascii", "3", "1", "3", "FIELDS x y z i\nSIZE 4 4 4 1\nTYPE F F F U\n") +
            "0 0 0 1\n1 0 0 256\n0 1 0 2\n",
        "value out of range");
  c.add("all-nan-binary", pcdHead("binary", "1", "1", "1") + floats({NAN, NAN, NAN}), "no finite points");
  c.add("all-nan-organized-ascii", pcdHead("ascii", "2", "2", "4") + repeat("nan nan nan\n", 4),
        "no finite points");
  c.add("random-bytes", garbage(4096, 2), "malformed header");
  c.add("fields-without-names", "FIELDS\nSIZE\nTYPE\nWIDTH 1\nDATA ascii\n1\n", "malformed header");
  return c;
}

Corpus objCorpus() {
  Corpus c(Kind::Obj);
  const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  c.add("empty", "", "empty file");
  c.add("only-comments", "# nothing here\n# at all\n", "no points");
  c.add("only-normals", "vn 0 0 1\nvt 0 0\n", "no points");
  c.add("only-faces", "f 1 2 3\n", "no points");
  c.add("vertex-of-two", "v 1 2\n", "a vertex needs 3 coordinates");
  c.add("vertex-empty", "v\n", "a vertex needs 3 coordinates");
  c.add("vertex-word", "v 1 2 x\n", "non-numeric value");
  c.add("vertex-comma", tri + "v 1,0 2 3\n", "non-numeric value");
  c.add("vertex-nul", std::string("v 1 2\0 3\n", 9), "non-numeric value");
  c.add("vertex-latin1", tri + "v 1 2 3\xb0\n", "non-numeric value");
  c.add("face-index-zero", tri + "f 0 1 2\n", "bad face index");
  c.add("face-index-past-end", tri + "f 1 2 4\n", "bad face index");
  c.add("face-negative-past-start", tri + "f -1 -2 -4\n", "bad face index");
  c.add("face-index-word", tri + "f a b c\n", "bad face index");
  c.add("face-index-fraction", tri + "f 1 2 2.5\n", "bad face index");
  c.add("face-index-20-digits", tri + "f 1 2 99999999999999999999\n", "bad face index");
  c.add("face-index-int-overflow", tri + "f 1 2 4294967296\n", "bad face index");
  c.add("face-of-two", tri + "f 1 2\n", "bad face");
  c.add("face-slash-first", tri + "f /1 2 3\n", "bad face index");
  c.add("all-nan", "v nan nan nan\nv nan 0 0\nv 0 0 NaN\n", "no finite points");
  c.add("all-inf", "v inf 0 0\nv 0 -inf 0\n", "no finite points");
  c.add("all-overflowing", "v 1e999 0 0\nv 0 -1e400 0\n", "no finite points");
  c.add("binary-high-bytes", garbage(4096, 3, 128, 255), "no points");
  c.add("binary-control-bytes", garbage(4096, 4, 1, 31), "no points");
  return c;
}

std::string scenarioWith(const std::string& body) {
  return "{" + body + "}";
}

Corpus scenarioCorpus() {
  Corpus c(Kind::Scenario);
  const std::string fixed = R"("fixed": [{"box": {"min": [-1, -1, -1], "max": [0.045, 1, 1]}}])";
  const std::string manip = R"("manipulated": {"box": {"min": [0.955, -1, -1], "max": [2, 1, 1]}})";
  const std::string handles = fixed + ", " + manip;
  const auto withMove = [&](const std::string& move) {
    return scenarioWith(handles + R"(, "move": )" + move);
  };
  const auto withManip = [&](const std::string& region) {
    return scenarioWith(fixed + R"(, "manipulated": )" + region);
  };
  // Not JSON.
  c.add("empty", "", "empty file");
  c.add("open-brace", "{", "invalid JSON");
  c.add("truncated", scenarioWith(handles).substr(0, 40), "invalid JSON");
  c.add("trailing-comma", scenarioWith(handles + ","), "invalid JSON");
  c.add("comment", "// handles\n" + scenarioWith(handles), "invalid JSON");
  c.add("single-quotes", "{'fixed': []}", "invalid JSON");
  c.add("nan-literal", withManip(R"({"sphere": {"center": [NaN, 0, 0], "radius": 1}})"), "invalid JSON");
  c.add("infinity-literal", withManip(R"({"sphere": {"center": [0, 0, 0], "radius": Infinity}})"),
        "invalid JSON");
  c.add("number-overflow", withManip(R"({"sphere": {"center": [0, 0, 0], "radius": 1e400}})"),
        "invalid JSON");
  c.add("invalid-utf8-key", scenarioWith(handles + ", \"\xff\xfe\": 1"), "invalid JSON");
  c.add("nul-byte", std::string("{\"fixed\"\0: []}", 14), "invalid JSON");
  c.add("utf16", std::string("\xff\xfe{\0}\0", 6), "invalid JSON");
  c.add("random-bytes", garbage(1024, 5), "invalid JSON");
  c.add("two-documents", scenarioWith(handles) + scenarioWith(handles), "invalid JSON");
  // Not a scenario.
  c.add("top-level-array", "[" + scenarioWith(handles) + "]", "must be an object");
  c.add("top-level-number", "42", "must be an object");
  c.add("deep-array", std::string(100000, '[') + std::string(100000, ']'), "must be an object");
  c.add("missing-fixed", scenarioWith(manip), "/fixed: is required");
  c.add("missing-manipulated", scenarioWith(fixed), "/manipulated: is required");
  c.add("fixed-not-array", scenarioWith(R"("fixed": {"indices": [0]}, )" + manip),
        "must be a non-empty array");
  c.add("fixed-empty", scenarioWith(R"("fixed": [], )" + manip), "must be a non-empty array");
  c.add("unknown-key", scenarioWith(handles + R"(, "clusterz": 8)"), "/clusterz: unknown key");
  c.add("unknown-key-with-control-char", scenarioWith(handles + ", \"a\\u0001b\": 8"),
        "/a\\u0001b: unknown key");
  c.add("duplicate-key", scenarioWith(handles + ", " + fixed), "/fixed: duplicate key");
  c.add("duplicate-nested-key", withManip(R"({"sphere": {"center": [0, 0, 0], "radius": 1, "radius": 2}})"),
        "/manipulated/sphere/radius: duplicate key");
  c.add("wrong-format", scenarioWith(R"("format": "hgdeform-scenario/2", )" + handles), "/format: must be");
  c.add("region-two-kinds", withManip(R"({"indices": [1], "sphere": {"center": [0, 0, 0], "radius": 1}})"),
        "exactly one of");
  c.add("region-unknown-kind", withManip(R"({"cone": {"radius": 1}})"), "unknown region kind");
  c.add("region-not-object", withManip("7"), "/manipulated: must be an object");
  c.add("radius-zero", withManip(R"({"sphere": {"center": [1, 0, 0], "radius": 0}})"),
        "must be a positive number");
  c.add("radius-negative", withManip(R"({"sphere": {"center": [1, 0, 0], "radius": -1}})"),
        "must be a positive number");
  c.add("radius-string", withManip(R"({"sphere": {"center": [1, 0, 0], "radius": "1"}})"),
        "must be a number");
  c.add("radius-null", withManip(R"({"sphere": {"center": [1, 0, 0], "radius": null}})"), "must be a number");
  c.add("radius-missing", withManip(R"({"sphere": {"center": [1, 0, 0]}})"), "/radius: is required");
  c.add("center-of-two", withManip(R"({"sphere": {"center": [1, 0], "radius": 1}})"),
        "must be an array of 3 numbers");
  c.add("center-string", withManip(R"({"sphere": {"center": [1, "0", 0], "radius": 1}})"),
        "/center/1: must be a number");
  c.add("sphere-unknown-key", withManip(R"({"sphere": {"centre": [1, 0, 0], "radius": 1}})"), "unknown key");
  c.add("box-min-above-max", withManip(R"({"box": {"min": [2, -1, -1], "max": [1, 1, 1]}})"),
        "must not exceed max");
  c.add("indices-empty", withManip(R"({"indices": []})"), "must be a non-empty array of point indices");
  c.add("indices-negative", withManip(R"({"indices": [3, -1]})"),
        "/indices/1: must be a non-negative integer");
  c.add("indices-fraction", withManip(R"({"indices": [1.5]})"), "must be a non-negative integer");
  c.add("indices-2^64-1", withManip(R"({"indices": [18446744073709551615]})"),
        "must be a non-negative integer");
  c.add("indices-out-of-range", withManip(R"({"indices": [10000000]})"), "out of range");
  c.add("cylinder-radius-zero",
        withManip(R"({"cylinder": {"start": [1, 0, 0], "end": [2, 0, 0], "radius": 0}})"),
        "/manipulated/cylinder/radius: must be a positive number");
  c.add("cylinder-start-is-end",
        withManip(R"({"cylinder": {"start": [1, 0, 0], "end": [1, 0, 0], "radius": 1}})"),
        "/manipulated/cylinder/end: must differ from start");
  c.add("field-not-in-shape", withManip(R"({"field": {"name": "label", "equals": 1}})"),
        "/manipulated/field/name: the shape has no field 'label' (its fields: x, y, z");
  c.add("field-equals-and-min", withManip(R"({"field": {"name": "label", "equals": 1, "min": 0}})"),
        "/manipulated/field/min: cannot go with equals");
  c.add("field-min-above-max", withManip(R"({"field": {"name": "label", "min": 2, "max": 1}})"),
        "/manipulated/field/min: must not exceed max");
  c.add("region-selects-nothing", withManip(R"({"sphere": {"center": [50, 50, 50], "radius": 1}})"),
        "selects no point");
  c.add("fixed-and-manipulated-overlap", withManip(R"({"box": {"min": [-1, -1, -1], "max": [2, 1, 1]}})"),
        "both fixed and manipulated");
  c.add("joint-overlaps-handle",
        scenarioWith(handles + R"(, "joints": [{"box": {"min": [0.9, -1, -1], "max": [2, 1, 1]}}])"),
        "joint overlaps a handle");
  c.add("joints-not-array", scenarioWith(handles + R"(, "joints": {"indices": [5]})"),
        "must be an array of regions");
  c.add("clusters-zero", scenarioWith(handles + R"(, "clusters": 0)"), "must be an integer from 1 to 1000");
  c.add("clusters-too-many", scenarioWith(handles + R"(, "clusters": 1001)"),
        "must be an integer from 1 to 1000");
  c.add("clusters-fraction", scenarioWith(handles + R"(, "clusters": 2.5)"),
        "must be an integer from 1 to 1000");
  c.add("clusters-string", scenarioWith(handles + R"(, "clusters": "16")"),
        "must be an integer from 1 to 1000");
  c.add("move-empty-list", withMove("[]"), "must not be empty");
  c.add("move-unknown", withMove(R"({"twist": {}})"), "unknown move");
  c.add("move-two-kinds", withMove(R"({"drag": {}, "frame": {}})"), "exactly one of");
  c.add("drag-without-to", withMove(R"({"drag": {"from": [1, 0, 0]}})"), "/move/drag/to: is required");
  c.add("drag-to-far-away", withMove(R"({"drag": {"from": [1, 0, 0], "to": [1e16, 0, 0]}})"),
        "/move/drag/to/0: must be a coordinate between");
  c.add("frame-empty", withMove(R"({"frame": {}})"), "needs translate and/or rotate");
  c.add("translate-huge", withMove(R"({"frame": {"translate": [0, -1e300, 0]}})"),
        "must be a coordinate between");
  c.add("axis-zero", withMove(R"({"frame": {"rotate": {"axis": [0, 0, 0], "degrees": 10}}})"),
        "must not be the zero vector");
  c.add("axis-underflows", withMove(R"({"frame": {"rotate": {"axis": [1e-160, 0, 0], "degrees": 10}}})"),
        "moderate length");
  // The issue: an axis whose squared length underflows to 0 was said to be the zero vector.
  c.add("axis-underflows-to-zero",
        withMove(R"({"frame": {"rotate": {"axis": [0, 0, 1e-300], "degrees": 10}}})"),
        "moderate length (its length underflows)");
  c.add("axis-overflows", withMove(R"({"frame": {"rotate": {"axis": [1e200, 1e200, 0], "degrees": 10}}})"),
        "moderate length");
  c.add("degrees-string", withMove(R"({"frame": {"rotate": {"axis": [0, 0, 1], "degrees": "10"}}})"),
        "must be a number");
  c.add("degrees-huge", withMove(R"({"frame": {"rotate": {"axis": [0, 0, 1], "degrees": 1e300}}})"),
        "must be between");
  c.add("degrees-missing", withMove(R"({"frame": {"rotate": {"axis": [0, 0, 1]}}})"),
        "/degrees: is required");
  c.add("moves-nested-64-deep",
        withMove(std::string(64, '[') + R"({"frame": {"translate": [0, 0, 1]}})" + std::string(64, ']')),
        "nested more than");
  c.add("move-list-with-bad-item",
        withMove(R"([{"frame": {"translate": [0, 0, 1]}}, {"frame": {"translate": [0, 0]}}])"),
        "/move/1/frame/translate: must be an array of 3 numbers");
  return c;
}

std::vector<Corpus> allCorpora() {
  return {plyCorpus(), pcdCorpus(), objCorpus(), scenarioCorpus()};
}

/// File names: every third a name with non-ASCII letters, an emoji, spaces and a quote, so that
/// messages are checked to carry such paths intact.
std::string fileName(Kind kind, std::size_t index, const std::string& name) {
  const char* ext = kind == Kind::Ply   ? ".ply"
                    : kind == Kind::Pcd ? ".pcd"
                    : kind == Kind::Obj ? ".obj"
                                        : ".json";
  char prefix[16];
  std::snprintf(prefix, sizeof prefix, "%03zu-", index);
  const std::string fancy = index % 3 == 1 ? "scan d\xc3\xa9j\xc3\xa0 vu \xf0\x9f\x99\x82 it's " : "";
  return prefix + fancy + name + ext;
}

class RobustCorpus : public ::testing::TestWithParam<Kind> {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir;
    // A good shape and a good scenario, for the CLI runs whose other input is the bad one.
    hgd::writeShape(dir_->file("bar.ply"), hgd::shapes::bar());
    writeBytes(dir_->file("bar.json"), kBarScenario);
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static TempDir* dir_;
};
TempDir* RobustCorpus::dir_ = nullptr;

/// The library's verdict on a bad input: the message of the exception thrown while reading it
/// (and, for shapes, extracting the points to deform; for scenarios, resolving the regions
/// on the bar), or "" when it was accepted.
std::string libraryError(Kind kind, const std::string& path, const Shape& bar_shape,
                         const hgd::Geometry& bar) {
  try {
    if (kind == Kind::Scenario) {
      const hgd::Scenario s = hgd::readScenario(path);
      hgd::resolveHandles(s, bar, bar_shape);
    } else {
      const Shape s = hgd::readShape(path);
      hgd::extractGeometry(s);
    }
  } catch (const hgd::IoError& e) {
    if (kind == Kind::Scenario) ADD_FAILURE() << "IoError for a scenario: " << e.what();
    return e.what();
  } catch (const hgd::ScenarioError& e) {
    if (kind != Kind::Scenario) ADD_FAILURE() << "ScenarioError for a shape: " << e.what();
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << path << ": unexpected exception type: " << e.what();
    return e.what();
  }
  return "";
}

TEST_P(RobustCorpus, EveryBadInputIsRejectedClearlyByLibraryAndCli) {
  const Kind kind = GetParam();
  const Corpus corpus = [&] {
    for (Corpus& c : allCorpora())
      if (c.kind() == kind) return c;
    return Corpus(kind);
  }();
  const Shape bar_shape = hgd::readShape(dir_->file("bar.ply"));
  const hgd::Geometry bar = hgd::extractGeometry(bar_shape);
  TempDir work;
  const char* outputs[] = {"out.ply", "out.pcd", "out.obj"};
  std::size_t index = 0, cli_runs = 0;
  for (const BadInput& in : corpus.inputs()) {
    SCOPED_TRACE(std::string(kindName(kind)) + " input '" + in.name + "'");
    const std::string path = work.file(fileName(kind, index, in.name));
    writeBytes(path, in.bytes);

    const std::string message = libraryError(kind, path, bar_shape, bar);
    EXPECT_FALSE(message.empty()) << "accepted by the library";
    EXPECT_TRUE(contains(message, path)) << "the message does not name the file: " << message;
    EXPECT_TRUE(contains(message, in.phrase)) << "expected '" << in.phrase << "' in: " << message;

    // The CLI: field and deform in turn, outputs of every format in turn.
    const std::string command = index % 2 == 0 ? "field" : "deform";
    const std::string out = work.file(outputs[index % 3]);
    const std::set<std::string> before = listing(work.path());
    const std::string shape = kind == Kind::Scenario ? dir_->file("bar.ply") : path;
    const std::string scenario = kind == Kind::Scenario ? path : dir_->file("bar.json");
    const CliRun r =
        cli(command + " " + quote(shape) + " -s " + quote(scenario) + " -o " + quote(out) + " -q");
    ++cli_runs;
    EXPECT_EQ(r.code, 1) << command << ": " << r.err;
    EXPECT_TRUE(contains(r.err, "hgdeform " + command + ": ")) << r.err;
    EXPECT_TRUE(contains(r.err, path)) << "the CLI's message does not name the file: " << r.err;
    EXPECT_TRUE(contains(r.err, in.phrase)) << "expected '" << in.phrase << "' in: " << r.err;
    EXPECT_FALSE(fs::exists(out)) << "output written for a bad input";
    EXPECT_EQ(listing(work.path()), before) << "the CLI left a file behind";
    ++index;
  }
  std::printf("[ robust   ] %s corpus: %zu bad inputs, each through the library and the CLI (%zu runs)\n",
              kindName(kind), corpus.inputs().size(), cli_runs);
}

INSTANTIATE_TEST_SUITE_P(Kinds, RobustCorpus,
                         ::testing::Values(Kind::Ply, Kind::Pcd, Kind::Obj, Kind::Scenario),
                         [](const ::testing::TestParamInfo<Kind>& p) {
                           return std::string(kindName(p.param));
                         });

TEST(RobustCorpusSize, AtLeastAHundredInputs) {
  std::size_t total = 0;
  std::string counts;
  std::set<std::string> names;
  for (const Corpus& c : allCorpora()) {
    total += c.inputs().size();
    counts += std::string(counts.empty() ? "" : ", ") + kindName(c.kind()) + " " +
              std::to_string(c.inputs().size());
    for (const BadInput& in : c.inputs())
      EXPECT_TRUE(names.insert(std::string(kindName(c.kind())) + "/" + in.name).second)
          << "twice: " << in.name;
  }
  std::printf("[ robust   ] bad inputs: %s; %zu in all\n", counts.c_str(), total);
  EXPECT_GE(total, 100u);
}

// --- odd but readable input -------------------------------------------------------------------

TEST(RobustInput, MissingFilesDirectoriesAndFifosAreRefused) {
  TempDir dir;
  fs::create_directory(dir.file("folder.ply"));
  fs::create_directory(dir.file("folder.json"));
  ASSERT_EQ(::mkfifo(dir.file("fifo.ply").c_str(), 0600), 0);
  ASSERT_EQ(::mkfifo(dir.file("fifo.json").c_str(), 0600), 0);
  hgd::writeShape(dir.file("bar.ply"), hgd::shapes::bar());
  writeBytes(dir.file("bar.json"), kBarScenario);
  for (const char* name : {"missing.ply", "folder.ply", "fifo.ply"}) {
    const std::string p = dir.file(name);
    try {
      hgd::readShape(p);
      ADD_FAILURE() << name << " was read";
    } catch (const hgd::IoError& e) {
      EXPECT_TRUE(contains(e.what(), p + ": cannot open")) << e.what();
    }
    const CliRun r =
        cli("deform " + quote(p) + " -s " + quote(dir.file("bar.json")) + " -o " + quote(dir.file("o.ply")));
    EXPECT_EQ(r.code, 1) << r.err;
    EXPECT_TRUE(contains(r.err, p + ": cannot open")) << r.err;
  }
  for (const char* name : {"missing.json", "folder.json", "fifo.json"}) {
    const std::string p = dir.file(name);
    try {
      hgd::readScenario(p);
      ADD_FAILURE() << name << " was read";
    } catch (const hgd::ScenarioError& e) {
      EXPECT_TRUE(contains(e.what(), p + ": cannot open scenario file")) << e.what();
    }
    const CliRun r =
        cli("field " + quote(dir.file("bar.ply")) + " -s " + quote(p) + " -o " + quote(dir.file("o.ply")));
    EXPECT_EQ(r.code, 1) << r.err;
    EXPECT_TRUE(contains(r.err, p + ": cannot open scenario file")) << r.err;
  }
  EXPECT_FALSE(fs::exists(dir.file("o.ply")));
}

TEST(RobustInput, NonAsciiPathsWorkAndAppearIntactInMessages) {
  TempDir dir;
  const std::string sub = dir.file("r\xc3\xa9pertoire avec espaces \xe2\x9c\x93");
  fs::create_directory(sub);
  const std::string in = sub + "/scan \xc3\xbc \xf0\x9f\x99\x82 it's #1.ply";
  const std::string scenario = sub + "/sc\xc3\xa9nario \xf0\x9f\x8e\xaf.json";
  const std::string out = sub +
                          "/d\xc3\xa9"
                          "form\xc3\xa9 \xf0\x9f\x9a\x80.pcd";
  const std::string raw = sub + "/bytes \xff\xfe not utf-8.obj";  // any bytes but '/' and NUL
  hgd::writeShape(in, hgd::shapes::bar());
  hgd::writeShape(raw, hgd::shapes::bar());
  writeBytes(scenario, kBarScenario);
  EXPECT_EQ(hgd::readShape(in).size(), hgd::shapes::bar().size());
  EXPECT_EQ(hgd::readShape(raw).size(), hgd::shapes::bar().size());

  CliRun r = cli("deform " + quote(in) + " -s " + quote(scenario) + " -o " + quote(out));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(contains(r.out, in)) << r.out;
  EXPECT_TRUE(contains(r.out, out)) << r.out;
  EXPECT_EQ(hgd::readShape(out).size(), hgd::shapes::bar().size());
  r = cli("field " + quote(raw) + " -s " + quote(scenario) + " -o " + quote(sub + "/\xf0\x9f\x8c\x88.ply"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(fs::exists(sub + "/\xf0\x9f\x8c\x88.ply"));

  // Errors name such files byte for byte.
  const std::string bad = sub + "/cass\xc3\xa9 \xf0\x9f\x92\xa5.ply";
  writeBytes(bad, "ply\nformat ascii 1.0\nelement vertex 9\n" + kXyz + "end_header\n1 2 3\n");
  r = cli("deform " + quote(bad) + " -s " + quote(scenario) + " -o " + quote(sub + "/never.ply"));
  EXPECT_EQ(r.code, 1);
  EXPECT_TRUE(contains(r.err, bad + ": truncated data")) << r.err;
  writeBytes(scenario, "{\"fixed\": 1}");
  r = cli("deform " + quote(in) + " -s " + quote(scenario) + " -o " + quote(sub + "/never.ply"));
  EXPECT_EQ(r.code, 1);
  EXPECT_TRUE(contains(r.err, scenario + ": /fixed: must be a non-empty array")) << r.err;
  EXPECT_FALSE(fs::exists(sub + "/never.ply"));
}

TEST(RobustInput, ByteOrderMarkIsSkipped) {
  TempDir dir;
  const std::string bom = "\xef\xbb\xbf";
  writeBytes(dir.file("a.obj"), bom + "v 1 2 3\nv 4 5 6\nv 7 8 10\nf 1 2 3\n");
  const Shape obj = hgd::readShape(dir.file("a.obj"));
  ASSERT_EQ(obj.size(), 3u);  // the first vertex is not lost
  EXPECT_EQ(positions(obj)[0], Eigen::Vector3d(1, 2, 3));
  writeBytes(dir.file("a.ply"), bom + plyHead("ascii", "1") + "1 2 3\n");
  EXPECT_EQ(hgd::readShape(dir.file("a.ply")).size(), 1u);
  writeBytes(dir.file("a.pcd"), bom + pcdHead("ascii", "1", "1", "1") + "1 2 3\n");
  EXPECT_EQ(hgd::readShape(dir.file("a.pcd")).size(), 1u);
  writeBytes(dir.file("a.json"), bom + kBarScenario);
  EXPECT_EQ(hgd::readScenario(dir.file("a.json")).fixed.size(), 1u);
}

/// The bar with some points made NaN or infinite (not all): `bad` gets their indices.
Shape barWithNonFinitePoints(std::vector<std::size_t>* bad) {
  Shape s = hgd::shapes::bar();
  const hgd::XyzFields f = hgd::findXyzFields(s.cloud);
  const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
  for (std::size_t i = 5; i < s.size(); i += 37) {
    const double v = i % 3 == 0 ? nan : (i % 3 == 1 ? inf : -inf);
    hgd::writeValue(s.cloud, i, s.cloud.fields[static_cast<std::size_t>(i % 2 ? f.x : f.z)], v);
    bad->push_back(i);
  }
  return s;
}

TEST(RobustInput, NonFinitePointsAreDroppedForComputationAndKeptInPlace) {
  TempDir dir;
  std::vector<std::size_t> bad;
  const Shape shape = barWithNonFinitePoints(&bad);
  ASSERT_GT(bad.size(), 50u);
  const std::vector<Eigen::Vector3d> before = positions(shape);
  const auto check = [&](const Shape& out, const std::string& what) {
    SCOPED_TRACE(what);
    const std::vector<Eigen::Vector3d> after = positions(out);
    ASSERT_EQ(after.size(), before.size());
    std::set<std::size_t> bad_set(bad.begin(), bad.end());
    double moved = 0;
    for (std::size_t i = 0; i < after.size(); ++i) {
      if (bad_set.count(i)) {
        for (int k = 0; k < 3; ++k)
          // The input is float; OBJ reads back as double what was written as the shortest float.
          EXPECT_TRUE((std::isnan(before[i][k]) && std::isnan(after[i][k])) ||
                      static_cast<float>(before[i][k]) == static_cast<float>(after[i][k]))
              << "point " << i << " changed from " << before[i].transpose() << " to " << after[i].transpose();
      } else {
        ASSERT_TRUE(after[i].allFinite()) << "point " << i;
        moved = std::max(moved, (after[i] - before[i]).norm());
      }
    }
    EXPECT_GT(moved, 0.1);  // the handle moved by 0.2
  };
  // Library.
  Shape lib = shape;
  hgd::deformShape(lib, hgd::parseScenario(kBarScenario, "bar.json"));
  check(lib, "library");
  // CLI, every output format (ascii and binary).
  hgd::writeShape(dir.file("in.ply"), shape);
  writeBytes(dir.file("s.json"), kBarScenario);
  for (const char* out : {"o.ply", "o.pcd", "o.obj"})
    for (const char* enc : {"", " --ascii"}) {
      const CliRun r = cli("deform " + quote(dir.file("in.ply")) + " -s " + quote(dir.file("s.json")) +
                           " -o " + quote(dir.file(out)) + enc + " -q");
      ASSERT_EQ(r.code, 0) << r.err;
      check(hgd::readShape(dir.file(out)), std::string("CLI ") + out + enc);
    }
}

/// The bar's points, each `copies` times (all first copies, then all second copies...).
std::vector<Eigen::Vector3d> barPoints(int copies) {
  const std::vector<Eigen::Vector3d> p = positions(hgd::shapes::bar());
  std::vector<Eigen::Vector3d> out;
  for (int c = 0; c < copies; ++c) out.insert(out.end(), p.begin(), p.end());
  return out;
}

const std::vector<std::pair<std::string, std::string>> kBarMoves = {
    {"frame", R"({"frame": {"translate": [0, 0.2, 0]}})"},
    {"drag", R"({"drag": {"from": [1, 0, 0], "to": [1, 0.2, 0.05]}})"}};

TEST(RobustInput, EveryPointThreeTimesDeformsWithoutCrashOrNaN) {
  const Shape shape = xyzShape(barPoints(3));
  const std::size_t n = shape.size() / 3;
  for (const auto& [label, move] : kBarMoves) {
    SCOPED_TRACE(move);
    Shape a = shape;
    hgd::deformShape(a, hgd::parseScenario("{" + kBarHandles + ", \"move\": " + move + "}", "s.json"));
    const std::vector<Eigen::Vector3d> pa = positions(a);
    ASSERT_EQ(nonFinite(pa), 0u);
    double spread = 0;  // the copies of a point stay together
    for (std::size_t i = 0; i < n; ++i)
      spread = std::max({spread, (pa[i] - pa[i + n]).norm(), (pa[i] - pa[i + 2 * n]).norm()});
    EXPECT_LT(spread, 1e-3) << label;
  }
  // The CLI, on a file.
  TempDir dir;
  hgd::writeShape(dir.file("t.pcd"), shape);
  writeBytes(dir.file("s.json"), kBarScenario);
  const CliRun r = cli("deform " + quote(dir.file("t.pcd")) + " -s " + quote(dir.file("s.json")) + " -o " +
                       quote(dir.file("o.ply")) + " -q");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(nonFinite(positions(hgd::readShape(dir.file("o.ply")))), 0u);
}

TEST(RobustInput, EveryPointThreeTimesDeformsLikeTheSingleCloud) {
  const Shape tripled = xyzShape(barPoints(3)), once = xyzShape(barPoints(1));
  const std::size_t n = once.size();
  for (const auto& [label, move] : kBarMoves) {
    SCOPED_TRACE(move);
    const hgd::Scenario sc = hgd::parseScenario("{" + kBarHandles + ", \"move\": " + move + "}", "s.json");
    Shape a = tripled, b = once;
    const hgd::DeformReport ra = hgd::deformShape(a, sc);
    hgd::deformShape(b, sc);
    EXPECT_EQ(ra.unreachable, 0u);
    const std::vector<Eigen::Vector3d> pa = positions(a), pb = positions(b);
    double off = 0;
    for (std::size_t i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) off = std::max(off, (pa[i + c * n] - pb[i]).norm());
    std::printf("[ robust   ] tripled points, %s: %.2g from the single cloud\n", label.c_str(), off);
    EXPECT_LT(off, 0.01) << label;
  }
}

TEST(RobustInput, ReportNeverReplacesAnInputOrTheOutput) {
  TempDir dir;
  hgd::writeShape(dir.file("in.ply"), hgd::shapes::bar());
  writeBytes(dir.file("s.json"), kBarScenario);
  const std::string scan = slurp(dir.file("in.ply"));
  for (const std::string& report :
       {dir.path().string() + "/./in.ply", dir.file("s.json"), dir.file("out.ply")}) {
    SCOPED_TRACE(report);
    const CliRun r = cli("deform " + quote(dir.file("in.ply")) + " -s " + quote(dir.file("s.json")) + " -o " +
                         quote(dir.file("out.ply")) + " -r " + quote(report) + " -q");
    EXPECT_NE(r.code, 0) << "accepted a report path that is an input or the output";
    EXPECT_EQ(slurp(dir.file("in.ply")), scan) << "the scan was replaced";
    EXPECT_EQ(slurp(dir.file("s.json")), kBarScenario) << "the scenario was replaced";
    if (fs::exists(dir.file("out.ply"))) {
      EXPECT_NO_THROW(hgd::readShape(dir.file("out.ply"))) << "the output was replaced";
    }
  }
}

// --- degenerate geometry -----------------------------------------------------------------------

/// Deforms `shape` as `scenario_json` says through the library and the CLI (deform, and field).
/// Each must succeed with finite output or fail with a clear message; a crash, a hang or a NaN
/// is a failure. Returns true when everything succeeded.
bool deformsOrFailsClearly(const std::string& what, const Shape& shape, const std::string& scenario_json,
                           const hgd::DeformOptions& options = {}, const std::string& cli_options = "") {
  SCOPED_TRACE(what);
  bool ok = true;
  std::string outcome;
  {
    Shape s = shape;
    try {
      const hgd::DeformReport rep = hgd::deformShape(s, hgd::parseScenario(scenario_json, "s.json"), options);
      const std::vector<Eigen::Vector3d> p = positions(s);
      EXPECT_EQ(nonFinite(p), nonFinite(positions(shape))) << "non-finite output";
      double moved = 0;
      const std::vector<Eigen::Vector3d> p0 = positions(shape);
      for (std::size_t i = 0; i < p.size(); ++i)
        if (p0[i].allFinite()) moved = std::max(moved, (p[i] - p0[i]).norm());
      outcome = "library: deformed (" + std::to_string(rep.clusters) + " clusters, max displacement " +
                std::to_string(moved) + ")";
    } catch (const std::exception& e) {
      ok = false;
      outcome = std::string("library: failed: ") + e.what();
      EXPECT_GT(std::strlen(e.what()), 10u) << "unclear message";
    }
  }
  TempDir dir;
  hgd::writeShape(dir.file("in.ply"), shape);
  writeBytes(dir.file("s.json"), scenario_json);
  std::size_t files = 2;
  for (const std::string command : {"deform", "field"}) {
    const std::string out = dir.file(command + ".ply");
    const CliRun r = cli(command + " " + quote(dir.file("in.ply")) + " -s " + quote(dir.file("s.json")) +
                         " -o " + quote(out) + " -q " + (command == "deform" ? cli_options : ""));
    if (r.code == 0) {
      const Shape o = hgd::readShape(out);
      EXPECT_EQ(nonFinite(positions(o)), nonFinite(positions(shape))) << command << ": non-finite output";
      if (command == "field") {
        const int h = hgd::findField(o.cloud, "harmonic");
        EXPECT_GE(h, 0);
        const hgd::Geometry g = hgd::extractGeometry(o);
        for (std::size_t i = 0; h >= 0 && i < g.size(); ++i) {
          const double v = hgd::readValue(o.cloud, static_cast<std::size_t>(g.raw_index[i]),
                                          o.cloud.fields[static_cast<std::size_t>(h)]);
          if (!(v >= 0 && v <= 1)) {
            ADD_FAILURE() << command << ": field value " << v << " at point " << i;
            break;
          }
        }
      }
      outcome += "; CLI " + command + ": ok";
      ++files;
    } else {
      ok = false;
      EXPECT_EQ(r.code, 1) << command << " crashed or hung (124 = timeout, -1 = signal): " << r.err;
      EXPECT_TRUE(contains(r.err, "hgdeform " + command + ": ")) << r.err;
      EXPECT_FALSE(fs::exists(out));
      outcome +=
          "; CLI " + command + ": exit " + std::to_string(r.code) + ": " + r.err.substr(0, r.err.find('\n'));
    }
    EXPECT_EQ(listing(dir.path()).size(), files) << "files left behind";
  }
  std::printf("[ robust   ] %s: %s\n", what.c_str(), outcome.c_str());
  return ok;
}

std::string frameScenario(const std::string& handles, const std::string& translate = "[0, 0.2, 0.1]") {
  return "{" + handles + R"(, "move": {"frame": {"translate": )" + translate + "}}}";
}

std::string dragScenario(const std::string& handles, const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  return "{" + handles + R"(, "move": {"drag": {"from": )" + vec(from) + R"(, "to": )" + vec(to) + "}}}";
}

std::string rotateScenario(const std::string& handles) {
  return "{" + handles + R"(, "move": {"frame": {"rotate": {"axis": [0, 0, 1], "degrees": 60}}}})";
}

const std::string kXHandles = R"("fixed": [{"box": {"min": [-1, -1, -1], "max": [0.1, 2, 1]}}],
  "manipulated": {"box": {"min": [0.9, -1, -1], "max": [2, 2, 1]}})";

TEST(RobustGeometry, AllPointsIdentical) {
  const Shape s = xyzShape(std::vector<Eigen::Vector3d>(60, Eigen::Vector3d(1, 2, 3)));
  const std::string handles =
      R"("fixed": [{"indices": [0, 1, 2, 3, 4]}], "manipulated": {"indices": [55, 56, 57]})";
  deformsOrFailsClearly("all points identical, frame", s, frameScenario(handles));
  deformsOrFailsClearly("all points identical, drag", s,
                        dragScenario(handles, Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(1, 2.2, 3)));
  deformsOrFailsClearly("all points identical, rotate", s, rotateScenario(handles));
}

TEST(RobustGeometry, CollinearAndCoplanarClouds) {
  std::vector<Eigen::Vector3d> line, plane;
  for (int i = 0; i < 200; ++i) line.emplace_back(i / 199.0, 0, 0);
  for (int i = 0; i < 30; ++i)
    for (int j = 0; j < 30; ++j) plane.emplace_back(i / 29.0, j / 29.0, 0);
  for (const auto& [name, pts] :
       {std::make_pair(std::string("collinear"), line), std::make_pair(std::string("coplanar"), plane)}) {
    const Shape s = xyzShape(pts);
    EXPECT_TRUE(deformsOrFailsClearly(name + ", frame", s, frameScenario(kXHandles)));
    EXPECT_TRUE(deformsOrFailsClearly(
        name + ", drag", s, dragScenario(kXHandles, Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(1, 0.2, 0.1))));
    EXPECT_TRUE(deformsOrFailsClearly(name + ", rotate", s, rotateScenario(kXHandles)));
  }
}

TEST(RobustGeometry, HandleOfOnePoint) {
  const Shape bar = hgd::shapes::bar();
  const hgd::Geometry g = hgd::extractGeometry(bar);
  std::size_t tip = 0;
  for (std::size_t i = 0; i < g.size(); ++i)
    if (g.world(i).x() > g.world(tip).x()) tip = i;
  const std::string handles = R"("fixed": [{"box": {"min": [-1, -1, -1], "max": [0.045, 1, 1]}}],
    "manipulated": {"indices": [)" +
                              std::to_string(g.raw_index[tip]) + "]}";
  EXPECT_TRUE(deformsOrFailsClearly("one-point manipulated handle, frame", bar, frameScenario(handles)));
  EXPECT_TRUE(
      deformsOrFailsClearly("one-point manipulated handle, drag", bar,
                            dragScenario(handles, g.world(tip), g.world(tip) + Eigen::Vector3d(0, 0.2, 0))));
  const std::string one_fixed =
      R"("fixed": [{"indices": [0]}], "manipulated": {"box": {"min": [0.955, -1, -1], "max": [2, 1, 1]}})";
  EXPECT_TRUE(deformsOrFailsClearly("one-point fixed handle, frame", bar, frameScenario(one_fixed)));
}

TEST(RobustGeometry, HandlesThatTouch) {
  // No free point between the handles: the fixed half and the manipulated half meet.
  const std::string handles = R"("fixed": [{"box": {"min": [-1, -1, -1], "max": [0.5, 1, 1]}}],
    "manipulated": {"box": {"min": [0.5000001, -1, -1], "max": [2, 1, 1]}})";
  const Shape bar = hgd::shapes::bar();
  EXPECT_TRUE(deformsOrFailsClearly("touching handles, frame", bar, frameScenario(handles)));
  EXPECT_TRUE(
      deformsOrFailsClearly("touching handles, drag", bar,
                            dragScenario(handles, Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(1, 0.2, 0))));
}

/// Two copies of the bar, the second shifted by `shift`.
Shape twoBars(const Eigen::Vector3d& shift, std::size_t* first_size) {
  const std::vector<Eigen::Vector3d> p = positions(hgd::shapes::bar());
  std::vector<Eigen::Vector3d> both = p;
  for (const auto& q : p) both.push_back(q + shift);
  *first_size = p.size();
  return xyzShape(both);
}

TEST(RobustGeometry, FixedAndManipulatedInDifferentComponents) {
  std::size_t n = 0;
  const Shape s = twoBars(Eigen::Vector3d(0, 1, 0), &n);
  // Fixed: the first bar's x = 0 end; manipulated: the second bar's x = 1 end.
  const std::string handles = R"("fixed": [{"box": {"min": [-1, -1, -1], "max": [0.045, 0.5, 1]}}],
    "manipulated": {"box": {"min": [0.955, 0.5, -1], "max": [2, 2, 1]}})";
  deformsOrFailsClearly("handles in different components, frame", s, frameScenario(handles));
  deformsOrFailsClearly("handles in different components, drag", s,
                        dragScenario(handles, Eigen::Vector3d(1, 1, 0), Eigen::Vector3d(1, 1.2, 0)));
}

TEST(RobustGeometry, ComponentWithoutHandleStaysInPlace) {
  std::size_t n = 0;
  const Shape s = twoBars(Eigen::Vector3d(0, 1, 0), &n);
  const std::string handles = R"("fixed": [{"box": {"min": [-1, -1, -1], "max": [0.045, 0.5, 1]}}],
    "manipulated": {"box": {"min": [0.955, -1, -1], "max": [2, 0.5, 1]}})";
  EXPECT_TRUE(deformsOrFailsClearly("component without handle, frame", s, frameScenario(handles)));
  EXPECT_TRUE(
      deformsOrFailsClearly("component without handle, drag", s,
                            dragScenario(handles, Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(1, 0.2, 0))));
  Shape d = s;
  hgd::deformShape(d, hgd::parseScenario(frameScenario(handles), "s.json"));
  const std::vector<Eigen::Vector3d> p0 = positions(s), p1 = positions(d);
  double second = 0, first = 0;
  for (std::size_t i = 0; i < n; ++i) first = std::max(first, (p1[i] - p0[i]).norm());
  for (std::size_t i = n; i < p0.size(); ++i) second = std::max(second, (p1[i] - p0[i]).norm());
  EXPECT_GT(first, 0.1);
  EXPECT_LT(second, 1e-6) << "the bar without handles moved";
}

TEST(RobustGeometry, NeighbourCountLargerThanTheCloud) {
  const Shape five = xyzShape({{0, 0, 0}, {0.25, 0, 0}, {0.5, 0.01, 0}, {0.75, 0, 0.01}, {1, 0, 0}});
  const std::string handles = R"("fixed": [{"indices": [0]}], "manipulated": {"indices": [4]})";
  EXPECT_TRUE(deformsOrFailsClearly("5 points, k = 10 (default), frame", five, frameScenario(handles)));
  EXPECT_TRUE(
      deformsOrFailsClearly("5 points, k = 10 (default), drag", five,
                            dragScenario(handles, Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(1, 0.3, 0))));
  hgd::DeformOptions many;
  many.field.k_neighbors = 100;
  many.field.k_normals = 100;
  EXPECT_TRUE(deformsOrFailsClearly("5 points, k = 100", five, frameScenario(handles), many, "-k 100"));
  const Shape two = xyzShape({{0, 0, 0}, {1, 0, 0}});
  deformsOrFailsClearly("2 points", two, frameScenario(handles.substr(0, handles.find("[4]")) + "[1]}"));
}

TEST(RobustGeometry, ClustersOfFewerThanThreePoints) {
  const Shape bar = hgd::shapes::bar(1.0f, 0.1f, 0.03f);
  std::printf("[ robust   ] bar of %zu points, 200 isoclusters\n", bar.size());
  ASSERT_LT(bar.size(), 700u);
  const std::string handles = kBarHandles + R"(, "clusters": 200)";
  EXPECT_TRUE(deformsOrFailsClearly("200 isoclusters on a small bar, frame", bar, frameScenario(handles)));
  EXPECT_TRUE(
      deformsOrFailsClearly("200 isoclusters on a small bar, drag", bar,
                            dragScenario(handles, Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(1, 0.2, 0))));
  hgd::DeformOptions few_samples;
  few_samples.clusters.samples = 10;
  EXPECT_TRUE(deformsOrFailsClearly("200 isoclusters, 10 samples", bar, frameScenario(handles), few_samples,
                                    "--samples 10"));
}

/// The bar (jittered, so that no two neighbours tie in distance: rounding would break ties
/// differently at each scale, as in Deform.UnitsDoNotMatter) scaled by `scale`, and a scenario
/// that rotates its end by 40 degrees (no coordinate in the move: any scale can say it).
std::pair<Shape, std::string> scaledBar(double scale) {
  std::vector<Eigen::Vector3d> p = barPoints(1);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-0.002, 0.002);
  for (auto& v : p) v = (v + Eigen::Vector3d(jitter(rng), jitter(rng), jitter(rng))) * scale;
  const auto sc = [&](double v) {
    std::ostringstream o;
    o.precision(17);
    o << v * scale;
    return o.str();
  };
  const std::string scenario = R"({"fixed": [{"box": {"min": [)" + sc(-1) + ", " + sc(-1) + ", " + sc(-1) +
                               R"(], "max": [)" + sc(0.045) + ", " + sc(1) + ", " + sc(1) +
                               R"(]}}], "manipulated": {"box": {"min": [)" + sc(0.955) + ", " + sc(-1) +
                               ", " + sc(-1) + R"(], "max": [)" + sc(2) + ", " + sc(1) + ", " + sc(1) +
                               R"(]}}, "move": {"frame": {"rotate": {"axis": [0, 1, 1], "degrees": 40}}}})";
  return {xyzShape(p), scenario};
}

TEST(RobustGeometry, ExtremeScalesDeformLikeTheUnitShape) {
  // Femtometres to light years in metres: the same deformation as the unit bar.
  const auto [unit, unit_scenario] = scaledBar(1);
  Shape reference = unit;
  hgd::deformShape(reference, hgd::parseScenario(unit_scenario, "s.json"));
  const std::vector<Eigen::Vector3d> expected = positions(reference);
  for (const double scale : {1e-12, 1e-6, 1e6, 1e15}) {
    const auto [s, scenario] = scaledBar(scale);
    char what[64];
    std::snprintf(what, sizeof what, "bar scaled by %g", scale);
    if (!deformsOrFailsClearly(what, s, scenario)) continue;
    Shape d = s;
    hgd::deformShape(d, hgd::parseScenario(scenario, "s.json"));
    const std::vector<Eigen::Vector3d> got = positions(d);
    double worst = 0;
    for (std::size_t i = 0; i < got.size(); ++i)
      worst = std::max(worst, (got[i] / scale - expected[i]).norm());
    std::printf("[ robust   ] %s: differs from the unit bar by %.2g (relative)\n", what, worst);
    EXPECT_LT(worst, 1e-3) << what;
  }
}

TEST(RobustGeometry, TinyAndHugeCoordinatesGiveFiniteOutput) {
  // Squared distances underflow float below ~1e-19 and overflow it above ~1e19.
  for (const double scale : {1e-30, 1e-20, 1e20}) {
    const auto [s, scenario] = scaledBar(scale);
    char what[64];
    std::snprintf(what, sizeof what, "bar scaled by %g", scale);
    deformsOrFailsClearly(what, s, scenario);
  }
}

TEST(RobustGeometry, CoordinatesWhoseSquaredDistancesOverflowFloat) {
  for (const double scale : {1e25, 1e30}) {
    const auto [s, scenario] = scaledBar(scale);
    char what[64];
    std::snprintf(what, sizeof what, "bar scaled by %g", scale);
    deformsOrFailsClearly(what, s, scenario);
  }
}

hgd::Handles barHandles(const hgd::Geometry& g) {
  return hgdtest::endHandles(g, 0.045, 0.955);
}

void expectFinite(const hgd::Deformer& d) {
  for (const auto& p : d.deformedPoints()) ASSERT_TRUE(p.allFinite());
}

TEST(RobustGeometry, NonFiniteDragTargetsAreRefused) {
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::bar());
  hgd::Deformer d(g, barHandles(g));
  const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
  const Eigen::Vector3d from(1, 0, 0);
  for (const Eigen::Vector3d& to :
       {Eigen::Vector3d(inf, 0, 0), Eigen::Vector3d(1, -inf, 0), Eigen::Vector3d(1, 0, nan)}) {
    SCOPED_TRACE(to.transpose());
    try {
      d.dragTo(from, to);
      ADD_FAILURE() << "dragTo accepted a non-finite target";
    } catch (const std::invalid_argument& e) {
      EXPECT_TRUE(contains(e.what(), "not finite")) << e.what();
    }
    EXPECT_THROW(d.drag(from, to), std::invalid_argument);
    EXPECT_THROW(d.dragTo(to, from), std::invalid_argument);
    expectFinite(d);
  }
  Eigen::Affine3d t = Eigen::Affine3d::Identity();
  t.translation() = Eigen::Vector3d(nan, 0, 0);
  EXPECT_THROW(d.setHandleTransform(t), std::invalid_argument);
  expectFinite(d);
  // The deformer still works afterwards.
  const hgd::DragResult r = d.dragTo(from, Eigen::Vector3d(1, 0.2, 0));
  EXPECT_TRUE(r.reached);
  expectFinite(d);
}

TEST(RobustGeometry, FarAwayTargetsEndInTimeWithFiniteOutput) {
  // A drag or a translation a million diagonals long (a georeferenced offset forgotten in a
  // scenario) must end, in bounded time, with a finite shape or a clear error.
  TempDir dir;
  hgd::writeShape(dir.file("bar.ply"), hgd::shapes::bar());
  const std::vector<std::pair<std::string, std::string>> moves = {
      {"drag 1e6 away", R"({"drag": {"from": [1, 0, 0], "to": [1, 1e6, 0]}})"},
      {"drag 1e15 away", R"({"drag": {"from": [1, 0, 0], "to": [1e15, 0, 1]}})"},
      {"translate by 1e6", R"({"frame": {"translate": [0, 1e6, 0]}})"},
      {"translate by 1e15", R"({"frame": {"translate": [-1e15, 0, 1e15]}})"},
      {"rotate by 1e6 degrees", R"({"frame": {"rotate": {"axis": [0, 1, 1], "degrees": 1e6}}})"}};
  for (const auto& [what, move] : moves) {
    SCOPED_TRACE(what);
    writeBytes(dir.file("s.json"), "{" + kBarHandles + ", \"move\": " + move + "}");
    const auto t0 = std::chrono::steady_clock::now();
    const CliRun r = cli("deform " + quote(dir.file("bar.ply")) + " -s " + quote(dir.file("s.json")) +
                         " -o " + quote(dir.file("out.ply")) + " -q");
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("[ robust   ] %s: exit %d after %.1f s %s", what.c_str(), r.code, s, r.err.c_str());
    if (r.code == 0) {
      EXPECT_EQ(nonFinite(positions(hgd::readShape(dir.file("out.ply")))), 0u);
      fs::remove(dir.file("out.ply"));
    } else {
      EXPECT_EQ(r.code, 1) << "crashed (-1) or hung (124): " << r.err;
      EXPECT_TRUE(contains(r.err, "hgdeform deform: ")) << r.err;
    }
    std::printf("\n");
  }
  // Through the API, beyond what a scenario may hold.
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::bar());
  hgd::Deformer d(g, barHandles(g));
  try {
    const hgd::DragResult r = d.dragTo(Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(1, 1e300, 0));
    std::printf("[ robust   ] API drag to y = 1e300: %d frames, reached %d\n", r.frames, r.reached);
    expectFinite(d);
  } catch (const std::exception& e) {
    std::printf("[ robust   ] API drag to y = 1e300: %s\n", e.what());
    EXPECT_GT(std::strlen(e.what()), 10u);
  }
  expectFinite(d);
}

// --- numerical failure --------------------------------------------------------------------------

TEST(RobustNumerics, FieldSolverThatDoesNotConvergeIsReported) {
  // Large enough for several levels (a small cloud's only level is an exact Cholesky solve).
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::bumpySphere(40000));
  std::vector<std::vector<int>> fixed(1);
  std::vector<int> manipulated;
  for (std::size_t i = 0; i < g.size(); ++i) {
    if (g.world(i).z() < -0.9) fixed[0].push_back(static_cast<int>(i));
    if (g.world(i).x() > 0.9) manipulated.push_back(static_cast<int>(i));
  }
  hgd::HarmonicField field;
  field.setInputCloud(g.points);
  field.setHandles(fixed, manipulated);
  hgd::FieldOptions opt;
  opt.solver = hgd::FieldSolver::Multilevel;
  opt.max_iterations = 1;
  opt.tolerance = 1e-14;
  field.setOptions(opt);
  std::vector<float> phi;
  try {
    field.compute(phi);
    ADD_FAILURE() << "no error from a multilevel solve of one iteration to 1e-14";
  } catch (const std::runtime_error& e) {
    EXPECT_TRUE(contains(e.what(), "did not converge")) << e.what();
  }
}

TEST(RobustNumerics, GaussNewtonOnSingularOrNonFiniteSystems) {
  // Clusters of one repeated point (a singular second moment) and a cluster with a NaN point.
  for (const bool with_nan : {false, true}) {
    SCOPED_TRACE(with_nan ? "NaN point" : "coincident points");
    std::vector<hgd::SolverCluster> clusters(3);
    for (int c = 0; c < 3; ++c) {
      clusters[static_cast<std::size_t>(c)].barycentre = Eigen::Vector3d(c * 0.5, 0, 0);
      clusters[static_cast<std::size_t>(c)].points.assign(4, Eigen::Vector3d(c * 0.5, 0, 0));
    }
    clusters[0].constant = true;
    if (with_nan) clusters[1].points[2] = Eigen::Vector3d(std::nan(""), 0, 0);
    hgd::ClusterSolver solver;
    solver.setup(clusters, {{0, 1}, {1, 2}}, 2, hgd::SolverWeights{});
    solver.setManipulation({Eigen::Vector3d(1, 0, 0)}, {Eigen::Vector3d(1, 0.3, 0)}, {1.0});
    try {
      const hgd::SolveStats st = solver.solve();
      for (const auto& t : solver.transforms()) {
        EXPECT_TRUE(t.A.allFinite() && t.t.allFinite()) << "non-finite transform, converged " << st.converged;
      }
    } catch (const std::runtime_error& e) {
      std::printf("[ robust   ] solver (%s): %s\n", with_nan ? "NaN point" : "coincident points", e.what());
      EXPECT_TRUE(contains(e.what(), "Gauss-Newton")) << e.what();
    }
  }
}

TEST(RobustNumerics, CappedGaussNewtonKeepsTheShapeFinite) {
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::bar());
  hgd::DeformOptions opt;
  opt.gauss_newton.max_iterations = 1;
  opt.max_drag_frames = 5;
  hgd::Deformer d(g, barHandles(g), opt);
  const hgd::DragResult r = d.dragTo(Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0.2, 0.6, 0.3));
  expectFinite(d);
  EXPECT_TRUE(std::isfinite(r.error));
  Eigen::Affine3d t = Eigen::Affine3d::Identity();
  t.rotate(Eigen::AngleAxisd(3.0, Eigen::Vector3d::UnitY()));
  const hgd::SolveStats st = d.setHandleTransform(t);
  EXPECT_TRUE(std::isfinite(st.energy.total()));
  expectFinite(d);
}

TEST(RobustNumerics, GaussNewtonThatCannotDecreaseIsReportedByTheLibrary) {
  // A target 1e15 diagonals away: the energies overflow, no step decreases them.
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::bar());
  hgd::Deformer d(g, barHandles(g));
  const hgd::DragResult r = d.dragTo(Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(1e15, 0, 1));
  expectFinite(d);
  EXPECT_FALSE(r.reached);
  EXPECT_FALSE(r.last.decreased && r.last.converged) << "a frame that could not decrease claims success";
  std::printf("[ robust   ] drag 1e15 away: reached %d, last frame decreased %d converged %d, error %.3g\n",
              r.reached, r.last.decreased, r.last.converged, r.error);
}

TEST(RobustNumerics, GaussNewtonThatCannotDecreaseIsReportedByTheCli) {
  TempDir dir;
  hgd::writeShape(dir.file("bar.ply"), hgd::shapes::bar());
  writeBytes(dir.file("s.json"),
             "{" + kBarHandles + R"(, "move": {"drag": {"from": [1, 0, 0], "to": [1e15, 0, 1]}}})");
  const CliRun r = cli("deform " + quote(dir.file("bar.ply")) + " -s " + quote(dir.file("s.json")) + " -o " +
                       quote(dir.file("out.ply")) + " -q");
  // The shape written is valid (finite, the closest the solver got), so the exit is 0, but the
  // user is told the move fell short.
  EXPECT_TRUE(contains(r.err, "hgdeform: warning: move 1 (drag): the picked point stopped"))
      << "exit " << r.code << ", stderr: " << r.err;
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(nonFinite(positions(hgd::readShape(dir.file("out.ply")))), 0u);
}

TEST(RobustNumerics, FrameMoveThatCannotDecreaseIsReportedByTheCli) {
  TempDir dir;
  hgd::writeShape(dir.file("bar.ply"), hgd::shapes::bar());
  writeBytes(dir.file("s.json"), "{" + kBarHandles + R"(, "move": {"frame": {"translate": [1e15, 0, 0]}}})");
  const CliRun r = cli("deform " + quote(dir.file("bar.ply")) + " -s " + quote(dir.file("s.json")) + " -o " +
                       quote(dir.file("out.ply")) + " --report " + quote(dir.file("r.json")) + " -q");
  EXPECT_TRUE(
      contains(r.err, "hgdeform: warning: move 1 (frame): Gauss-Newton could not decrease the energy"))
      << "exit " << r.code << ", stderr: " << r.err;
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(nonFinite(positions(hgd::readShape(dir.file("out.ply")))), 0u);
  const std::string report = slurp(dir.file("r.json"));
  EXPECT_TRUE(contains(report, "\"warnings\"") && contains(report, "move 1 (frame): Gauss-Newton")) << report;
}

// --- coordinates far from the origin ----------------------------------------------------------

TEST(RobustGeoreferenced, OffsetShapeDeformsLikeTheCentredOne) {
  TempDir dir;
  const Eigen::Vector3d offset(1e6, 1e6, 1e6);
  const Shape centred = hgd::shapes::bar();
  const Shape far = withOffset(centred, offset);
  const double diag = hgd::boundingBoxDiagonal(hgd::extractGeometry(centred));
  const std::vector<Eigen::Vector3d> rest = positions(centred);
  hgd::writeShape(dir.file("centred.ply"), centred);
  hgd::writeShape(dir.file("far.ply"), far);
  ASSERT_TRUE(contains(slurp(dir.file("far.ply")).substr(0, 400), "property double x"));
  const auto handles = [](const Eigen::Vector3d& o) {
    return R"("fixed": [)" + boxJson(Eigen::Vector3d(-1, -1, -1) + o, Eigen::Vector3d(0.045, 1, 1) + o) +
           R"(], "manipulated": )" +
           boxJson(Eigen::Vector3d(0.955, -1, -1) + o, Eigen::Vector3d(2, 1, 1) + o);
  };
  const auto moves = [](const Eigen::Vector3d& o) {
    return std::vector<std::string>{
        R"({"frame": {"translate": [0, 0.2, 0.1], "rotate": {"axis": [0, 1, 0], "degrees": 30}}})",
        R"({"drag": {"from": )" + vec(Eigen::Vector3d(1, 0, 0) + o) + R"(, "to": )" +
            vec(Eigen::Vector3d(0.8, 0.4, 0.1) + o) + "}}"};
  };
  const std::vector<std::string> near_moves = moves(Eigen::Vector3d::Zero()), far_moves = moves(offset);
  for (std::size_t m = 0; m < near_moves.size(); ++m) {
    SCOPED_TRACE(near_moves[m]);
    const std::string sn = "{" + handles(Eigen::Vector3d::Zero()) + ", \"move\": " + near_moves[m] + "}";
    const std::string sf = "{" + handles(offset) + ", \"move\": " + far_moves[m] + "}";
    const auto compare = [&](const Shape& a, const Shape& b, const std::string& what) {
      const std::vector<Eigen::Vector3d> pa = positions(a), pb = positions(b);
      ASSERT_EQ(pa.size(), pb.size());
      double worst = 0, moved = 0;
      for (std::size_t i = 0; i < pa.size(); ++i) {
        worst = std::max(worst, (pb[i] - offset - pa[i]).norm());
        moved = std::max(moved, (pa[i] - rest[i]).norm());
      }
      std::printf("[ robust   ] 1e6 offset, %s, %s: max difference %.3g (%.2g of the diagonal)\n",
                  what.c_str(), m == 0 ? "frame" : "drag", worst, worst / diag);
      EXPECT_GT(moved, 0.1);
      EXPECT_LE(worst, 1e-4 * diag);
    };
    // Library.
    Shape a = centred, b = far;
    hgd::deformShape(a, hgd::parseScenario(sn, "near.json"));
    hgd::deformShape(b, hgd::parseScenario(sf, "far.json"));
    compare(a, b, "library");
    // CLI, from the files.
    writeBytes(dir.file("near.json"), sn);
    writeBytes(dir.file("far.json"), sf);
    CliRun r = cli("deform " + quote(dir.file("centred.ply")) + " -s " + quote(dir.file("near.json")) +
                   " -o " + quote(dir.file("near_out.ply")) + " -q");
    ASSERT_EQ(r.code, 0) << r.err;
    r = cli("deform " + quote(dir.file("far.ply")) + " -s " + quote(dir.file("far.json")) + " -o " +
            quote(dir.file("far_out.ply")) + " -q");
    ASSERT_EQ(r.code, 0) << r.err;
    const Shape fo = hgd::readShape(dir.file("far_out.ply"));
    EXPECT_EQ(fo.cloud.fields[static_cast<std::size_t>(hgd::findField(fo.cloud, "x"))].datatype,
              Field::FLOAT64);
    compare(hgd::readShape(dir.file("near_out.ply")), fo, "CLI");
  }
}

// --- out of memory ------------------------------------------------------------------------------

TEST(RobustMemory, OutOfMemoryEndsWithAMessage) {
#ifdef HGD_TEST_ASAN
  GTEST_SKIP() << "ulimit -v cannot apply under AddressSanitizer (its shadow memory needs terabytes of "
                  "address space)";
#else
  TempDir dir;
  const Shape sphere = hgd::shapes::bumpySphere(2000000);
  hgd::writeShape(dir.file("big.ply"), sphere);
  writeBytes(dir.file("s.json"), R"({"fixed": [{"box": {"min": [-2, -2, -2], "max": [2, 2, -0.8]}}],
    "manipulated": {"box": {"min": [-2, -2, 0.8], "max": [2, 2, 2]}}, "move": {"frame": {"translate": [0, 0, 0.3]}}})");
  // A header that claims far more than the file holds, under the same limit.
  writeBytes(dir.file("claims.ply"), plyHead("binary_little_endian", "100000000000") + floats({0, 0, 0}));
  const auto limited = [&](const std::string& limit_kb, const std::string& in,
                           const std::string& extra = "") {
    return shell("timeout 60 bash -c " + quote("ulimit -v " + limit_kb + "; exec " + quote(HGD_TOOL) +
                                               " deform " + quote(in) + " -s " + quote(dir.file("s.json")) +
                                               " -o " + quote(dir.file("out.ply")) + " -q" + extra));
  };
  // 400 MB runs out while reading; 900 MB while building at full resolution (the default
  // multi-resolution build deforms these 2M points within 900 MB).
  for (const auto& [limit, extra] :
       {std::pair<std::string, std::string>{"400000", ""}, {"900000", " --full-field"}}) {
    SCOPED_TRACE("ulimit -v " + limit + extra);
    const CliRun r = limited(limit, dir.file("big.ply"), extra);
    std::printf("[ robust   ] 2M points under ulimit -v %s: exit %d: %s", limit.c_str(), r.code,
                r.err.c_str());
    EXPECT_EQ(r.code, 1) << "killed (-1) or hung (124)? " << r.err;
    EXPECT_TRUE(contains(r.err, "hgdeform deform: out of memory")) << r.err;
    EXPECT_FALSE(fs::exists(dir.file("out.ply")));
    EXPECT_EQ(listing(dir.path()).size(), 3u) << "files left behind";
  }
  const CliRun r = limited("400000", dir.file("claims.ply"));
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_TRUE(contains(r.err, dir.file("claims.ply") + ": truncated data")) << r.err;
  EXPECT_FALSE(fs::exists(dir.file("out.ply")));
#endif
}

TEST(RobustMemory, AddressSpaceLimitsAroundBlasNeitherHangNorKill) {
#ifdef HGD_TEST_ASAN
  GTEST_SKIP() << "ulimit -v cannot apply under AddressSanitizer";
#else
  // OpenBLAS 0.3.21 retries a failed mmap of its 128 MiB thread buffers for ever (a worker at
  // start-up, CHOLMOD's dpotrf later): under these limits the small bar used to hang. 200 MB
  // leaves too little for that buffer (a message), 280 MB about the buffer and no more, 400 MB
  // enough for one buffer but not two (it deforms).
  TempDir dir;
  hgd::writeShape(dir.file("bar.ply"), hgd::shapes::bar());
  writeBytes(dir.file("s.json"), kBarScenario);
  for (const std::string limit : {"200000", "280000", "400000"}) {
    SCOPED_TRACE("ulimit -v " + limit);
    const CliRun r =
        shell("timeout 60 bash -c " + quote("ulimit -v " + limit + "; exec " + quote(HGD_TOOL) + " deform " +
                                            quote(dir.file("bar.ply")) + " -s " + quote(dir.file("s.json")) +
                                            " -o " + quote(dir.file("out.ply")) + " -q"));
    std::printf("[ robust   ] bar under ulimit -v %s: exit %d %s", limit.c_str(), r.code, r.err.c_str());
    if (limit == "400000") {
      ASSERT_EQ(r.code, 0) << r.err;
      EXPECT_EQ(nonFinite(positions(hgd::readShape(dir.file("out.ply")))), 0u);
      fs::remove(dir.file("out.ply"));
    } else if (r.code != 0) {
      EXPECT_EQ(r.code, 1) << "killed (-1) or hung (124)? " << r.err;
      EXPECT_TRUE(contains(r.err, "hgdeform deform: out of memory")) << r.err;
      EXPECT_FALSE(fs::exists(dir.file("out.ply")));
    } else {
      fs::remove(dir.file("out.ply"));
    }
    EXPECT_EQ(listing(dir.path()).size(), 2u) << "files left behind";
  }
#endif
}

// --- messages of issue 28 ----------------------------------------------------------------------

// "clusters": 12.0 was refused as not an integer; a whole number is one however spelt.
TEST(RobustScenario, WholeNumberOfClustersInAnySpelling) {
  for (const char* spelt : {"12", "12.0", "1.2e1", "12.000"}) {
    const hgd::Scenario s =
        hgd::parseScenario("{" + kBarHandles + R"(, "clusters": )" + spelt + "}", "c.json");
    ASSERT_TRUE(s.clusters.has_value()) << spelt;
    EXPECT_EQ(*s.clusters, 12) << spelt;
  }
  for (const char* spelt : {"12.5", "0.0", "1000.5", "1e4", "-3.0"}) {
    try {
      hgd::parseScenario("{" + kBarHandles + R"(, "clusters": )" + spelt + "}", "c.json");
      ADD_FAILURE() << spelt << " accepted";
    } catch (const hgd::ScenarioError& e) {
      EXPECT_TRUE(contains(e.what(), "c.json: /clusters: must be an integer from 1 to 1000")) << e.what();
    }
  }
}

// Messages about a scenario with no file behind it (parsed from text, or built in memory) began
// with an empty name: ": /fixed/0: selects no point of the shape". They name it "scenario".
TEST(RobustScenario, ScenarioWithoutAFileIsNamedInMessages) {
  auto message = [](const std::function<void()>& f) -> std::string {
    try {
      f();
    } catch (const std::exception& e) {
      return e.what();
    }
    return "(no error)";
  };
  const std::string parsed =
      message([] { hgd::parseScenario("{" + kBarHandles + R"(, "clusters": 0})", ""); });
  EXPECT_EQ(parsed.rfind("scenario: /clusters: ", 0), 0u) << parsed;
  const std::string duplicate = message([] { hgd::parseScenario(R"({"clusters": 3, "clusters": 4})", ""); });
  EXPECT_EQ(duplicate.rfind("scenario: /clusters: duplicate key", 0), 0u) << duplicate;
  const std::string syntax = message([] { hgd::parseScenario("{", ""); });
  EXPECT_EQ(syntax.rfind("scenario: invalid JSON", 0), 0u) << syntax;

  const hgd::Shape bar = hgd::shapes::bar();
  const hgd::Geometry g = hgd::extractGeometry(bar);
  hgd::Scenario built;  // in memory: no path
  built.fixed.push_back(hgd::Region::sphere(Eigen::Vector3d(-5, -5, -5), 0.1));
  built.manipulated = hgd::Region::sphere(Eigen::Vector3d(1, 0, 0), 0.1);
  const std::string selects = message([&] { hgd::resolveHandles(built, g, bar); });
  EXPECT_EQ(selects.rfind("scenario: ", 0), 0u) << selects;
  EXPECT_TRUE(contains(selects, "selects no point")) << selects;
  // A parsed scenario keeps its file's name.
  const hgd::Scenario named = hgd::parseScenario("{" + kBarHandles + "}", "bar.json");
  EXPECT_EQ(named.path, "bar.json");
}

// --- regressions found by the fuzzers (fuzz/, scripts/fuzz.sh) ---------------------------------

TEST(RobustFuzzRegressions, ScenarioNumberOutOfRangeIsAScenarioError) {
  // fuzz_scenario on the old parser, crash-48fce1294a2f8fbea60d091d5014dab5d68a476a (after 3412
  // runs): nlohmann::json throws out_of_range, not parse_error, for a number beyond double, and
  // it escaped parseScenario (std::terminate in the fuzzer; a message without the file name in
  // the CLI).
  const std::string crash(
      "{\n \"fixed\": [\n1e400  \"box\": {\n    \"min\": [\n    x\": {\n   0\n    ],\n    \"radius   \"min,",
      84);
  for (const std::string& text : {crash, std::string("[1e400]"), std::string("{\"fixed\": -1e999}")}) {
    try {
      hgd::parseScenario(text, "f.json");
      ADD_FAILURE() << text << " parsed";
    } catch (const hgd::ScenarioError& e) {
      EXPECT_TRUE(contains(e.what(), "f.json: invalid JSON")) << e.what();
      EXPECT_TRUE(contains(e.what(), "number overflow")) << e.what();
    }
  }
}

TEST(RobustFuzzRegressions, DeeplyNestedMoveListsDoNotOverflowTheStack) {
  // A list of moves is a move, and the parser recursed once per level: 100000 levels of
  // brackets overflowed the stack (a segfault, no message).
  const std::string text = R"({"fixed": [{"indices": [0]}], "manipulated": {"indices": [1]}, "move": )" +
                           std::string(100000, '[') + R"({"frame": {"translate": [0, 0, 1]}})" +
                           std::string(100000, ']') + "}";
  try {
    hgd::parseScenario(text, "deep.json");
    ADD_FAILURE() << "parsed";
  } catch (const hgd::ScenarioError& e) {
    EXPECT_TRUE(contains(e.what(), "deep.json: /move/0/0/0/0")) << std::string(e.what()).substr(0, 200);
    EXPECT_TRUE(contains(e.what(), "nested more than 32 deep")) << std::string(e.what()).substr(0, 200);
  }
}

}  // namespace
