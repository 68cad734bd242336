// Precision: what did not move comes back bit for bit, what moved keeps the input's precision.
//
//  - A run that moves nothing, or the points of a fixed handle in a run that does, write every
//    coordinate back as the file had it (bit for bit; the same text in a text format), in float
//    and double PLY, PCD and XYZ, with one far stray in the cloud.
//  - Moved points agree with the same deformation computed here in double (the clusters'
//    transforms in world coordinates, blended as docs/method.md §6 says) within 1e-9 of the
//    shape's size for double input, and within one float ulp for float input: with strays at
//    1e5, 1e10 and 1e22, and on a georeferenced patch at (5e5, 5e6) with millimetre bumps and a
//    scanner's no-return point at the origin.
//  - Points absurdly far from the shape (1e22 in a 3-unit grid) are set apart with a warning,
//    never a crash; a cloud whose bulk spans 1e22 units is refused with a message naming it.
//  - Integer coordinates that cannot hold the result are widened with a warning, not clipped.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "hgdeform/app/runner.h"
#include "hgdeform/app/scenario.h"
#include "hgdeform/deformer/deformer.h"
#include "hgdeform/io/fields.h"
#include "hgdeform/io/io.h"
#include "support/shapes.h"
#include "test_util.h"

using namespace hgdtest;

namespace {

// The grid of the issue: 30 x 30 points, x and y from 0 to 2.9 in steps of 0.1, gentle bumps in
// z, in a shuffled order (as resampled scans arrive), plus the given strays.
std::vector<Eigen::Vector3d> grid(const std::vector<Eigen::Vector3d>& strays, unsigned seed = 7) {
  std::vector<Eigen::Vector3d> p;
  for (int i = 0; i < 30; ++i)
    for (int j = 0; j < 30; ++j) {
      const double x = 0.1 * i, y = 0.1 * j;
      p.emplace_back(x, y, 0.05 * std::sin(3 * x) * std::cos(2 * y));
    }
  std::mt19937 rng(seed);
  std::shuffle(p.begin(), p.end(), rng);
  for (const auto& s : strays) p.insert(p.begin() + static_cast<std::ptrdiff_t>(p.size() / 2), s);
  return p;
}

const char* kGridScenario = R"({
  "format": "hgdeform-scenario/1",
  "fixed": [ {"box": {"min": [-1, -1, -1], "max": [4, 0.35, 1]}} ],
  "manipulated": {"box": {"min": [-1, 2.55, -1], "max": [4, 3, 1]}},
  "clusters": 8,
  "move": {"drag": {"from": [1.5, 2.9, 0], "to": [1.9, 3.3, 0.6]}}
})";
const char* kGridScenarioNoMove = R"({
  "format": "hgdeform-scenario/1",
  "fixed": [ {"box": {"min": [-1, -1, -1], "max": [4, 0.35, 1]}} ],
  "manipulated": {"box": {"min": [-1, 2.55, -1], "max": [4, 3, 1]}},
  "clusters": 8
})";

std::string shortest(double v, bool as_float) {
  char buf[64];
  const auto r = as_float ? std::to_chars(buf, buf + sizeof buf, static_cast<float>(v))
                          : std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

// A PLY of the points with x/y/z of the given type (binary little endian).
void writePly(const std::string& path, const std::vector<Eigen::Vector3d>& pts, bool as_double) {
  std::string s = "ply\nformat binary_little_endian 1.0\ncomment made by test_precision\nelement vertex " +
                  std::to_string(pts.size()) + "\n";
  for (const char* a : {"x", "y", "z"})
    s += std::string("property ") + (as_double ? "double " : "float ") + a + "\n";
  s += "end_header\n";
  for (const auto& p : pts)
    for (int a = 0; a < 3; ++a) {
      if (as_double)
        put(s, p[a]);
      else
        put(s, static_cast<float>(p[a]));
    }
  writeText(path, s);
}

// The points as an XYZ text file (float spellings: what the reader keeps).
std::string xyzText(const std::vector<Eigen::Vector3d>& pts) {
  std::string s;
  for (const auto& p : pts)
    s += shortest(p.x(), true) + " " + shortest(p.y(), true) + " " + shortest(p.z(), true) + "\n";
  return s;
}

Eigen::Vector3d valueOf(const hgd::Shape& s, std::size_t i) {
  const hgd::XyzFields f = hgd::findXyzFields(s.cloud);
  return {hgd::readValue(s.cloud, i, s.cloud.fields[f.x]), hgd::readValue(s.cloud, i, s.cloud.fields[f.y]),
          hgd::readValue(s.cloud, i, s.cloud.fields[f.z])};
}

bool sameBits(double a, double b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

// The nearest rotation by SVD, computed here (not the library's).
Eigen::Matrix3d polarRotation(const Eigen::Matrix3d& a) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(a, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d u = svd.matrixU();
  if ((u * svd.matrixV().transpose()).determinant() < 0) u.col(2) *= -1;
  return u * svd.matrixV().transpose();
}

// Point k's deformation computed here in double, in world coordinates, from the clusters' world
// transforms: the linear blend of the two matrices, or the rotation-aware one (the rigid parts
// about each cluster's barycentre, their quaternions blended on one hemisphere and normalised,
// turning about the pair's centre).
Eigen::Vector3d referenceBlend(const hgd::Deformer& d, const std::vector<Eigen::Affine3d>& T, std::size_t k,
                               const Eigen::Vector3d& x, hgd::Blend blend) {
  const auto br = d.interpolationTable().bracket(k);
  const auto lo = static_cast<std::size_t>(br.lower), hi = static_cast<std::size_t>(br.upper);
  if (lo == hi) return T[lo] * x;
  const double w = br.alpha;
  if (blend == hgd::Blend::Linear)
    return ((1 - w) * T[lo].linear() + w * T[hi].linear()) * x + (1 - w) * T[lo].translation() +
           w * T[hi].translation();
  const Eigen::Vector3d o = d.geometry().origin;
  const Eigen::Vector3d ga = d.clustering().clusters[lo].barycentre + o;
  const Eigen::Vector3d gb = d.clustering().clusters[hi].barycentre + o;
  const Eigen::Vector3d c = 0.5 * (ga + gb);
  const Eigen::Matrix3d ra = polarRotation(T[lo].linear()), rb = polarRotation(T[hi].linear());
  const Eigen::Vector3d ta = ra * (c - ga) + T[lo] * ga, tb = rb * (c - gb) + T[hi] * gb;
  Eigen::Quaterniond qa(ra), qb(rb);
  if (qa.dot(qb) < 0) qb.coeffs() *= -1;
  Eigen::Quaterniond q;
  q.coeffs() = (1 - w) * qa.coeffs() + w * qb.coeffs();
  q.normalize();
  return q.toRotationMatrix() * (x - c) + (1 - w) * ta + w * tb;
}

struct Compared {
  double max_moved_error = 0;  ///< largest |written - reference| over moved points
  double max_float_path = 0;   ///< largest |written - the float positions| over the body's points
  double max_float_ulps = 0;   ///< float input: the same in units of the written value's ulp
  std::size_t moved = 0, unmoved = 0, unmoved_changed = 0, fixed_changed = 0;
};

// Deforms `path` with `scenario` through the library, writes `out`, and compares every written
// coordinate with the input's (unmoved points) or the reference (moved points).
Compared deformAndCompare(const std::string& path, const std::string& scenario, const std::string& out,
                          hgd::Blend blend = hgd::Blend::Rotation, bool multires = false) {
  hgd::RunOptions ro;
  ro.blend = blend;
  if (multires) {  // the coarse level and its prolongation, on a small shape
    ro.deform.multires_above = 400;
    ro.deform.coarse_points = 300;
    ro.deform.points_per_coarse = 0;
  }
  hgd::ScenarioRunner run = hgd::ScenarioRunner::read(path, ro);
  run.setScenario(hgd::parseScenario(scenario, "test.json"));
  run.applyMoves();
  const hgd::Deformer& d = run.deformer();
  const std::vector<Eigen::Affine3d> T = d.worldTransforms();
  run.write(out);
  const hgd::Shape in = hgd::readShape(path), res = hgd::readShape(out);
  const bool is_float = in.cloud.fields[static_cast<std::size_t>(hgd::findXyzFields(in.cloud).x)].datatype ==
                        pcl::PCLPointField::FLOAT32;
  const hgd::Geometry& g = d.geometry();
  std::vector<char> fixed(g.size(), 0);
  for (const auto& h : d.handles().fixed)
    for (const int i : h) fixed[static_cast<std::size_t>(i)] = 1;
  Compared c;
  for (std::size_t i = 0; i < in.size(); ++i) {
    const Eigen::Vector3d a = valueOf(in, i), b = valueOf(res, i);
    const int k = g.finite_index[i];
    const bool identical = sameBits(a.x(), b.x()) && sameBits(a.y(), b.y()) && sameBits(a.z(), b.z());
    if (k < 0) {  // NaN, or set apart as absurdly far: untouched
      c.unmoved_changed += !identical;
      continue;
    }
    const auto ku = static_cast<std::size_t>(k);
    const Eigen::Vector3d ref = referenceBlend(d, T, ku, a, blend);
    // The float positions the viewer shows and the stretch is measured on (a wrong transform or
    // identity flag in the double path would part the two).
    if (g.body.contains((*g.points)[ku].getVector3fMap()))
      c.max_float_path = std::max(c.max_float_path, (b - d.deformedWorld(ku)).cwiseAbs().maxCoeff());
    if (fixed[ku]) c.fixed_changed += !identical;
    if (ref == a) {  // the reference does not move it either
      ++c.unmoved;
      c.unmoved_changed += !identical;
      continue;
    }
    ++c.moved;
    c.max_moved_error = std::max(c.max_moved_error, (b - ref).cwiseAbs().maxCoeff());
    if (is_float)
      for (int ax = 0; ax < 3; ++ax) {
        const float bf = static_cast<float>(b[ax]);
        const double ulp = std::nextafter(bf, std::numeric_limits<float>::infinity()) - bf;
        c.max_float_ulps = std::max(c.max_float_ulps, std::abs(b[ax] - ref[ax]) / ulp);
      }
  }
  std::printf("  %zu moved (largest error %.3g, %.3g float ulps; %.3g from the float path), %zu unmoved\n",
              c.moved, c.max_moved_error, c.max_float_ulps, c.max_float_path, c.unmoved);
  return c;
}

}  // namespace

// The issue's case: a no-move run with one far stray wrote every y as 0. Now every value comes
// back bit for bit, in every format, and the far stray is named.
static void noMoveWritesEveryValueBackBitForBit(const std::string& scenario);

// A scenario without a move, and (issue 48) one whose move is no motion: a frame of 0 rewrote
// every point outside the fixed handle by the rounding of a solve about a far origin.
TEST(Precision, NoMoveWritesEveryValueBackBitForBit) {
  for (const char* move : {"", R"(, "move": {"frame": {"translate": [0, 0, 0]}})",
                           R"(, "move": {"frame": {"rotate": {"axis": [0, 0, 1], "degrees": 0}}})"}) {
    SCOPED_TRACE(move);
    noMoveWritesEveryValueBackBitForBit(
        std::string(kGridScenarioNoMove).insert(std::string(kGridScenarioNoMove).rfind('}'), move));
  }
}

static void noMoveWritesEveryValueBackBitForBit(const std::string& scenario) {
  TempDir dir;
  const auto pts = grid({{0, 1e10, 0}});
  writeText(dir.file("s.json"), scenario);
  std::vector<std::string> inputs;
  writePly(dir.file("float.ply"), pts, false);
  writePly(dir.file("double.ply"), pts, true);
  writeText(dir.file("points.xyz"), xyzText(pts));
  {
    std::vector<Eigen::Vector3f> f;
    for (const auto& p : pts) f.push_back(p.cast<float>());
    hgd::Shape s = hgd::shapes::cloudShape(f, {});
    hgd::writeShape(dir.file("cloud.pcd"), s);
  }
  for (const std::string name : {"float.ply", "double.ply", "points.xyz", "cloud.pcd"}) {
    SCOPED_TRACE(name);
    const std::string ext = name.substr(name.find('.'));
    const CommandResult r =
        shell(quote(HGD_TOOL) + " deform " + quote(dir.file(name)) + " -s " + quote(dir.file("s.json")) +
              " -o " + quote(dir.file("out" + ext)) + " --report " + quote(dir.file("r.json")));
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_TRUE(contains(r.err, "left where they are")) << r.err;  // the 1e10 point, said
    const hgd::Shape a = hgd::readShape(dir.file(name)), b = hgd::readShape(dir.file("out" + ext));
    ASSERT_EQ(a.size(), b.size());
    std::size_t changed = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
      const Eigen::Vector3d va = valueOf(a, i), vb = valueOf(b, i);
      changed += !(sameBits(va.x(), vb.x()) && sameBits(va.y(), vb.y()) && sameBits(va.z(), vb.z()));
    }
    EXPECT_EQ(changed, 0u);
    if (ext == ".xyz") {
      EXPECT_EQ(slurp(dir.file("out.xyz")), slurp(dir.file("points.xyz")));  // the same text
    }
  }
}

// A drag with a stray at 1e5, 1e10 or 1e22 (each set apart: AFarStrayStaysWhereItIsAtAnyDistance): the
// fixed points come back bit for bit, the moved ones within 1e-9 of the shape's size (double
// input) or one ulp (float input) of the deformation computed here in double.
TEST(Precision, StraysDoNotCostTheOtherPointsTheirPrecision) {
  TempDir dir;
  const double size = std::sqrt(2.0) * 2.9;  // the grid's diagonal, without its stray
  for (const double far : {1e5, 1e10, 1e22}) {
    for (const bool as_double : {true, false}) {
      SCOPED_TRACE("stray at " + shortest(far, false) + (as_double ? ", double" : ", float"));
      const auto pts = grid({{0, far, 0}});
      writePly(dir.file("in.ply"), pts, as_double);
      for (const bool multires : {false, true})
        for (const hgd::Blend blend : {hgd::Blend::Rotation, hgd::Blend::Linear}) {
          SCOPED_TRACE(multires ? "multi-resolution" : "full resolution");
          const Compared c =
              deformAndCompare(dir.file("in.ply"), kGridScenario, dir.file("out.ply"), blend, multires);
          EXPECT_GT(c.moved, 400u);
          EXPECT_GT(c.unmoved, 50u);
          EXPECT_EQ(c.fixed_changed, 0u);
          EXPECT_EQ(c.unmoved_changed, 0u);
          // The issue asks for 1e-9 of the size; measured 1.3e-15 on the grid: double rounding.
          if (as_double)
            EXPECT_LE(c.max_moved_error, 1e-10 * size) << c.max_moved_error;
          else  // measured 0.5 on the grid (1 on a stray at 1e5 when it was deformed)
            EXPECT_LE(c.max_float_ulps, 1.0 + 1e-9) << c.max_float_ulps;
          EXPECT_LE(c.max_float_path, 1e-5 * size) << c.max_float_path;  // float rounding
        }
    }
  }
}

// A survey patch: 20 m x 20 m at (5e5, 5e6, 120), 1 mm bumps, 0.25 m spacing, with a scanner's
// no-return point at (0, 0, 0). Before, the frame's centre sat half-way to the origin and a float
// there has a quarter-metre step: the bumps were gone. Now the patch deforms as the same patch
// placed near the origin does (its no-return point as far off), to well under a millimetre, and
// what is written agrees with the double reference.
TEST(Precision, GeoreferencedPatchKeepsMillimetresThroughADrag) {
  TempDir dir;
  std::vector<Eigen::Vector3d> rel;  // relative to (5e5, 5e6, 0)
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> bump(-0.001, 0.001);
  for (int i = 0; i <= 80; ++i)
    for (int j = 0; j <= 80; ++j) rel.emplace_back(0.25 * i, 0.25 * j, 120 + bump(rng));
  std::shuffle(rel.begin(), rel.end(), rng);
  rel.emplace_back(-5e5, -5e6, 0);  // the no-return point
  const Eigen::Vector3d geo(5e5, 5e6, 0);
  std::vector<Eigen::Vector3d> far = rel;
  for (auto& p : far) p += geo;
  writePly(dir.file("survey.ply"), far, true);
  // In the survey the no-return point is at exactly (0, 0, 0) and set apart (issue 48); its twin
  // near the origin would be a stray of the patch, deformed with it: left out.
  writePly(dir.file("local.ply"), std::vector<Eigen::Vector3d>(rel.begin(), rel.end() - 1), true);
  auto scenarioAt = [](const Eigen::Vector3d& o) {
    auto v = [&](double x, double y, double z) {
      return "[" + shortest(o.x() + x, false) + ", " + shortest(o.y() + y, false) + ", " +
             shortest(z, false) + "]";
    };
    return std::string(R"({"format": "hgdeform-scenario/1", "clusters": 8,)") +
           R"("fixed": [ {"box": {"min": )" + v(-10, -10, 100) + R"(, "max": )" + v(4, 30, 140) +
           R"(}} ], "manipulated": {"box": {"min": )" + v(17, -10, 100) + R"(, "max": )" + v(30, 30, 140) +
           R"(}}, "move": {"drag": {"from": )" + v(20, 10, 120) + R"(, "to": )" + v(21, 10, 122) + "}}}";
  };
  const Compared c = deformAndCompare(dir.file("survey.ply"), scenarioAt(geo), dir.file("out.ply"));
  EXPECT_GT(c.moved, 2000u);
  EXPECT_EQ(c.fixed_changed, 0u);
  EXPECT_EQ(c.unmoved_changed, 0u);
  EXPECT_LE(c.max_moved_error, 1e-9 * 28.3) << c.max_moved_error;  // measured 1.9e-9 m (6.6e-11)
  EXPECT_LE(c.max_float_path, 1e-5 * 28.3) << c.max_float_path;
  deformAndCompare(dir.file("local.ply"), scenarioAt(Eigen::Vector3d::Zero()), dir.file("local_out.ply"));

  const hgd::Shape a = hgd::readShape(dir.file("survey.ply")), b = hgd::readShape(dir.file("out.ply"));
  const hgd::Shape la = hgd::readShape(dir.file("local.ply")), lb = hgd::readShape(dir.file("local_out.ply"));
  double worst = 0, moved = 0;
  for (std::size_t i = 0; i + 1 < a.size(); ++i) {  // the no-return point aside
    const Eigen::Vector3d d_far = valueOf(b, i) - valueOf(a, i), d_local = valueOf(lb, i) - valueOf(la, i);
    worst = std::max(worst, (d_far - d_local).cwiseAbs().maxCoeff());
    moved = std::max(moved, d_local.norm());
  }
  std::printf("  georeferenced vs near the origin: displacements differ by at most %.3g m (largest %.3g m)\n",
              worst, moved);
  EXPECT_GT(moved, 1.0);
  EXPECT_LT(worst, 1e-8);  // measured 4.7e-10 m (double rounding at 5e6)
}

// Issue 48: a georeferenced patch with 60% "no return" points at (0, 0, 0) (as some scanners
// write them) ended 1.96 m off with 61 clusters instead of 18: the zeros set the frame's origin
// and size. Exact zeros far from the shape are set apart, said, and the patch deforms exactly
// as it does without them, whatever their share.
TEST(Precision, NoReturnZerosDoNotMoveTheFrame) {
  TempDir dir;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> bump(-0.001, 0.001);
  const Eigen::Vector3d geo(5e5, 5e6, 0);
  std::vector<Eigen::Vector3d> patch;
  for (int i = 0; i <= 60; ++i)
    for (int j = 0; j <= 60; ++j) patch.push_back(geo + Eigen::Vector3d(0.25 * i, 0.25 * j, 120 + bump(rng)));
  std::shuffle(patch.begin(), patch.end(), rng);
  writePly(dir.file("clean.ply"), patch, true);
  const std::string scenario = [&] {
    auto v = [&](double x, double y, double z) {
      return "[" + shortest(geo.x() + x, false) + ", " + shortest(geo.y() + y, false) + ", " +
             shortest(z, false) + "]";
    };
    return std::string(R"({"format": "hgdeform-scenario/1", "clusters": 8,)") +
           R"("fixed": [ {"box": {"min": )" + v(-10, -10, 100) + R"(, "max": )" + v(3, 30, 140) +
           R"(}} ], "manipulated": {"box": {"min": )" + v(12, -10, 100) + R"(, "max": )" + v(30, 30, 140) +
           R"(}}, "move": {"drag": {"from": )" + v(14, 7, 120) + R"(, "to": )" + v(15, 7, 122) + "}}}";
  }();
  writeText(dir.file("s.json"), scenario);
  const auto run = [&](const std::string& in, const std::string& out) {
    const hgdtest::CommandResult r =
        hgdtest::shell(hgdtest::quote(HGD_TOOL) + " deform " + hgdtest::quote(in) + " -s " +
                       hgdtest::quote(dir.file("s.json")) + " -o " + hgdtest::quote(out) + " -q --report " +
                       hgdtest::quote(out + ".json"));
    EXPECT_EQ(r.code, 0) << r.err;
    return r.err;
  };
  run(dir.file("clean.ply"), dir.file("clean_out.ply"));
  const hgd::Shape clean = hgd::readShape(dir.file("clean_out.ply"));
  for (const double share : {0.01, 0.3, 0.6}) {
    std::vector<Eigen::Vector3d> pts;
    std::vector<int> of;  // per point: its row in the clean patch, or -1 for a zero
    std::bernoulli_distribution zero(share);
    for (std::size_t k = 0; k < patch.size();) {
      if (zero(rng)) {
        pts.emplace_back(0, 0, 0);
        of.push_back(-1);
      } else {
        pts.push_back(patch[k]);
        of.push_back(static_cast<int>(k++));
      }
    }
    writePly(dir.file("zeros.ply"), pts, true);
    const std::string err = run(dir.file("zeros.ply"), dir.file("zeros_out.ply"));
    EXPECT_TRUE(hgdtest::contains(err, "at exactly (0, 0, 0)")) << err;
    const hgd::Shape out = hgd::readShape(dir.file("zeros_out.ply"));
    std::size_t differ = 0, zeros_moved = 0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const Eigen::Vector3d p = valueOf(out, i);
      if (of[i] < 0)
        zeros_moved += !(p.array() == 0).all();
      else
        differ += p != valueOf(clean, static_cast<std::size_t>(of[i]));
    }
    EXPECT_EQ(zeros_moved, 0u) << share;
    EXPECT_EQ(differ, 0u) << share << ": the patch deformed otherwise than without the zeros";
  }
}

// A frame move far out (translate 1e12, inside the allowed range) on a double file: the handle
// moves rigidly to within double rounding at 1e12 (1.2e-4), not 4,096 units.
TEST(Precision, HugeTranslationKeepsTheHandleRigid) {
  TempDir dir;
  const auto pts = grid({});
  writePly(dir.file("in.ply"), pts, true);
  const std::string scenario = R"({
    "format": "hgdeform-scenario/1",
    "fixed": [ {"box": {"min": [-1, -1, -1], "max": [4, 0.35, 1]}} ],
    "manipulated": {"box": {"min": [-1, 2.55, -1], "max": [4, 3, 1]}},
    "move": {"frame": {"translate": [1e12, 0, 0]}}
  })";
  writeText(dir.file("s.json"), scenario);
  const CommandResult r2 = shell(quote(HGD_TOOL) + " deform " + quote(dir.file("in.ply")) + " -s " +
                                 quote(dir.file("s.json")) + " -o " + quote(dir.file("out.ply")));
  ASSERT_EQ(r2.code, 0) << r2.err;
  const hgd::Shape in = hgd::readShape(dir.file("in.ply")), out = hgd::readShape(dir.file("out.ply"));
  double worst = 0, worst_fixed = 0;
  for (std::size_t i = 0; i < in.size(); ++i) {
    const Eigen::Vector3d a = valueOf(in, i), b = valueOf(out, i);
    if (a.y() >= 2.55) worst = std::max(worst, (b - a - Eigen::Vector3d(1e12, 0, 0)).cwiseAbs().maxCoeff());
    if (a.y() <= 0.35) worst_fixed = std::max(worst_fixed, (b - a).cwiseAbs().maxCoeff());
  }
  std::printf("  handle off the exact translation by at most %.3g\n", worst);
  EXPECT_LE(worst, 2.5e-4) << worst;
  EXPECT_EQ(worst_fixed, 0.0);
}

// One stray far off a 2.9-unit grid (a bad return), at any distance from 20 to 3e5 times the
// grid's size: it stays where it is, bit for bit, said in a warning, and the other points come
// out as the grid without it does. Before (issue 48), from 1e2 units on it turned with its
// nearest cluster (flung 66 to 653,000 units by this drag) and the others moved by up to 0.8% of
// the drag; only from a million sizes was it set apart.
TEST(Precision, AFarStrayStaysWhereItIsAtAnyDistance) {
  TempDir dir;
  const std::vector<Eigen::Vector3d> clean = grid({});
  writePly(dir.file("clean.ply"), clean, true);
  const auto deform = [&](const std::string& in, const std::string& out) {
    hgd::ScenarioRunner r = hgd::ScenarioRunner::read(in);
    r.setScenario(hgd::parseScenario(kGridScenario, "s.json"));
    r.applyMoves();
    r.write(out);
    return std::make_pair(r.geometry().far_points, r.report().warnings);
  };
  deform(dir.file("clean.ply"), dir.file("clean_out.ply"));
  const hgd::Shape want = hgd::readShape(dir.file("clean_out.ply"));
  const std::size_t at = clean.size() / 2;  // where grid() puts the stray
  for (const double far : {60.0, 1e2, 1e3, 1e4, 1e5, 9.9e5}) {
    SCOPED_TRACE("stray at y = " + shortest(far, false));
    const Eigen::Vector3d stray(1.5, far, 0.02);
    writePly(dir.file("in.ply"), grid({stray}), true);
    const auto [apart, warnings] = deform(dir.file("in.ply"), dir.file("out.ply"));
    EXPECT_EQ(apart, 1u);
    bool said = false;
    for (const auto& w : warnings) said = said || contains(w, "1 point lies more than");
    EXPECT_TRUE(said);
    const hgd::Shape got = hgd::readShape(dir.file("out.ply"));
    ASSERT_EQ(got.size(), clean.size() + 1);
    const Eigen::Vector3d s = valueOf(got, at);
    EXPECT_TRUE(sameBits(s.x(), stray.x()) && sameBits(s.y(), stray.y()) && sameBits(s.z(), stray.z()))
        << s.transpose();
    double worst = 0;
    for (std::size_t i = 0; i < clean.size(); ++i)
      worst = std::max(worst, (valueOf(got, i < at ? i : i + 1) - valueOf(want, i)).cwiseAbs().maxCoeff());
    // The grid's own points as without the stray: measured 0 (the stray never enters the build).
    EXPECT_LE(worst, 1e-12) << worst;
  }
  // Five points together as far off (a small second object, a part that reaches out) are not
  // strays: they are deformed with the shape (a first version set any few far points apart).
  std::vector<Eigen::Vector3d> group;
  for (int k = 0; k < 5; ++k) group.emplace_back(1.5 + 0.05 * k, 100.0, 0.02 * k);
  writePly(dir.file("group.ply"), grid(group), true);
  const hgd::ScenarioRunner r = hgd::ScenarioRunner::read(dir.file("group.ply"));
  EXPECT_EQ(r.geometry().far_points, 0u);
}

// 50 runs with points at 1e22 among a 3-unit grid (a corrupt block's values): set apart, said,
// never a crash; and a cloud whose bulk spans 1e22 units is refused with a message naming it.
TEST(Precision, PointsNear1e22NeverCrash) {
  TempDir dir;
  std::vector<Eigen::Vector3d> strays;
  for (int k = 0; k < 5; ++k) strays.emplace_back(k % 2 ? 1e22 : -3e21, 1e20 * k, k % 3 ? 7e29 : 1);
  writePly(dir.file("in.ply"), grid(strays), false);
  for (int run = 0; run < 50; ++run) {
    hgd::ScenarioRunner r = hgd::ScenarioRunner::read(dir.file("in.ply"));
    EXPECT_EQ(r.geometry().far_points, 5u);
    r.setScenario(hgd::parseScenario(kGridScenario, "s.json"));
    r.applyMoves();
    const hgd::DeformReport rep = r.report();
    bool said = false;
    for (const auto& w : rep.warnings) said = said || contains(w, "5 points lie more than");
    EXPECT_TRUE(said);
    for (const auto& p : r.deformer().deformedPoints()) ASSERT_TRUE(p.allFinite());
  }
  // A small cloud (7 x 7 and one 1e22 point): the point is set apart, the cloud not refused.
  {
    std::vector<Eigen::Vector3f> small;
    for (int i = 0; i < 7; ++i)
      for (int j = 0; j < 7; ++j) small.emplace_back(0.1f * i, 0.1f * j, 0.0f);
    small.emplace_back(1e22f, 0.0f, 0.0f);
    const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::cloudShape(small, {}));
    EXPECT_EQ(g.far_points, 1u);
    EXPECT_EQ(g.size(), 49u);
  }
  // Most of the cloud garbage: refused, naming the file.
  std::vector<Eigen::Vector3d> bad;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int k = 0; k < 2000; ++k) bad.emplace_back(u(rng) * 1e22, u(rng) * 1e22, u(rng));
  writePly(dir.file("bad.ply"), grid(bad), false);
  try {
    hgd::ScenarioRunner::read(dir.file("bad.ply"));
    FAIL() << "a cloud spanning 1e22 units was accepted";
  } catch (const std::exception& e) {
    EXPECT_TRUE(contains(e.what(), dir.file("bad.ply"))) << e.what();
    EXPECT_TRUE(contains(e.what(), "corrupt")) << e.what();
  }
  const CommandResult r = shell(quote(HGD_TOOL) + " deform " + quote(dir.file("bad.ply")) + " -s " +
                                quote(dir.file("s.json")) + " -o " + quote(dir.file("o.ply")));
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.code, -1);  // not killed by a signal
}

// uchar coordinates dragged past 255 and below 0 were written as 255 and 0. Now the property is
// widened to float, with a warning, and the values are what the deformation gives.
TEST(Precision, IntegerCoordinatesAreWidenedNotClipped) {
  TempDir dir;
  std::string s =
      "ply\nformat ascii 1.0\nelement vertex 900\nproperty uchar x\nproperty uchar y\nproperty uchar z\n"
      "end_header\n";
  for (int i = 0; i < 30; ++i)
    for (int j = 0; j < 30; ++j)
      s += std::to_string(8 * i) + " " + std::to_string(8 * j) + " " +
           std::to_string(100 + (i * 7 + j * 3) % 5) + "\n";
  writeText(dir.file("in.ply"), s);
  writeText(dir.file("s.json"), R"({
    "format": "hgdeform-scenario/1",
    "fixed": [ {"box": {"min": [-1, -1, 0], "max": [255, 20, 255]}} ],
    "manipulated": {"box": {"min": [-1, 210, 0], "max": [255, 240, 255]}},
    "move": {"frame": {"translate": [-60, 70, 0]}}
  })");
  const CommandResult r =
      shell(quote(HGD_TOOL) + " deform " + quote(dir.file("in.ply")) + " -s " + quote(dir.file("s.json")) +
            " -o " + quote(dir.file("out.ply")) + " --report " + quote(dir.file("r.json")));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(contains(r.err, "integers")) << r.err;
  EXPECT_TRUE(contains(slurp(dir.file("r.json")), "integers"));
  const hgd::Shape out = hgd::readShape(dir.file("out.ply"));
  const hgd::XyzFields f = hgd::findXyzFields(out.cloud);
  EXPECT_EQ(out.cloud.fields[static_cast<std::size_t>(f.y)].datatype, pcl::PCLPointField::FLOAT32);
  double max_y = -1e9, min_x = 1e9;
  for (std::size_t i = 0; i < out.size(); ++i) {
    max_y = std::max(max_y, valueOf(out, i).y());
    min_x = std::min(min_x, valueOf(out, i).x());
  }
  EXPECT_GT(max_y, 300.0);  // 232 + 70 on the handle
  EXPECT_LT(min_x, -50.0);  // 0 - 60 on the handle

  // 32-bit integers (y = 20,000,000 + 8 j: more digits than a float holds) beside float x and
  // short z: each integer field is widened on its own, y to double, and the fixed points' values
  // come back exactly.
  std::string t =
      "ply\nformat ascii 1.0\nelement vertex 900\nproperty float x\nproperty int y\nproperty short z\n"
      "end_header\n";
  for (int i = 0; i < 30; ++i)
    for (int j = 0; j < 30; ++j)
      t += std::to_string(8 * i) + " " + std::to_string(20000000 + 8 * j) + " " +
           std::to_string(100 + (i * 7 + j * 3) % 5) + "\n";
  writeText(dir.file("in32.ply"), t);
  writeText(dir.file("s32.json"), R"({
    "format": "hgdeform-scenario/1",
    "fixed": [ {"box": {"min": [-1, 19999999, 0], "max": [255, 20000020, 255]}} ],
    "manipulated": {"box": {"min": [-1, 20000210, 0], "max": [255, 20000240, 255]}},
    "move": {"frame": {"translate": [-60, 70, 0.5]}}
  })");
  const CommandResult r32 = shell(quote(HGD_TOOL) + " deform " + quote(dir.file("in32.ply")) + " -s " +
                                  quote(dir.file("s32.json")) + " -o " + quote(dir.file("out32.ply")));
  ASSERT_EQ(r32.code, 0) << r32.err;
  const hgd::Shape a32 = hgd::readShape(dir.file("in32.ply")), b32 = hgd::readShape(dir.file("out32.ply"));
  const hgd::XyzFields f32 = hgd::findXyzFields(b32.cloud);
  EXPECT_EQ(b32.cloud.fields[static_cast<std::size_t>(f32.x)].datatype, pcl::PCLPointField::FLOAT32);
  EXPECT_EQ(b32.cloud.fields[static_cast<std::size_t>(f32.y)].datatype, pcl::PCLPointField::FLOAT64);
  EXPECT_EQ(b32.cloud.fields[static_cast<std::size_t>(f32.z)].datatype, pcl::PCLPointField::FLOAT32);
  std::size_t fixed_changed = 0, handle_off = 0;
  for (std::size_t i = 0; i < a32.size(); ++i) {
    const Eigen::Vector3d u = valueOf(a32, i), v = valueOf(b32, i);
    if (u.y() <= 20000016) fixed_changed += u != v;
    if (u.y() >= 20000216)
      handle_off += std::abs(v.y() - u.y() - 70) > 1e-6 || std::abs(v.z() - u.z() - 0.5) > 1e-4;
  }
  EXPECT_EQ(fixed_changed, 0u);
  EXPECT_EQ(handle_off, 0u);
}

// Text files come back as the same text where nothing moved: a column written with six decimals
// ("1.500000") keeps them, one written as "1.0" keeps its ".0", in XYZ, OBJ, ascii PLY and PCD.
// Before, values were printed in their shortest spelling ("1.5", "1").
TEST(Precision, UnmovedTextComesBackAsSpelt) {
  TempDir dir;
  const auto pts = grid({});
  auto fixed6 = [](double v) {
    char b[64];
    std::snprintf(b, sizeof b, "%.6f", v);
    return std::string(b);
  };
  auto pyRepr = [](double v) {  // Python's repr: shortest, with ".0" on whole numbers
    std::string s = shortest(v, false);
    if (s.find_first_of(".e") == std::string::npos) s += ".0";
    return s;
  };
  std::string xyz, obj, ply, pcd;
  ply = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(pts.size()) +
        "\nproperty double x\nproperty double y\nproperty double z\nend_header\n";
  pcd =
      "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE 8 8 8\nTYPE F F F\n"
      "COUNT 1 1 1\nWIDTH " +
      std::to_string(pts.size()) + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " +
      std::to_string(pts.size()) + "\nDATA ascii\n";
  for (const auto& p : pts) {
    xyz += fixed6(p.x()) + " " + fixed6(p.y()) + " " + fixed6(p.z()) + "\n";
    obj += "v " + fixed6(p.x()) + " " + fixed6(p.y()) + " " + fixed6(p.z()) + "\n";
    ply += pyRepr(p.x()) + " " + pyRepr(p.y()) + " " + pyRepr(p.z()) + "\n";
    pcd += fixed6(p.x()) + " " + pyRepr(p.y()) + " " + fixed6(p.z()) + "\n";
  }
  writeText(dir.file("in.xyz"), xyz);
  writeText(dir.file("in.obj"), obj);
  writeText(dir.file("in.ply"), ply);
  writeText(dir.file("in.pcd"), pcd);
  writeText(dir.file("s.json"), kGridScenarioNoMove);
  for (const std::string ext : {".xyz", ".obj", ".ply", ".pcd"}) {
    SCOPED_TRACE(ext);
    const CommandResult r =
        shell(quote(HGD_TOOL) + " deform " + quote(dir.file("in" + ext)) + " -s " +
              quote(dir.file("s.json")) + " -o " + quote(dir.file("out" + ext)) + " --ascii");
    ASSERT_EQ(r.code, 0) << r.err;
    const std::string a = slurp(dir.file("in" + ext)), b = slurp(dir.file("out" + ext));
    // Every data line of the input is in the output, the same text.
    std::istringstream in(a), out(b);
    std::vector<std::string> la, lb;
    for (std::string l; std::getline(in, l);) la.push_back(l);
    for (std::string l; std::getline(out, l);) lb.push_back(l);
    ASSERT_GE(lb.size(), pts.size());
    std::size_t differ = 0;
    for (std::size_t k = 0; k < pts.size(); ++k)
      differ += la[la.size() - pts.size() + k] != lb[lb.size() - pts.size() + k];
    EXPECT_EQ(differ, 0u) << "first output line: " << lb[lb.size() - pts.size()];
  }
}
