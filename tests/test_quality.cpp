// Shape quality at default settings: local distortion (support/quality.h, the bench's measure)
// against values measured now (a regression of a few percent fails), against CGAL's ARAP run
// to convergence on the same mesh and move where this build has CGAL, and the independence of
// a branch no handle is on.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "hgdeform/deformer/deformer.h"
#include "hgdeform/io/io.h"
#include "support/arap.h"
#include "support/quality.h"
#include "support/shapes.h"
#include "test_util.h"

// ARAP to convergence takes a minute under the sanitizers: there, the stored figures alone.
#ifdef HGD_TEST_ASAN
constexpr bool kRunArap = false;
#else
constexpr bool kRunArap = true;
#endif

namespace {

struct Outcome {
  double distortion = 0, other = 0, arap = 0, arap_other = 0;
  double legs = 0, arap_legs = 0;  ///< the largest length change of the planted legs (unsigned)
};

// The quadruped's three planted legs (the fixed feet 0, 1 and 3), foot to top, by file index.
std::vector<hgd::quality::Part> plantedLegs(const hgd::Shape& q) {
  std::vector<hgd::quality::Part> legs;
  for (const int leg : {0, 1, 3})
    legs.push_back({hgd::shapes::quadrupedFoot(q, leg), hgd::shapes::quadrupedLegTop(q, leg)});
  return legs;
}

// Deforms `shape` (handles by file index) with default options: the manipulated handle
// translated by `move` exactly (a frame move); with `arap`, CGAL's ARAP too, on the same
// handles and targets, iterated until its distortion settles.
Outcome deformAndMeasure(const hgd::Shape& shape, const std::vector<std::vector<int>>& fixed_file,
                         const std::vector<int>& manipulated_file, const Eigen::Vector3d& move,
                         const std::vector<int>& other_file, bool arap,
                         const hgd::DeformOptions& options = hgd::DeformOptions{},
                         const std::vector<hgd::quality::Part>& legs_file = {}) {
  const hgd::Geometry g = hgd::extractGeometry(shape);
  const auto ours = [&](std::vector<int> file) {
    for (int& i : file) i = g.finite_index[static_cast<std::size_t>(i)];
    return file;
  };
  hgd::Handles h;
  for (const auto& f : fixed_file) h.fixed.push_back(ours(f));
  h.manipulated = ours(manipulated_file);
  const std::vector<int> other = ours(other_file);
  std::vector<hgd::quality::Part> legs;
  for (const auto& l : legs_file) legs.push_back({ours(l.a), ours(l.b)});
  std::vector<Eigen::Vector3d> rest(g.size()), deformed(g.size());
  for (std::size_t i = 0; i < g.size(); ++i) rest[i] = g.world(i);
  hgd::Deformer d(g, h, options);
  d.setHandleTransform(Eigen::Affine3d(Eigen::Translation3d(move)));
  for (std::size_t i = 0; i < g.size(); ++i) deformed[i] = d.deformedWorld(i);
  // The handle went where it was sent: the measure below compares like with like.
  for (const int i : h.manipulated)
    EXPECT_LT((deformed[static_cast<std::size_t>(i)] - rest[static_cast<std::size_t>(i)] - move).norm(),
              1e-4 * move.norm());
  Outcome out;
  out.distortion = hgd::quality::localDistortion(rest, deformed);
  if (!other.empty()) out.other = hgd::quality::meanDisplacement(rest, deformed, other) / move.norm();
  out.legs = hgd::quality::largestLengthChange(rest, deformed, legs);
  if (arap && hgdbench::haveCgalArap()) {
    const std::vector<std::array<int, 3>> triangles = hgdbench::fanTriangles(g.faces);
    std::vector<int> all_fixed;
    for (const auto& f : h.fixed) all_fixed.insert(all_fixed.end(), f.begin(), f.end());
    const auto r = hgdbench::cgalArapConverged(rest, triangles, all_fixed, h.manipulated, move, 0, 800, 25,
                                               hgd::quality::distortionSettles(rest, 0.005, &out.arap));
    if (!other.empty())
      out.arap_other = hgd::quality::meanDisplacement(rest, r.positions, other) / move.norm();
    out.arap_legs = hgd::quality::largestLengthChange(rest, r.positions, legs);
    std::printf("ARAP: %d iterations%s\n", r.iterations, r.converged ? "" : " (not settled)");
  }
  return out;
}

// The measure itself, against values computed by hand: a rigid motion has none, a uniform
// scale by s has |s - 1|, a shear of the plane y' = y + a x gives more the larger a is.
TEST(Quality, DistortionMeasureIsZeroForRigidAndScaleForScale) {
  std::vector<Eigen::Vector3d> rest;
  for (int i = 0; i < 12; ++i)
    for (int j = 0; j < 12; ++j) rest.emplace_back(0.1 * i, 0.1 * j, 0.01 * ((i * 7 + j * 3) % 5));
  const Eigen::Affine3d rigid =
      Eigen::Translation3d(1, 2, 3) * Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized());
  std::vector<Eigen::Vector3d> moved, scaled, sheared;
  for (const auto& p : rest) {
    moved.push_back(rigid * p);
    scaled.push_back(1.1 * p);
    sheared.emplace_back(p.x(), p.y() + 0.2 * p.x(), p.z());
  }
  EXPECT_LT(hgd::quality::localDistortion(rest, moved), 1e-12);
  EXPECT_NEAR(hgd::quality::localDistortion(rest, scaled), 0.1, 1e-9);
  const double shear = hgd::quality::localDistortion(rest, sheared);
  EXPECT_GT(shear, 0.02);
  EXPECT_LT(shear, 0.2);
}

// The length measure against hand-computed values: two rings 2 apart; a rigid motion keeps
// the length, a uniform scale by s changes it by s - 1, one ring slid 0.1 along the axis by
// 0.05, and slid 0.5 across it by sqrt(4.25) / 2 - 1.
TEST(Quality, LengthChangeIsThatOfTheCentroidsDistance) {
  std::vector<Eigen::Vector3d> rest;
  std::vector<int> a, b;
  for (int k = 0; k < 24; ++k) {
    const double t = 2 * M_PI * k / 24;
    a.push_back(static_cast<int>(rest.size()));
    rest.emplace_back(0.3 * std::cos(t), 0, 0.3 * std::sin(t));
    b.push_back(static_cast<int>(rest.size()));
    rest.emplace_back(0.3 * std::cos(t), -2, 0.3 * std::sin(t));
  }
  const Eigen::Affine3d rigid =
      Eigen::Translation3d(1, 2, 3) * Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized());
  std::vector<Eigen::Vector3d> moved, scaled, along = rest, across = rest;
  for (const auto& p : rest) {
    moved.push_back(rigid * p);
    scaled.push_back(1.1 * p);
  }
  for (const int i : b) {
    along[static_cast<std::size_t>(i)].y() -= 0.1;
    across[static_cast<std::size_t>(i)].x() += 0.5;
  }
  EXPECT_NEAR(hgd::quality::lengthChange(rest, moved, a, b), 0, 1e-12);
  EXPECT_NEAR(hgd::quality::lengthChange(rest, scaled, a, b), 0.1, 1e-12);
  EXPECT_NEAR(hgd::quality::lengthChange(rest, along, a, b), 0.05, 1e-12);
  EXPECT_NEAR(hgd::quality::lengthChange(rest, across, a, b), std::sqrt(4.25) / 2 - 1, 1e-12);
  EXPECT_NEAR(hgd::quality::lengthChange(rest, along, b, a), 0.05, 1e-12);  // either end first
}

// A quadruped, three feet fixed, the right hind foot moved back and up: local distortion no
// worse than measured, and the other hind shin (no handle on its leg) nearly still.
TEST(Quality, QuadrupedDistortionAndTheOtherLeg) {
  const hgd::Shape q = hgd::shapes::quadruped(0.03f);
  const Outcome o = deformAndMeasure(
      q,
      {hgd::shapes::quadrupedFoot(q, 0), hgd::shapes::quadrupedFoot(q, 1), hgd::shapes::quadrupedFoot(q, 3)},
      hgd::shapes::quadrupedFoot(q, 2), Eigen::Vector3d(-0.25, 0.2, 0), hgd::shapes::quadrupedShin(q, 3),
      kRunArap, hgd::DeformOptions{}, plantedLegs(q));
  std::printf(
      "quadruped (%u vertices): distortion %.5f, other hind shin %.2f%% of the move, planted legs' length "
      "%.2f%%; ARAP %.5f, %.2f%%, %.2f%%\n",
      q.cloud.width, o.distortion, 100 * o.other, 100 * o.legs, o.arap, 100 * o.arap_other,
      100 * o.arap_legs);
  // Measured 0.01440 and 5.49%; bounds 2% and 3% above. CGAL's ARAP, settled: 0.01180 and
  // 2.60% (175 iterations), 1.22x less distortion than ours (bound 1.25x). With
  // DeformOptions::iso_rigidity = 2: 0.01396 and 5.18%.
  EXPECT_LT(o.distortion, 0.01469);
  EXPECT_LT(o.other, 0.0566);
  // The planted legs (foot to top) lengthen 5.52% as the body rises (bound 3% above); ARAP's
  // 1.36%: they tilt about the feet instead (bound 1.5%: the measure names the stretch, not
  // the turn).
  EXPECT_LT(o.legs, 0.0569);
  if (o.arap > 0) {
    EXPECT_LT(o.distortion, 1.25 * o.arap);
    EXPECT_LT(o.arap_legs, 0.015);
  }
}

// The opt-in reweighted E_Prop (GaussNewtonOptions::reweight_rounds; 32 isovalues, 8 rounds,
// as the bench reports it) on the same quadruped and move: the bending gathers at the hip and
// near the foot, as ARAP's does, so the distortion falls below ARAP's and the other leg stays.
TEST(Quality, ReweightedPropBendsTheQuadrupedLikeArap) {
  const hgd::Shape q = hgd::shapes::quadruped(0.03f);
  hgd::DeformOptions options;
  options.clusters.isovalues = 32;
  options.gauss_newton.reweight_rounds = 8;
  const Outcome o = deformAndMeasure(
      q,
      {hgd::shapes::quadrupedFoot(q, 0), hgd::shapes::quadrupedFoot(q, 1), hgd::shapes::quadrupedFoot(q, 3)},
      hgd::shapes::quadrupedFoot(q, 2), Eigen::Vector3d(-0.25, 0.2, 0), hgd::shapes::quadrupedShin(q, 3),
      kRunArap, options, plantedLegs(q));
  std::printf(
      "reweighted quadruped: distortion %.5f, other hind shin %.2f%% of the move, planted legs' length "
      "%.2f%%; ARAP %.5f, %.2f%%, %.2f%%\n",
      o.distortion, 100 * o.other, 100 * o.legs, o.arap, 100 * o.arap_other, 100 * o.arap_legs);
  // Measured 0.00809 and 0.14% (the default: 0.01440 and 5.49%); bounds 3% above and 0.5% (the
  // issue's goal is 1.5%). CGAL's ARAP, settled: 0.01180, so 0.69x ARAP (bound 0.75x).
  EXPECT_LT(o.distortion, 0.00833);
  EXPECT_LT(o.other, 0.005);
  // The planted legs keep their length: 0.14% (the default 5.52%); bound 0.5% (the goal is 1%).
  EXPECT_LT(o.legs, 0.005);
  if (o.arap > 0) {
    EXPECT_LT(o.distortion, 0.75 * o.arap);
  }
}

// The Armadillo of the shared datasets (skipped without it): feet fixed, the top of the head
// moved by a tenth of the diagonal, as the bench does; against CGAL's ARAP on the same move.
TEST(Quality, ArmadilloDistortion) {
  const std::string path = std::string(HGD_SHARED_DATA_DIR) + "/meshes/armadillo_49990.ply";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "no " << path;
  const hgd::Shape a = hgd::readShape(path);
  const hgd::Geometry g = hgd::extractGeometry(a);
  Eigen::AlignedBox3d box;
  for (std::size_t i = 0; i < g.size(); ++i) box.extend(g.world(i));
  std::vector<int> fixed, handle;
  const double height = box.sizes().y();
  for (std::size_t i = 0; i < g.size(); ++i) {
    const double y = g.world(i).y();
    if (y < box.min().y() + 0.06 * height) fixed.push_back(g.raw_index[i]);
    if (y > box.max().y() - 0.08 * height) handle.push_back(g.raw_index[i]);
  }
  const Outcome o =
      deformAndMeasure(a, {fixed}, handle, Eigen::Vector3d(0, 0, 0.1 * box.diagonal().norm()), {}, kRunArap);
  std::printf("armadillo: distortion %.5f; ARAP %.5f\n", o.distortion, o.arap);
  // Measured 0.01490 (0.01510 while every mesh edge joined the kNN graph; 0.01419 in 0.1.x,
  // before the real-scan work; 0.01449 with DeformOptions::iso_rigidity = 2); bound 2% above.
  // CGAL's ARAP, settled: 0.00970 (225 iterations), 1.54x less than ours (bound 1.57x).
  EXPECT_LT(o.distortion, 0.0152);
  if (o.arap > 0) {
    EXPECT_LT(o.distortion, 1.57 * o.arap);
  }
}

}  // namespace
