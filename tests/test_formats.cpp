// XYZ/TXT, OFF and STL reading and writing, and reading by content (tests for issue 15 item 5).
// Every file is written by hand here from arrays of this test; what is read is compared against
// those arrays, not against another reader.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "hgdeform/io/fields.h"
#include "hgdeform/io/io.h"
#include "test_util.h"

namespace {

using hgd::IoError;
using hgd::Shape;
using hgdtest::TempDir;
using Field = pcl::PCLPointField;
using Tri = std::array<std::array<float, 3>, 3>;

std::string g17(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

void expectIoError(const std::function<void()>& f, const std::string& path, const std::string& phrase) {
  try {
    f();
    ADD_FAILURE() << "no IoError thrown; expected '" << phrase << "' for " << path;
  } catch (const IoError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find(path), std::string::npos) << m;
    EXPECT_NE(m.find(phrase), std::string::npos) << "expected '" << phrase << "' in: " << m;
  }
}

void expectReadError(const std::string& path, const std::string& phrase) {
  expectIoError([&] { hgd::readShape(path); }, path, phrase);
}

double value(const Shape& s, std::size_t i, const std::string& name) {
  const int f = hgd::findField(s.cloud, name);
  EXPECT_GE(f, 0) << "no field " << name;
  return f < 0 ? NAN : hgd::readValue(s.cloud, i, s.cloud.fields[static_cast<std::size_t>(f)]);
}

std::vector<std::string> names(const Shape& s) {
  std::vector<std::string> out;
  for (const auto& f : s.cloud.fields) out.push_back(f.name);
  return out;
}

/// Random rows of `cols` values: x y z with noise in random order, then other columns.
std::vector<std::vector<double>> randomRows(std::mt19937& rng, std::size_t n, std::size_t cols) {
  std::normal_distribution<double> noise(0.0, 0.01);
  std::uniform_real_distribution<double> u(-5, 5);
  std::vector<std::vector<double>> rows(n, std::vector<double>(cols));
  for (std::size_t i = 0; i < n; ++i) {
    rows[i][0] = std::cos(0.3 * static_cast<double>(i)) + noise(rng);
    rows[i][1] = std::sin(0.3 * static_cast<double>(i)) + noise(rng);
    rows[i][2] = 0.1 * static_cast<double>(i) + noise(rng);
    for (std::size_t k = 3; k < cols; ++k) rows[i][k] = u(rng);
  }
  std::shuffle(rows.begin(), rows.end(), rng);
  return rows;
}

/// Corner positions of a face, as read.
Tri corners(const Shape& s, std::size_t face) {
  Tri t{};
  for (std::size_t c = 0; c < 3; ++c) {
    const auto v = static_cast<std::size_t>(s.polygons.at(face).vertices.at(c));
    t[c] = {static_cast<float>(value(s, v, "x")), static_cast<float>(value(s, v, "y")),
            static_cast<float>(value(s, v, "z"))};
  }
  return t;
}

/// A mesh in several pieces: `pieces` tetrahedra far apart, faces in random order.
std::vector<Tri> tetrahedra(std::mt19937& rng, int pieces) {
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<Tri> tris;
  for (int p = 0; p < pieces; ++p) {
    std::array<std::array<float, 3>, 4> v;
    for (auto& c : v) c = {10.0f * static_cast<float>(p) + u(rng), u(rng), u(rng)};
    for (const auto& f : {std::array<int, 3>{0, 1, 2}, {0, 3, 1}, {1, 3, 2}, {2, 3, 0}})
      tris.push_back({v[static_cast<std::size_t>(f[0])], v[static_cast<std::size_t>(f[1])],
                      v[static_cast<std::size_t>(f[2])]});
  }
  std::shuffle(tris.begin(), tris.end(), rng);
  return tris;
}

std::string asciiStl(const std::vector<Tri>& tris) {
  std::string s = "solid test\n";
  for (const auto& t : tris) {
    s += "  facet normal 0 0 1\n    outer loop\n";
    for (const auto& c : t) s += "      vertex " + g17(c[0]) + " " + g17(c[1]) + " " + g17(c[2]) + "\n";
    s += "    endloop\n  endfacet\n";
  }
  return s + "endsolid test\n";
}

std::string binaryStl(const std::vector<Tri>& tris, std::uint32_t declared, std::uint16_t attribute = 0) {
  std::string s(80, ' ');
  hgdtest::put(s, declared);
  for (const auto& t : tris) {
    for (int k = 0; k < 3; ++k) hgdtest::put(s, 0.0f);
    for (const auto& c : t)
      for (const float v : c) hgdtest::put(s, v);
    hgdtest::put(s, attribute);
  }
  return s;
}

void expectTriangles(const Shape& s, const std::vector<Tri>& tris) {
  ASSERT_EQ(s.polygons.size(), tris.size());
  for (std::size_t f = 0; f < tris.size(); ++f) EXPECT_EQ(corners(s, f), tris[f]) << "face " << f;
}

// --- XYZ -----------------------------------------------------------------------------------

TEST(Xyz, ReadsEveryColumnWithCommentsAndBlankLines) {
  TempDir dir;
  std::mt19937 rng(11);
  const auto rows = randomRows(rng, 60, 5);
  for (const char* sep : {" ", ",", " \t, "}) {
    std::string text = "# a scan\n\n";
    for (std::size_t i = 0; i < rows.size(); ++i) {
      for (std::size_t k = 0; k < 5; ++k) text += (k ? sep : "") + g17(rows[i][k]);
      text += i % 7 == 3 ? "\n\n# noise\n" : "\n";
    }
    const std::string p = dir.file("scan.xyz");
    hgdtest::writeText(p, text);
    const Shape s = hgd::readShape(p);
    EXPECT_EQ(s.format, hgd::FileFormat::Xyz);
    EXPECT_TRUE(s.warnings.empty());
    EXPECT_EQ(names(s), (std::vector<std::string>{"x", "y", "z", "field3", "field4"}));
    ASSERT_EQ(s.size(), rows.size());
    for (std::size_t i = 0; i < rows.size(); ++i) {
      EXPECT_EQ(value(s, i, "x"), rows[i][0]);
      EXPECT_EQ(value(s, i, "y"), rows[i][1]);
      EXPECT_EQ(value(s, i, "z"), rows[i][2]);
      // Written with 17 digits, more than a float holds: the columns are doubles (issue 48).
      EXPECT_EQ(value(s, i, "field3"), rows[i][3]);
      EXPECT_EQ(value(s, i, "field4"), rows[i][4]);
    }
  }
}

TEST(Xyz, HeaderNamesTheColumns) {
  TempDir dir;
  const std::string p = dir.file("scan.txt");
  hgdtest::writeText(p, "//intensity X Y Z label\n7 1 2 3 4\n8 5 6 7 9\n");
  const Shape s = hgd::readShape(p);
  EXPECT_EQ(names(s), (std::vector<std::string>{"intensity", "x", "y", "z", "label"}));
  EXPECT_EQ(value(s, 1, "x"), 5);
  EXPECT_EQ(value(s, 1, "intensity"), 8);
  EXPECT_EQ(value(s, 0, "label"), 4);
}

TEST(Xyz, SixColumnConventions) {
  TempDir dir;
  const std::string p = dir.file("c.xyz");
  hgdtest::writeText(p, "0 0 0 255 0 10\n1 0 0 3 4 5\n");  // integers 0..255: colours
  Shape s = hgd::readShape(p);
  EXPECT_EQ(names(s), (std::vector<std::string>{"x", "y", "z", "red", "green", "blue"}));
  EXPECT_EQ(s.cloud.fields[3].datatype, Field::UINT8);
  EXPECT_EQ(value(s, 0, "red"), 255);
  hgdtest::writeText(p, "0 0 0 0 0 1\n1 0 0 0.6 0.8 0\n");  // unit vectors: normals
  s = hgd::readShape(p);
  EXPECT_EQ(names(s), (std::vector<std::string>{"x", "y", "z", "nx", "ny", "nz"}));
  EXPECT_FLOAT_EQ(value(s, 1, "ny"), 0.8f);
  hgdtest::writeText(p, "0 0 0 0.5 0.2 0.1\n1 0 0 1 0.25 0\n");  // 0..1: float colours
  s = hgd::readShape(p);
  EXPECT_EQ(names(s), (std::vector<std::string>{"x", "y", "z", "red", "green", "blue"}));
  EXPECT_EQ(s.cloud.fields[3].datatype, Field::FLOAT32);
  hgdtest::writeText(p, "0 0 0 0.5 -2 300\n1 0 0 1 0.25 0\n");  // neither
  s = hgd::readShape(p);
  EXPECT_EQ(names(s), (std::vector<std::string>{"x", "y", "z", "field3", "field4", "field5"}));
}

TEST(Xyz, RoundTripKeepsColumnsOrderAndSeparator) {
  TempDir dir;
  std::mt19937 rng(5);
  const auto rows = randomRows(rng, 40, 4);
  std::string text;
  for (const auto& r : rows) text += g17(r[0]) + "," + g17(r[1]) + "," + g17(r[2]) + "," + g17(r[3]) + "\n";
  const std::string in = dir.file("in.xyz"), out = dir.file("out.txt");
  hgdtest::writeText(in, text);
  const Shape a = hgd::readShape(in);
  hgd::writeShape(out, a);
  const std::string written = hgdtest::slurp(out);
  EXPECT_EQ(std::count(written.begin(), written.end(), '\n'), 40);  // no header line added
  EXPECT_EQ(std::count(written.begin(), written.end(), ','), 3 * 40);
  const Shape b = hgd::readShape(out);
  ASSERT_EQ(names(b), names(a));
  for (std::size_t i = 0; i < rows.size(); ++i)
    for (const char* n : {"x", "y", "z", "field3"}) EXPECT_EQ(value(b, i, n), value(a, i, n));
  // Named columns keep their names through a round trip (a header line is written).
  hgdtest::writeText(in, "x y z intensity\n1 2 3 0.5\n");
  hgd::writeShape(out, hgd::readShape(in));
  EXPECT_EQ(hgdtest::slurp(out), "x y z intensity\n1 2 3 0.5\n");
}

TEST(Xyz, ErrorsNameFileAndLine) {
  TempDir dir;
  const std::string p = dir.file("bad.xyz");
  hgdtest::writeText(p, "# c\n1 2 3\n4 5 6\n7 8\n");
  expectReadError(p, "line 4 has 2 values, expected 3");
  hgdtest::writeText(p, "1 2 3\n4 five 6\n");
  expectReadError(p, "'five' at line 2");
  hgdtest::writeText(p, "# only a comment\n\n");
  expectReadError(p, "no points");
  hgdtest::writeText(p, "x y\n1 2\n");
  expectReadError(p, "line 1");
}

// Separators and the row of names are written back as the file had them: tabs stay tabs,
// ", " stays ", ", "//X Y Z Intensity" and "a b c d" stay as written (issue 28 item 8).
TEST(Xyz, SeparatorsAndRowOfNamesAreKeptAsWritten) {
  TempDir dir;
  const std::string in = dir.file("in.xyz"), out = dir.file("out.xyz");
  for (const std::string text :
       {"1\t2\t3\n4\t5\t6\n", "1, 2, 3, 0.5\n4, 5, 6, 0.25\n", "//X Y Z Intensity\n1 2 3 0.5\n4 5 6 0.25\n",
        "a b c d\n1 2 3 4\n5 6 7 8\n", "X\tY\tZ\n1\t2\t3\n", "x, y, z, i\n1, 2, 3, 4\n"}) {
    hgdtest::writeText(in, text);
    const Shape s = hgd::readShape(in);
    hgd::writeShape(out, s);
    EXPECT_EQ(hgdtest::slurp(out), text);
  }
  // The names as read: the coordinates x y z whatever the row called them.
  hgdtest::writeText(in, "a b c d\n1 2 3 4\n");
  EXPECT_EQ(names(hgd::readShape(in)), (std::vector<std::string>{"x", "y", "z", "d"}));
  // A field added since: a new row of names, with the file's separator, in CloudCompare's
  // spelling (issue 48: CloudCompare ignores a row of names without the "//").
  hgdtest::writeText(in, "1\t2\t3\n");
  Shape s = hgd::readShape(in);
  hgd::addFloatField(s.cloud, "w");
  hgd::writeShape(out, s);
  EXPECT_EQ(hgdtest::slurp(out), "//X\tY\tZ\tw\n1\t2\t3\t0\n");
  EXPECT_EQ(names(hgd::readShape(out)), (std::vector<std::string>{"x", "y", "z", "w"}));
}

// CloudCompare's ASCII header names normals Nx Ny Nz and colours R G B (A): they are the normals
// (turned by a deformation) and uchar colours, and a PLY made from the file declares them so.
TEST(Xyz, CloudComparesColumnNamesAreNormalsAndColours) {
  TempDir dir;
  const std::string in = dir.file("cc.txt");
  hgdtest::writeText(
      in,
      "//X Y Z R G B A Intensity Nx Ny Nz\n0 0 0 10 20 30 255 0.5 0 0 1\n1 0 0 40 50 60 128 0.25 0 1 0\n"
      "0 1 0 70 80 90 0 1 1 0 0\n");
  const Shape s = hgd::readShape(in);
  EXPECT_EQ(names(s), (std::vector<std::string>{"x", "y", "z", "red", "green", "blue", "alpha", "Intensity",
                                                "nx", "ny", "nz"}));
  EXPECT_TRUE(hgd::findXyzFields(s.cloud).hasNormals());
  EXPECT_EQ(s.cloud.fields[3].datatype, pcl::PCLPointField::UINT8);
  EXPECT_EQ(s.cloud.fields[6].datatype, pcl::PCLPointField::UINT8);
  EXPECT_EQ(value(s, 1, "green"), 50);
  const std::string out = dir.file("back.txt");
  hgd::writeShape(out, s);
  EXPECT_EQ(hgdtest::slurp(out), hgdtest::slurp(in));  // the header and rows as written
  const std::string ply = dir.file("cc.ply");
  hgd::writeShape(ply, s);
  const std::string head = hgdtest::slurp(ply).substr(0, 500);
  for (const char* p : {"property uchar red\n", "property uchar alpha\n", "property float nx\n"})
    EXPECT_NE(head.find(p), std::string::npos) << p << head;
}

// A '#' comment after a row's values is skipped, as a whole-line comment is; a value that is no
// number (a hexadecimal float) is named with its line and column (issue 28 item 10).
TEST(Xyz, TrailingCommentsAndBadValuesInTheFirstRow) {
  TempDir dir;
  const std::string p = dir.file("c.xyz");
  hgdtest::writeText(p, "# scan\n# columns x y z\n0 0 0 # first\n1 2 3 #second\n4,5,6 #third\n");
  const Shape s = hgd::readShape(p);
  ASSERT_EQ(s.size(), 3u);
  EXPECT_EQ(names(s), (std::vector<std::string>{"x", "y", "z"}));
  EXPECT_EQ(value(s, 1, "y"), 2);
  EXPECT_EQ(value(s, 2, "z"), 6);
  hgdtest::writeText(p, "# scan\n\n0x1.8p1 0 0\n1 2 3\n");
  expectReadError(p, "non-numeric value '0x1.8p1' at line 3 (column 1; hexadecimal numbers are not read)");
  hgdtest::writeText(p, "0x0p+0 0x0p+0 0x0p+0\n1 2 3\n");  // all hexadecimal: still no row of names
  expectReadError(p, "non-numeric value '0x0p+0' at line 1 (column 1; hexadecimal");
  hgdtest::writeText(p, "1 2 3\n4 5 0x10\n");
  expectReadError(p, "non-numeric value '0x10' at line 2 (column 3");
  hgdtest::writeText(p, "0 0 0 zero\n1 2 3 4\n");
  expectReadError(p, "non-numeric value 'zero' at line 1 (column 4)");
}

// --- OFF -----------------------------------------------------------------------------------

TEST(Off, ReadsAMeshInPieces) {
  TempDir dir;
  std::mt19937 rng(3);
  const std::vector<Tri> tris = tetrahedra(rng, 3);
  // Vertices: every corner once, in order of first use (as the test's own arrays say).
  std::vector<std::array<float, 3>> verts;
  std::vector<std::array<int, 3>> faces;
  for (const auto& t : tris) {
    std::array<int, 3> f{};
    for (std::size_t c = 0; c < 3; ++c) {
      auto it = std::find(verts.begin(), verts.end(), t[c]);
      if (it == verts.end()) it = verts.insert(verts.end(), t[c]);
      f[c] = static_cast<int>(it - verts.begin());
    }
    faces.push_back(f);
  }
  std::string text = "OFF # three tetrahedra\n# counts\n" + std::to_string(verts.size()) + " " +
                     std::to_string(faces.size()) + " 0\n";
  for (const auto& v : verts) text += g17(v[0]) + " " + g17(v[1]) + " " + g17(v[2]) + "\n";
  for (const auto& f : faces)
    text += "3 " + std::to_string(f[0]) + " " + std::to_string(f[1]) + " " + std::to_string(f[2]) + "\n";
  const std::string p = dir.file("pieces.off");
  hgdtest::writeText(p, text);
  const Shape s = hgd::readShape(p);
  EXPECT_EQ(s.format, hgd::FileFormat::Off);
  ASSERT_EQ(s.size(), verts.size());
  ASSERT_EQ(s.polygons.size(), faces.size());
  for (std::size_t f = 0; f < faces.size(); ++f)
    for (std::size_t c = 0; c < 3; ++c) EXPECT_EQ(s.polygons[f].vertices[c], faces[f][c]);
  expectTriangles(s, tris);
  // Round trip through OFF keeps every vertex and face.
  const std::string out = dir.file("out.off");
  hgd::writeShape(out, s);
  const Shape b = hgd::readShape(out);
  ASSERT_EQ(b.size(), s.size());
  expectTriangles(b, tris);
}

TEST(Off, ColourAndNormalVariants) {
  TempDir dir;
  const std::string p = dir.file("c.off");
  hgdtest::writeText(p,
                     "CNOFF 4 1 0\n0 0 0 0 0 1 255 0 0 255\n1 0 0 0 0 1 0 255 0 255\n"
                     "0 1 0 0 0 1 0 0 255 255\n1 1 0 0 0 1 9 9 9 255\n4 0 1 3 2 200 10 10\n");
  const Shape s = hgd::readShape(p);
  EXPECT_EQ(names(s),
            (std::vector<std::string>{"x", "y", "z", "nx", "ny", "nz", "red", "green", "blue", "alpha"}));
  EXPECT_EQ(value(s, 1, "green"), 255);
  EXPECT_EQ(value(s, 3, "x"), 1);
  ASSERT_EQ(s.polygons.size(), 1u);
  EXPECT_EQ(s.polygons[0].vertices, (std::vector<pcl::index_t>{0, 1, 3, 2}));
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("face colours"), std::string::npos);
  const std::string out = dir.file("back.off");
  hgd::writeShape(out, s);
  EXPECT_EQ(hgdtest::slurp(out).substr(0, 6), "CNOFF\n");
  const Shape b = hgd::readShape(out);
  EXPECT_EQ(names(b), names(s));
  for (std::size_t i = 0; i < 4; ++i)
    for (const auto& n : names(s)) EXPECT_EQ(value(b, i, n), value(s, i, n)) << n;
}

// A column whose values are spelt with differing decimals ("1.5" beside "1.50", "2" beside
// "2.000") comes back spelt as it was, row by row, in XYZ, OFF, OBJ and ascii PLY: written with
// the column's fewest decimals, 780 of 900 rows of such a file were respelt (issue 48).
TEST(TextSpelling, MixedDecimalsComeBackAsSpelt) {
  TempDir dir;
  std::mt19937 rng(5);
  std::string rows;
  for (int i = 0; i < 300; ++i) {
    const char* forms[] = {"%.1f", "%.2f", "%.3f", "%.0f", "%.6f"};
    std::string row;
    for (int a = 0; a < 3; ++a) {
      char b[40];
      std::snprintf(b, sizeof b, forms[rng() % 5], 0.5 * static_cast<double>(rng() % 40) + 0.25 * a);
      row += (a ? " " : "") + std::string(b);
    }
    rows += row + "\n";
  }
  const std::string xyz = dir.file("mixed.xyz");
  hgdtest::writeText(xyz, rows);
  hgd::writeShape(dir.file("back.xyz"), hgd::readShape(xyz));
  EXPECT_EQ(hgdtest::slurp(dir.file("back.xyz")), rows);

  const std::string off = dir.file("mixed.off");
  hgdtest::writeText(off, "OFF\n300 1 0\n" + rows + "3 0 1 2\n");
  hgd::writeShape(dir.file("back.off"), hgd::readShape(off));
  EXPECT_EQ(hgdtest::slurp(dir.file("back.off")), hgdtest::slurp(off));

  std::string obj_text;
  for (std::size_t at = 0, next; (next = rows.find('\n', at)) != std::string::npos; at = next + 1)
    obj_text += "v " + rows.substr(at, next - at + 1);
  obj_text += "f 1 2 3\n";
  const std::string obj = dir.file("mixed.obj");
  hgdtest::writeText(obj, obj_text);
  hgd::writeShape(dir.file("back.obj"), hgd::readShape(obj));
  EXPECT_NE(hgdtest::slurp(dir.file("back.obj")).find(obj_text.substr(0, 200)), std::string::npos);

  const std::string ply = dir.file("mixed.ply");
  const std::string head =
      "ply\nformat ascii 1.0\nelement vertex 300\nproperty double x\nproperty double y\nproperty double z\n"
      "end_header\n";
  hgdtest::writeText(ply, head + rows);
  hgd::WriteOptions ascii;
  ascii.encoding = hgd::Encoding::Ascii;
  hgd::writeShape(dir.file("back.ply"), hgd::readShape(ply), ascii);
  const std::string back = hgdtest::slurp(dir.file("back.ply"));
  ASSERT_NE(back.find("end_header\n"), std::string::npos);
  EXPECT_EQ(back.substr(back.find("end_header\n") + 11), rows);
}

// Colours without alpha get an opaque one in OFF (Open3D and CloudCompare read r g b a and
// misread three values); 0..1 colours (an OBJ's) become 0..255 there, as OFF's readers take any
// colour (issue 48).
TEST(Off, ColoursAreWrittenWithAlphaAndAsBytes) {
  TempDir dir;
  const std::string obj = dir.file("c.obj");
  hgdtest::writeText(obj, "v 0 0 0 1 0 0.5\nv 1 0 0 0 1 0\nv 0 1 0 0.2 0.4 1\nf 1 2 3\n");
  const std::string out = dir.file("c.off");
  hgd::writeShape(out, hgd::readShape(obj));
  // 0.5 * 255 = 127.5 rounds to 128; 0.2 * 255 = 51, 0.4 * 255 = 102
  EXPECT_EQ(hgdtest::slurp(out),
            "COFF\n3 1 0\n0 0 0 255 0 128 255\n1 0 0 0 255 0 255\n0 1 0 51 102 255 255\n3 0 1 2\n");
  const std::string ply = dir.file("c.ply");
  hgdtest::writeText(ply,
                     "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                     "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
                     "end_header\n1 2 3 4 5 6\n");
  const std::string out2 = dir.file("p.off");
  hgd::writeShape(out2, hgd::readShape(ply));
  EXPECT_EQ(hgdtest::slurp(out2), "COFF\n1 0 0\n1 2 3 4 5 6 255\n");
}

// An alpha of 0..1 without red, green and blue is no colour to convert: kept as it is. The
// conversion looked up the red field's flag at index -1, a read before its buffer that only
// AddressSanitizer sees (scripts/sanitize.sh runs this test so).
TEST(Off, AlphaWithoutColoursIsKept) {
  TempDir dir;
  const std::string xyz = dir.file("a.xyz");
  hgdtest::writeText(xyz, "//X Y Z alpha\n0 0 0 0.5\n1 0 0 0.25\n0 1 0 1\n");
  const std::string ply = dir.file("a.ply");
  hgd::writeShape(ply, hgd::readShape(xyz));
  const Shape b = hgd::readShape(ply);
  ASSERT_EQ(names(b), (std::vector<std::string>{"x", "y", "z", "alpha"}));
  EXPECT_EQ(value(b, 0, "alpha"), 0.5);
  EXPECT_EQ(value(b, 1, "alpha"), 0.25);
}

// An OBJ whose every vertex has one normal (each corner v//vn naming the same one) gives them
// as nx ny nz; corners that give a vertex two normals keep them with the lines only. A shape
// with normals is written to OBJ with one 'vn' per 'v' and faces naming them (issue 48).
TEST(Obj, VertexNormalsAreFieldsBothWays) {
  TempDir dir;
  const std::string p = dir.file("n.obj");
  hgdtest::writeText(p,
                     "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvn 0 0 1\nvn 0.6 0 0.8\nvn 0 -1 0\n"
                     "f 1//3 2//1 3//2\nf 2//1 4//2 3//2\n");
  const Shape s = hgd::readShape(p);
  ASSERT_EQ(names(s), (std::vector<std::string>{"x", "y", "z", "nx", "ny", "nz"}));
  const float want[4][3] = {{0, -1, 0}, {0, 0, 1}, {0.6f, 0, 0.8f}, {0.6f, 0, 0.8f}};
  for (std::size_t i = 0; i < 4; ++i)
    for (int a = 0; a < 3; ++a)
      EXPECT_EQ(value(s, i, std::string("n") + "xyz"[a]), want[i][a]) << i << " " << a;
  const std::string ply = dir.file("n.ply");
  hgd::writeShape(ply, s);
  EXPECT_EQ(names(hgd::readShape(ply)), (std::vector<std::string>{"x", "y", "z", "nx", "ny", "nz"}));

  // vertex 2 (index 1) with two normals: no fields
  const std::string q = dir.file("m.obj");
  hgdtest::writeText(q,
                     "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 0 1 0\nf 1//1 2//1 3//1\nf 1//1 3//1 2//2\n");
  EXPECT_EQ(names(hgd::readShape(q)), (std::vector<std::string>{"x", "y", "z"}));

  const std::string back = dir.file("back.obj");
  hgd::writeShape(back, hgd::readShape(ply));
  EXPECT_EQ(hgdtest::slurp(back),
            "# written by hgdeform\nv 0 0 0\nvn 0 -1 0\nv 1 0 0\nvn 0 0 1\nv 0 1 0\nvn 0.6 0 0.8\n"
            "v 1 1 0\nvn 0.6 0 0.8\nf 1//1 2//2 3//3\nf 2//2 4//4 3//3\n");
  const Shape b = hgd::readShape(back);
  for (std::size_t i = 0; i < 4; ++i)
    for (const auto& n : names(s)) EXPECT_EQ(value(b, i, n), value(s, i, n)) << i << n;
}

// More lines than the header declares: an error naming the line, as PLY does, instead of
// faces silently dropped (issue 28 item 8).
TEST(Off, MoreFacesThanTheHeaderDeclaresIsAnError) {
  TempDir dir;
  const std::string p = dir.file("m.off");
  hgdtest::writeText(p, "OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 1 3 2 # one more\n");
  expectReadError(p,
                  "malformed data: line 8 '3 1 3 2 # one more': more lines than the header declares "
                  "(4 vertices, 1 faces)");
  hgdtest::writeText(p, "OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 1 3 2\n# the end\n\n");
  EXPECT_EQ(hgd::readShape(p).polygons.size(), 2u);
}

TEST(Off, MalformedAndTruncated) {
  TempDir dir;
  const std::string p = dir.file("bad.off");
  hgdtest::writeText(p, "OFF\n3 1 0\n0 0 0\n1 0 0\n");
  expectReadError(p, "truncated");
  hgdtest::writeText(p, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n");
  expectReadError(p, "bad face index '7' at line 6");
  hgdtest::writeText(p, "OFF\n3 0 0\n0 0 0\n1 x 0\n0 1 0\n");
  expectReadError(p, "'x' at line 4");
  hgdtest::writeText(p, "OFF\n3000000 1 0\n0 0 0\n");
  expectReadError(p, "truncated");
  // A face count of 2^64 - 1 (k + 1 wrapped to 0 and passed the check; found by fuzz_off).
  hgdtest::writeText(p, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n18446744073709551615 0 1 2\n");
  expectReadError(p, "bad face: line 6");
}

// --- STL -----------------------------------------------------------------------------------

TEST(Stl, AsciiWeldsCornersAndKeepsFaces) {
  TempDir dir;
  std::mt19937 rng(7);
  const std::vector<Tri> tris = tetrahedra(rng, 4);
  const std::string p = dir.file("m.stl");
  hgdtest::writeText(p, asciiStl(tris));
  const Shape s = hgd::readShape(p);
  EXPECT_EQ(s.format, hgd::FileFormat::Stl);
  EXPECT_EQ(s.size(), 16u);  // 4 corners per tetrahedron, each shared by 3 triangles
  expectTriangles(s, tris);
}

// The issue: an ASCII STL in upper case (SOLID, FACET NORMAL, VERTEX, ... as some exporters
// write it) was taken for a binary STL "declaring 1919252000 triangles". Read by its content, at
// .stl and at another extension alike.
TEST(Stl, UpperCaseAsciiIsAscii) {
  TempDir dir;
  std::mt19937 rng(11);
  const std::vector<Tri> tris = tetrahedra(rng, 2);
  std::string text = asciiStl(tris);
  for (char& c : text) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));  // 1E-05 reads too
  for (const std::string name : {"m.stl", "m.dat"}) {
    SCOPED_TRACE(name);
    const std::string p = dir.file(name);
    hgdtest::writeText(p, text);
    const Shape s = hgd::readShape(p);
    EXPECT_EQ(s.format, hgd::FileFormat::Stl);
    EXPECT_EQ(s.size(), 8u);
    expectTriangles(s, tris);
  }
}

TEST(Stl, BinaryWeldsAndWarnsAboutAttributes) {
  TempDir dir;
  std::mt19937 rng(8);
  const std::vector<Tri> tris = tetrahedra(rng, 2);
  const std::string p = dir.file("m.stl");
  hgdtest::writeText(p, binaryStl(tris, static_cast<std::uint32_t>(tris.size())));
  Shape s = hgd::readShape(p);
  EXPECT_EQ(s.size(), 8u);
  expectTriangles(s, tris);
  EXPECT_TRUE(s.warnings.empty());
  hgdtest::writeText(p, binaryStl(tris, static_cast<std::uint32_t>(tris.size()), 0x7c1f));
  s = hgd::readShape(p);
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("attribute bytes"), std::string::npos);
}

TEST(Stl, WrongTriangleCountOrTruncationIsRefused) {
  TempDir dir;
  std::mt19937 rng(9);
  const std::vector<Tri> tris = tetrahedra(rng, 1);
  const std::string p = dir.file("bad.stl");
  hgdtest::writeText(p, binaryStl(tris, 5));
  expectReadError(p, "declares 5 triangles");
  hgdtest::writeText(p, binaryStl(tris, 4).substr(0, 84 + 50 * 3 + 20));
  expectReadError(p, "declares 4 triangles");
  hgdtest::writeText(p, std::string(40, '\1'));
  expectReadError(p, "at least 84 bytes");
  const std::string text = asciiStl(tris);
  hgdtest::writeText(p, text.substr(0, text.find("endfacet")));
  expectReadError(p, "no 'endfacet'");
}

TEST(Stl, RoundTripsAsciiAndBinary) {
  TempDir dir;
  std::mt19937 rng(10);
  const std::vector<Tri> tris = tetrahedra(rng, 3);
  const std::string in = dir.file("in.stl");
  hgdtest::writeText(in, asciiStl(tris));
  const Shape s = hgd::readShape(in);
  for (const auto enc : {hgd::Encoding::Binary, hgd::Encoding::Ascii}) {
    const std::string out = dir.file("out.stl");
    hgd::WriteOptions wo;
    wo.encoding = enc;
    hgd::writeShape(out, s, wo);
    const std::string bytes = hgdtest::slurp(out);
    if (enc == hgd::Encoding::Binary) {
      EXPECT_EQ(bytes.size(), 84 + 50 * tris.size());
    }
    const Shape b = hgd::readShape(out);
    EXPECT_EQ(b.size(), s.size());
    expectTriangles(b, tris);
  }
}

TEST(Stl, FieldsItCannotHoldAreNamed) {
  TempDir dir;
  const std::string p = dir.file("c.xyz");
  hgdtest::writeText(p, "x y z intensity\n0 0 0 1\n");
  const Shape s = hgd::readShape(p);
  EXPECT_EQ(hgd::extrasLost(s, hgd::FileFormat::Stl), "STL cannot hold the fields intensity");
  EXPECT_EQ(hgd::extrasLost(s, hgd::FileFormat::Off), "OFF cannot hold the fields intensity");
  EXPECT_EQ(hgd::extrasLost(s, hgd::FileFormat::Xyz), "");
}

TEST(Stl, CloudWithoutFacesIsNotWrittenAndLeavesNothing) {
  TempDir dir;
  const std::string in = dir.file("c.xyz");
  hgdtest::writeText(in, "0 0 0\n1 0 0\n0 1 0\n");
  const Shape s = hgd::readShape(in);
  const std::string out = dir.file("c.stl");
  expectIoError([&] { hgd::writeShape(out, s); }, out, "no faces");
  EXPECT_EQ(dir.list(), std::vector<std::string>{"c.xyz"});
}

// --- reading by content --------------------------------------------------------------------

TEST(Sniff, ContentWinsOverTheExtension) {
  TempDir dir;
  const std::string ply =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n";
  const std::string p = dir.file("mesh.obj");
  hgdtest::writeText(p, ply);
  Shape s = hgd::readShape(p);
  EXPECT_EQ(s.format, hgd::FileFormat::Ply);
  EXPECT_EQ(s.size(), 3u);
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("read as PLY although the extension '.obj' says OBJ"), std::string::npos)
      << s.warnings[0];

  std::mt19937 rng(4);
  const std::vector<Tri> tris = tetrahedra(rng, 1);
  const std::string q = dir.file("part.dat");
  hgdtest::writeText(q, binaryStl(tris, 4));
  s = hgd::readShape(q);
  EXPECT_EQ(s.format, hgd::FileFormat::Stl);
  expectTriangles(s, tris);
  EXPECT_EQ(hgd::sniffFormat(q), hgd::FileFormat::Stl);

  const std::string r = dir.file("cloud.ply");
  hgdtest::writeText(r,
                     "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
                     "WIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n1 2 3\n");
  EXPECT_EQ(hgd::readShape(r).format, hgd::FileFormat::Pcd);
  hgdtest::writeText(r, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  EXPECT_EQ(hgd::readShape(r).format, hgd::FileFormat::Off);
  hgdtest::writeText(r, "# obj\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  EXPECT_EQ(hgd::readShape(r).format, hgd::FileFormat::Obj);
  hgdtest::writeText(r, "1 2 3\n4 5 6\n");
  EXPECT_EQ(hgd::readShape(r).format, hgd::FileFormat::Xyz);

  const std::string none = dir.file("noext");
  hgdtest::writeText(none, "0.5 1 2\n");
  s = hgd::readShape(none);
  EXPECT_EQ(s.format, hgd::FileFormat::Xyz);
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("(none)"), std::string::npos) << s.warnings[0];

  hgdtest::writeText(none, "\x89PNG\r\n\x1a\n....");
  expectReadError(none, "matches no format");
  expectIoError([&] { hgd::sniffFormat(none); }, none, "matches no format");
}

/// An OBJ of `lines`, padded with a comment so that the file is 84 + 50 n bytes and its bytes
/// 80-83 read n: the size of a binary STL of n triangles. `filler` fills the comment.
std::string objOfStlSize(const std::string& lines, std::uint32_t n, char filler) {
  const std::size_t size = 84 + 50 * std::size_t{n};
  std::string s = lines + "#";
  s.resize(size - 1, filler);
  s += '\n';
  std::memcpy(&s[80], &n, 4);  // little-endian hosts (x86_64, aarch64), as the STL counts
  return s;
}

// Found by fuzz_obj: a binary STL is known by its size alone, and an OBJ (whose comments keep
// any bytes) can match it. Read as STL, the file had 2 points where the OBJ it was had 1, and
// hgdeform could write an OBJ that it then read back as something else. A file named for a text
// format, whose text says that format (for an OBJ, a vertex or face on any line) or whose bytes
// after the would-be header are text, stays text; the STL test still wins for a real binary STL
// of any name.
TEST(Sniff, TextWhoseSizeFitsABinaryStlStaysText) {
  TempDir dir;
  // The fuzzer's case: a vertex, then a comment holding the count 1 (bytes 01 00 00 00).
  const std::string p = dir.file("coincidence.obj");
  hgdtest::writeText(p, objOfStlSize("v 1 2 3\n", 1, 'A'));
  Shape s = hgd::readShape(p);
  EXPECT_EQ(s.format, hgd::FileFormat::Obj);
  EXPECT_EQ(s.size(), 1u);
  EXPECT_TRUE(s.warnings.empty());
  // Written back (the comment kept as it was, and one more line end so that the file no longer
  // has a binary STL's size) and read again: the same one point.
  const std::string q = dir.file("again.obj");
  hgd::writeShape(q, s);
  EXPECT_EQ(hgdtest::slurp(q), hgdtest::slurp(p) + "\n");
  EXPECT_EQ(hgd::readShape(q).size(), 1u);

  // A first line that names no format ('s', a smoothing group): the bytes after the would-be
  // header decide, and they are text.
  hgdtest::writeText(p, objOfStlSize("s 1\nv 1 2 3\nv 4 5 6\n", 2, 'x'));
  s = hgd::readShape(p);
  EXPECT_EQ(s.format, hgd::FileFormat::Obj);
  EXPECT_EQ(s.size(), 2u);

  // Found by fuzz_obj again: a first line that names no format and bytes after the would-be
  // header that are not text (an OBJ keeps any bytes in a statement it does not know). A
  // vertex statement on any line makes it an OBJ; read as STL it was three points of junk, and
  // hgdeform wrote OBJs it could not read back as they were.
  hgdtest::writeText(p, objOfStlSize("s 1\nv 1 2 3\n", 1, '\x01'));
  s = hgd::readShape(p);
  EXPECT_EQ(s.format, hgd::FileFormat::Obj);
  EXPECT_EQ(s.size(), 1u);
  hgd::writeShape(q, s);
  EXPECT_EQ(hgdtest::slurp(q), hgdtest::slurp(p) + "\n");
  EXPECT_EQ(hgd::readShape(q).size(), 1u);

  // And a third time: non-text bytes before the vertex line, in a file read as OBJ by its name
  // (its size is no STL's), which the writer's dropping of a leading blank brought to an STL's
  // size: the writer adds a line end to any OBJ of that size, so what it writes reads back.
  std::string odd = objOfStlSize("s 1\ng\xe0\x92 x\nv 1 2 3\n", 1, '\x01');
  odd.insert(4, " ");  // " g...": one byte more here, and the count at bytes 81-84
  hgdtest::writeText(p, odd);
  s = hgd::readShape(p);
  EXPECT_EQ(s.format, hgd::FileFormat::Obj);
  ASSERT_EQ(s.size(), 1u);
  hgd::writeShape(q, s);
  const hgd::Shape back = hgd::readShape(q);
  EXPECT_EQ(back.format, hgd::FileFormat::Obj);
  EXPECT_EQ(back.size(), 1u);

  // A real binary STL named .obj is still an STL (its records are not text), with the warning.
  std::mt19937 rng(5);
  const std::vector<Tri> tris = tetrahedra(rng, 2);
  hgdtest::writeText(p, binaryStl(tris, 8));
  s = hgd::readShape(p);
  EXPECT_EQ(s.format, hgd::FileFormat::Stl);
  expectTriangles(s, tris);
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("read as STL"), std::string::npos) << s.warnings[0];

  // Even when its records' bytes spell a line starting "v " (x = 10.0288, the bytes 0A 76 20
  // 41: a newline, 'v', a blank, 'A'): only a whole vertex or face line in text before the
  // first byte that is not text makes an OBJ (the review's case; it was read as a broken OBJ).
  float x = 0;
  const unsigned char spell[4] = {0x0A, 0x76, 0x20, 0x41};
  std::memcpy(&x, spell, 4);
  const std::vector<Tri> spelling = {
      Tri{{{0, 0, 0}, {0, 10, 0}, {x, 0, 0}}}, Tri{{{0, 0, 0}, {x, 0, 0}, {0, 0, 10}}},
      Tri{{{0, 0, 0}, {0, 0, 10}, {0, 10, 0}}}, Tri{{{x, 0, 0}, {0, 10, 0}, {0, 0, 10}}}};
  hgdtest::writeText(p, binaryStl(spelling, 4));
  s = hgd::readShape(p);
  EXPECT_EQ(s.format, hgd::FileFormat::Stl);
  expectTriangles(s, spelling);
}

TEST(Sniff, FileOfItsOwnFormatGetsThatFormatsErrors) {
  TempDir dir;
  const std::string p = dir.file("broken.ply");
  hgdtest::writeText(p, "plx\nformat ascii 1.0\n");
  expectReadError(p, "expected 'ply'");
}

}  // namespace
