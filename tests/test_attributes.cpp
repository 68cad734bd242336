// Every attribute of a file survives a deformation written back in its own format: an OBJ's
// texture coordinates, normals (turned with the shape), groups, objects, materials and face
// corners; a PLY's face properties, vertex list properties, other elements and comments, in
// every encoding. Expected values come from the files as written here, not from the reader.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <sstream>
#include <string>
#include <vector>

#include "hgdeform/app/runner.h"
#include "hgdeform/app/scenario.h"
#include "hgdeform/deformer/deformer.h"
#include "hgdeform/io/io.h"
#include "test_util.h"

namespace {

using hgdtest::slurp;
using hgdtest::TempDir;
using hgdtest::writeText;

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}

bool startsWith(const std::string& s, const char* p) {
  return s.rfind(p, 0) == 0;
}

// A bent-able strip as an OBJ the way modelling tools write one: a material library, an
// object and two groups, texture coordinates, per-vertex normals and v/vt/vn corners, a
// smoothing group and a comment. Returns the file's text.
std::string stripObj(int nx, int ny, std::vector<Eigen::Vector3f>* normals = nullptr) {
  std::string t = "# made by a test\nmtllib strip.mtl\no strip\n";
  for (int i = 0; i < nx; ++i)
    for (int j = 0; j < ny; ++j) {
      char b[96];
      std::snprintf(b, sizeof b, "v %g %g %g\n", 0.05 * i, 0.05 * j, 0.02 * std::sin(0.7 * i));
      t += b;
    }
  for (int i = 0; i < nx; ++i)
    for (int j = 0; j < ny; ++j) {
      char b[64];
      std::snprintf(b, sizeof b, "vt %g %g\n", i / double(nx - 1), j / double(ny - 1));
      t += b;
    }
  // Normals of the surface z = 0.02 sin(0.7 i): (-dz/dx, 0, 1), x = 0.05 i.
  for (int i = 0; i < nx; ++i)
    for (int j = 0; j < ny; ++j) {
      const Eigen::Vector3f n =
          Eigen::Vector3f(-0.02f * 0.7f / 0.05f * std::cos(0.7f * i), 0, 1).normalized();
      if (normals) normals->push_back(n);
      char b[96];
      std::snprintf(b, sizeof b, "vn %.7g %.7g %.7g\n", n.x(), n.y(), n.z());
      t += b;
    }
  t += "usemtl paper\ns 1\n";
  for (int i = 0; i + 1 < nx; ++i) {
    if (i == 0) t += "g left\n";
    if (i == nx / 2) t += "g right\n";
    for (int j = 0; j + 1 < ny; ++j) {
      const int a = i * ny + j + 1, b = (i + 1) * ny + j + 1, c = (i + 1) * ny + j + 2, d = i * ny + j + 2;
      char buf[160];
      std::snprintf(buf, sizeof buf, "f %d/%d/%d %d/%d/%d %d/%d/%d %d/%d/%d\n", a, a, a, b, b, b, c, c, c, d,
                    d, d);
      t += buf;
    }
  }
  return t;
}

hgd::Scenario turnTheFarEnd(double degrees, double from_x = 1.3) {
  hgd::Scenario s;
  s.fixed.push_back(hgd::Region::box({-1, -1, -1}, {0.12, 10, 1}));
  s.manipulated = hgd::Region::box({from_x, -1, -1}, {10, 10, 1});
  hgd::Move m;
  m.kind = hgd::Move::Kind::Frame;
  m.frame.axis = Eigen::Vector3d::UnitY();
  m.frame.degrees = degrees;
  s.moves.push_back(m);
  return s;
}

// Each normal `vn` (grid order, i along the strip) against the normal of the deformed strip
// `v` at its vertex: the cross product of the grid tangents computed here from the written
// vertices. The far end (turned by about 50 degrees) must have turned.
void expectNormalsFollowTheStrip(const std::vector<Eigen::Vector3f>& v,
                                 const std::vector<Eigen::Vector3f>& vn, int nx, int ny, const char* what) {
  ASSERT_EQ(v.size(), static_cast<std::size_t>(nx * ny));
  ASSERT_EQ(vn.size(), v.size());
  double worst = 0, sum = 0;
  int far_end_turned = 0;
  for (int i = 0; i < nx; ++i)
    for (int j = 0; j < ny; ++j) {
      const auto at = [&](int ii, int jj) { return v[static_cast<std::size_t>(ii * ny + jj)]; };
      const Eigen::Vector3f du = at(std::min(i + 1, nx - 1), j) - at(std::max(i - 1, 0), j);
      const Eigen::Vector3f dv = at(i, std::min(j + 1, ny - 1)) - at(i, std::max(j - 1, 0));
      const Eigen::Vector3f expected = du.cross(dv).normalized();
      const Eigen::Vector3f got = vn[static_cast<std::size_t>(i * ny + j)].normalized();
      const double angle =
          std::acos(std::clamp(static_cast<double>(expected.dot(got)), -1.0, 1.0)) * 180 / M_PI;
      worst = std::max(worst, angle);
      sum += angle;
      if (i == nx - 1 && std::abs(got.x()) > 0.5f) ++far_end_turned;  // turned by about 50 degrees
    }
  std::printf("%s: mean %.2f, worst %.2f degrees from the deformed strip's\n", what, sum / (nx * ny), worst);
  EXPECT_LT(sum / (nx * ny), 3.0);
  EXPECT_LT(worst, 12.0);  // the strip's ends, where a one-sided difference is coarse
  EXPECT_EQ(far_end_turned, ny);
}

// The OBJ written back has every line it had, in order; only v and vn lines change. Each vn
// is turned as the surface turned: compared with the normal of the deformed strip computed
// here from the written vertices.
TEST(Attributes, ObjKeepsEveryLineAndTurnsItsNormals) {
  TempDir dir;
  const int nx = 30, ny = 6;
  const std::string in_text = stripObj(nx, ny);
  writeText(dir.file("strip.obj"), in_text);
  hgd::Shape shape = hgd::readShape(dir.file("strip.obj"));
  const hgd::DeformReport rep = hgd::deformShape(shape, turnTheFarEnd(50));
  EXPECT_TRUE(rep.warnings.empty()) << rep.warnings.front();
  EXPECT_EQ(hgd::extrasLost(shape, hgd::FileFormat::Obj), "");
  EXPECT_NE(hgd::extrasLost(shape, hgd::FileFormat::Ply), "");
  hgd::writeShape(dir.file("out.obj"), shape);
  const auto a = lines(in_text), b = lines(slurp(dir.file("out.obj")));
  ASSERT_EQ(a.size(), b.size());
  std::vector<Eigen::Vector3f> v, vn;
  std::size_t changed_v = 0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    if (startsWith(a[k], "v ")) {
      ASSERT_TRUE(startsWith(b[k], "v ")) << k;
      Eigen::Vector3f x;
      std::sscanf(b[k].c_str(), "v %f %f %f", &x.x(), &x.y(), &x.z());
      v.push_back(x);
      changed_v += a[k] != b[k];
    } else if (startsWith(a[k], "vn ")) {
      ASSERT_TRUE(startsWith(b[k], "vn ")) << k;
      Eigen::Vector3f n;
      std::sscanf(b[k].c_str(), "vn %f %f %f", &n.x(), &n.y(), &n.z());
      vn.push_back(n);
    } else {
      EXPECT_EQ(a[k], b[k]) << "line " << k + 1;  // vt, g, o, usemtl, mtllib, s, f, comments
    }
  }
  ASSERT_EQ(v.size(), static_cast<std::size_t>(nx * ny));
  ASSERT_EQ(vn.size(), v.size());
  EXPECT_GT(changed_v, v.size() / 2);
  expectNormalsFollowTheStrip(v, vn, nx, ny, "obj normals");
}

// An OBJ point cloud (v and vn lines, no faces) pairs its normals with its vertices by order,
// as MeshLab and CloudCompare read one, so they turn with the shape as a mesh's do (the issue:
// no face paired a vn with a v, so every vn was written back as read).
TEST(Attributes, ObjCloudNormalsTurnWithTheShape) {
  TempDir dir;
  const int nx = 30, ny = 6;
  std::string text = "# a scanned strip: points and normals\n";
  for (int i = 0; i < nx; ++i)
    for (int j = 0; j < ny; ++j) {
      // The surface z = 0.02 sin(0.7 i) at x = 0.05 i; its normal (-dz/dx, 0, 1).
      const Eigen::Vector3f n =
          Eigen::Vector3f(-0.02f * 0.7f / 0.05f * std::cos(0.7f * i), 0, 1).normalized();
      char b[192];
      std::snprintf(b, sizeof b, "v %g %g %g\nvn %.7g %.7g %.7g\n", 0.05 * i, 0.05 * j,
                    0.02 * std::sin(0.7 * i), n.x(), n.y(), n.z());
      text += b;
    }
  writeText(dir.file("strip.obj"), text);
  hgd::Shape shape = hgd::readShape(dir.file("strip.obj"));
  ASSERT_TRUE(shape.polygons.empty());
  const hgd::DeformReport rep = hgd::deformShape(shape, turnTheFarEnd(50));
  EXPECT_TRUE(rep.warnings.empty()) << rep.warnings.front();
  hgd::writeShape(dir.file("out.obj"), shape);
  const auto a = lines(text), b = lines(slurp(dir.file("out.obj")));
  ASSERT_EQ(a.size(), b.size());
  std::vector<Eigen::Vector3f> v, vn;
  for (std::size_t k = 0; k < a.size(); ++k) {
    if (startsWith(a[k], "v ")) {
      Eigen::Vector3f x;
      ASSERT_EQ(std::sscanf(b[k].c_str(), "v %f %f %f", &x.x(), &x.y(), &x.z()), 3) << b[k];
      v.push_back(x);
    } else if (startsWith(a[k], "vn ")) {
      Eigen::Vector3f n;
      ASSERT_EQ(std::sscanf(b[k].c_str(), "vn %f %f %f", &n.x(), &n.y(), &n.z()), 3) << b[k];
      vn.push_back(n);
    } else {
      EXPECT_EQ(a[k], b[k]) << "line " << k + 1;
    }
  }
  expectNormalsFollowTheStrip(v, vn, nx, ny, "obj cloud normals");
}

// A PLY as scanners and MeshLab write them: comments, a vertex list property, per-face
// colours and a flag, an edge element and a camera element. Written in `format`.
std::string richPly(const std::string& format, int nx, int ny) {
  const bool ascii = format == "ascii", be = format == "binary_big_endian";
  std::string h = "ply\nformat " + format + " 1.0\ncomment scanned by a test\nobj_info rig 7\n";
  h += "element camera 1\nproperty float view_px\nproperty float view_py\nproperty float view_pz\n";
  h += "element vertex " + std::to_string(nx * ny) +
       "\nproperty float x\nproperty float y\nproperty float z\nproperty list uchar float "
       "uv\nproperty uchar quality\n";
  const int faces = (nx - 1) * (ny - 1);
  h += "element face " + std::to_string(faces) +
       "\nproperty list uchar int vertex_indices\nproperty uchar red\nproperty uchar green\nproperty uchar "
       "blue\nproperty short flag\n";
  h += "element edge 2\nproperty int vertex1\nproperty int vertex2\nend_header\n";
  std::string d;
  const auto put = [&](auto x) {
    if (ascii) {
      std::ostringstream o;
      o.precision(9);
      if constexpr (sizeof x == 1)
        o << static_cast<int>(x);
      else
        o << x;
      d += (d.empty() || d.back() == '\n' ? "" : " ") + o.str();
      return;
    }
    char b[sizeof x];
    std::memcpy(b, &x, sizeof x);
    if (be) std::reverse(b, b + sizeof x);
    d.append(b, sizeof x);
  };
  const auto eol = [&] {
    if (ascii) d += "\n";
  };
  put(1.5f), put(-2.0f), put(9.25f), eol();
  for (int i = 0; i < nx; ++i)
    for (int j = 0; j < ny; ++j) {
      put(0.05f * i), put(0.05f * j), put(0.0f);
      put(static_cast<std::uint8_t>(2)), put(i / float(nx)), put(j / float(ny));
      put(static_cast<std::uint8_t>((i * 7 + j) % 256)), eol();
    }
  for (int i = 0; i + 1 < nx; ++i)
    for (int j = 0; j + 1 < ny; ++j) {
      put(static_cast<std::uint8_t>(4));
      for (const int k : {i * ny + j, (i + 1) * ny + j, (i + 1) * ny + j + 1, i * ny + j + 1}) put(k);
      put(static_cast<std::uint8_t>(i * 9 % 256)), put(static_cast<std::uint8_t>(j * 40)),
          put(static_cast<std::uint8_t>(200)), put(static_cast<std::int16_t>(-i * j)), eol();
    }
  put(0), put(nx * ny - 1), eol();
  put(3), put(4), eol();
  return h + d;
}

// Read, deformed, written in each encoding, read again: the same elements, properties,
// comments and values, the faces' colours and flags with their faces.
TEST(Attributes, PlyKeepsFacePropertiesListsElementsAndComments) {
  TempDir dir;
  const int nx = 24, ny = 5;
  for (const std::string in_format : {"ascii", "binary_little_endian", "binary_big_endian"}) {
    SCOPED_TRACE(in_format);
    writeText(dir.file("in.ply"), richPly(in_format, nx, ny));
    const hgd::Shape original = hgd::readShape(dir.file("in.ply"));
    hgd::Shape shape = original;
    hgd::deformShape(shape, turnTheFarEnd(40, 1.0));
    for (const hgd::Encoding enc : {hgd::Encoding::Binary, hgd::Encoding::Ascii}) {
      hgd::writeShape(dir.file("out.ply"), shape, {enc});
      const std::string text = slurp(dir.file("out.ply"));
      const hgd::Shape back = hgd::readShape(dir.file("out.ply"));
      EXPECT_NE(text.find("comment scanned by a test\nobj_info rig 7\n"), std::string::npos);
      const auto& x = back.extras.ply_elements;
      ASSERT_EQ(x.size(), 4u);
      const char* names[] = {"camera", "vertex", "face", "edge"};
      for (std::size_t e = 0; e < 4; ++e) {
        EXPECT_EQ(x[e].name, names[e]);
        EXPECT_EQ(x[e].count, original.extras.ply_elements[e].count);
        ASSERT_EQ(x[e].props.size(), original.extras.ply_elements[e].props.size()) << names[e];
        for (std::size_t k = 0; k < x[e].props.size(); ++k) {
          EXPECT_EQ(x[e].props[k].name, original.extras.ply_elements[e].props[k].name);
          EXPECT_EQ(x[e].props[k].type, original.extras.ply_elements[e].props[k].type);
        }
        EXPECT_EQ(x[e].values, original.extras.ply_elements[e].values) << names[e];
      }
      // Independently of the reader's own bookkeeping: the camera, an edge, a face's colour.
      EXPECT_EQ(x[0].values, (std::vector<double>{1.5, -2.0, 9.25}));
      EXPECT_EQ(x[3].values, (std::vector<double>{0, nx * ny - 1.0, 3, 4}));
      const std::size_t f = static_cast<std::size_t>(7 * (ny - 1) + 2);  // face (7, 2)
      ASSERT_GT(back.polygons.size(), f);
      EXPECT_EQ(back.polygons[f].vertices[0], 7 * ny + 2);
      EXPECT_EQ(x[2].values[f * 4 + 0], 7 * 9);
      EXPECT_EQ(x[2].values[f * 4 + 1], 80);
      EXPECT_EQ(x[2].values[f * 4 + 3], -14);
      // The vertex list uv of vertex (3, 1): length 2, then 3/nx and 1/ny.
      const std::size_t vtx = 3 * ny + 1;
      EXPECT_EQ(x[1].values[vtx * 3], 2);
      EXPECT_FLOAT_EQ(static_cast<float>(x[1].values[vtx * 3 + 1]), 3.0f / nx);
      // Positions are the deformed ones, the quality field unchanged.
      EXPECT_EQ(back.cloud.data, shape.cloud.data);
      EXPECT_NE(back.cloud.data, original.cloud.data);
    }
  }
}

}  // namespace

namespace {

// A list kept aside is read as its declared type: a value it cannot hold is an error naming
// the file and the line, as for scalars (it would otherwise be cast out of range on writing).
TEST(Attributes, PlyListValuesOutOfTheirTypeAreRefused) {
  TempDir dir;
  writeText(dir.file("bad.ply"),
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            "property list uchar short tags\nend_header\n0 0 0 1 5\n1 0 0 2 7 1e300\n0 1 0 0\n");
  try {
    hgd::readShape(dir.file("bad.ply"));
    ADD_FAILURE() << "accepted 1e300 as a short";
  } catch (const hgd::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.ply: value out of range"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("line 10"), std::string::npos) << e.what();
  }
  writeText(dir.file("good.ply"),
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            "property list uchar short tags\nend_header\n0 0 0 1 5\n1 0 0 2 7 -32768\n0 1 0 0\n");
  const hgd::Shape s = hgd::readShape(dir.file("good.ply"));
  ASSERT_EQ(s.extras.ply_elements.size(), 1u);
  EXPECT_EQ(s.extras.ply_elements[0].values, (std::vector<double>{1, 5, 2, 7, -32768, 0}));
}

}  // namespace
