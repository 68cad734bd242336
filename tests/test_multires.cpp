// The multi-resolution build (docs/method.md §7) against the full-resolution one, its reference:
// the same shapes, handles and drag through both, on clouds shaped like resampled scans (random
// order, random normal signs, noise, strays) and on a shape with a piece no handle reaches.
#include <gtest/gtest.h>
#include <malloc.h>
#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <numeric>
#include <random>
#include <set>

#include "../src/multires/prolong_labels.h"  // the route prolongInterpolation replaced
#include "hgdeform/cluster/clustering.h"
#include "hgdeform/deformer/deformer.h"
#include "hgdeform/field/harmonic_field.h"
#include "hgdeform/graph/neighbor_graph.h"
#include "hgdeform/io/geometry.h"
#include "hgdeform/multires/multires.h"
#include "support/shapes.h"
#include "support/threads.h"
#include "test_util.h"

namespace {

using hgd::Deformer;
using hgd::DeformOptions;
using hgdtest::ThreadCount;

DeformOptions fullResolution() {
  DeformOptions o;
  o.multires_above = 0;
  return o;
}

DeformOptions coarse(std::size_t points) {
  DeformOptions o;
  o.multires_above = 1;  // whatever the size
  o.coarse_points = points;
  o.points_per_coarse = 0;  // that many, whatever the size
  return o;
}

struct Errors {
  double phi_max = 0, phi_rms = 0, move_max = 0, move_rms = 0;
};

// φ and the deformed shape of `b` against those of `a` (the reference) over the points where
// `count` holds; displacements as a fraction of the drag.
template <typename Count>
Errors compare(const Deformer& a, const Deformer& b, double drag, Count&& count) {
  Errors e;
  std::size_t n = 0;
  for (std::size_t i = 0; i < a.field().size(); ++i) {
    if (!count(i)) continue;
    ++n;
    const double d = std::abs(static_cast<double>(a.field()[i]) - b.field()[i]);
    e.phi_max = std::max(e.phi_max, d);
    e.phi_rms += d * d;
    const double m = (a.deformedPoints()[i] - b.deformedPoints()[i]).norm() / drag;
    e.move_max = std::max(e.move_max, m);
    e.move_rms += m * m;
  }
  e.phi_rms = std::sqrt(e.phi_rms / static_cast<double>(n));
  e.move_rms = std::sqrt(e.move_rms / static_cast<double>(n));
  return e;
}

// How fast the displacement changes between neighbours (pairs of `graph`, among the points where
// `count` holds): the largest |d_i - d_j| / |x_i - x_j|, and the 99.9th percentile. A build
// whose points move in steps, cell by cell, shows it here.
template <typename Count>
std::pair<double, double> roughness(const hgd::Geometry& g, const Deformer& d,
                                    const hgd::NeighborGraph& graph, Count&& count) {
  std::vector<double> r;
  for (std::size_t i = 0; i < graph.size(); ++i) {
    if (!count(i)) continue;
    const Eigen::Vector3f di = d.deformedPoints()[i] - (*g.points)[i].getVector3fMap();
    for (const int* j = graph.begin(i); j != graph.end(i); ++j) {
      const auto u = static_cast<std::size_t>(*j);
      if (u < i || !count(u)) continue;
      const float dist = ((*g.points)[u].getVector3fMap() - (*g.points)[i].getVector3fMap()).norm();
      if (!(dist > 1e-6f)) continue;
      const Eigen::Vector3f du = d.deformedPoints()[u] - (*g.points)[u].getVector3fMap();
      r.push_back(static_cast<double>((du - di).norm() / dist));
    }
  }
  std::sort(r.begin(), r.end());
  return {r.back(), r[r.size() * 999 / 1000]};
}

// The fork of sampledFork (prongs 0.04 apart, random order, normals in random signs): fixed at
// the base, one prong's tip dragged up and out of the plane. The multi-resolution build must
// give the full field and shape within the bounds below, keep the other prong in place like the
// full build (the gap is about eight coarse cells), and say what it did.
TEST(Multires, FieldAndShapeMatchFullResolutionOnResampledForks) {
  struct Case {
    const char* name;
    double noise, outliers;
  };
  // How near the coarse build comes to the full one depends on the coarse sample: moving the
  // grid's side by 0.06% (a different sizing subset) moved the largest move apart from 0.010 to
  // 0.039 of the drag, and over 17 coarse levels of 13,000 to 17,000 points the largest move
  // apart ranged 0.008-0.082 of the drag (quartiles of the four cases 0.011-0.019, 0.014-0.024,
  // 0.016-0.042) and the median angle between the two builds' normals 0.6-18 degrees. So the
  // bounds are on the median over five levels (14,000 to 16,000 points), the typical agreement,
  // not on one level's luck: measured medians |dphi| max 0.012-0.023 / rms 0.0015-0.003, moves
  // 0.014-0.037 / 0.005-0.010 of the drag, normals (median / 99.9th percentile over the moved
  // points) 3.2-9.0 / 5.2-15 degrees. Bounds: the upper quartile of any case, with margin.
  const Case cases[] = {{"clean", 0, 0},
                        {"noise 0.2% of the diagonal", 0.002, 0},
                        {"1% strays", 0, 0.01},
                        {"noise and strays", 0.002, 0.01}};
  const std::size_t targets[] = {14000, 14500, 15000, 15500, 16000};
  for (const Case& k : cases) {
    SCOPED_TRACE(k.name);
    const hgd::shapes::PointsAndNormals f = hgd::shapes::sampledFork(150000, 5, k.noise, k.outliers);
    const hgd::Shape shape = hgd::shapes::cloudShape(f.p, f.n);
    const hgd::Geometry g = hgd::extractGeometry(shape);
    hgd::Handles h;
    // The geometry keeps its points in a space-filling order: the fork's own points are those
    // the file has first.
    auto surface = [&](std::size_t i) { return g.raw_index[i] < 150000; };
    h.fixed.emplace_back();
    for (std::size_t i = 0; i < g.size(); ++i) {
      const Eigen::Vector3d x = g.world(i);
      if (!surface(i)) continue;
      if (x.x() < 0.4) h.fixed.back().push_back(static_cast<int>(i));
      if (x.x() > 1.15 && x.y() > 0.0 && x.y() < 0.1) h.manipulated.push_back(static_cast<int>(i));
    }
    const Eigen::Vector3d from(1.2, 0.05, 0.0), to(1.2, 0.15, 0.3);
    const double drag = (to - from).norm();
    Deformer full(g, h, fullResolution());
    full.dragTo(from, to);
    // Normals: the file's (random signs) turned with their points as in the full build. The
    // angle to the full build's normal, over the surface points the drag moved (by more than 5%
    // of it): the median and the 99.9th percentile.
    const auto angles = [&](const Deformer& multi) {
      std::vector<double> angle;
      const auto &nf = full.deformedNormals(), &nm = multi.deformedNormals();
      for (std::size_t i = 0; i < g.size(); ++i)
        if (surface(i) && (full.deformedPoints()[i] - (*g.points)[i].getVector3fMap()).norm() > 0.05 * drag)
          angle.push_back(std::acos(std::clamp(static_cast<double>(nf[i].dot(nm[i])), -1.0, 1.0)) * 180 /
                          M_PI);
      EXPECT_GT(angle.size(), 1000u);
      std::sort(angle.begin(), angle.end());
      return std::make_pair(angle[angle.size() / 2], angle[angle.size() * 999 / 1000]);
    };
    std::vector<double> phi_max, phi_rms, move_max, move_rms, normal_median, normal_999;
    for (const std::size_t target : targets) {
      Deformer level(g, h, coarse(target));
      ASSERT_FALSE(level.coarseLevel().empty());
      level.dragTo(from, to);
      const Errors e = compare(full, level, drag, surface);
      const auto [a50, a999] = angles(level);
      phi_max.push_back(e.phi_max);
      phi_rms.push_back(e.phi_rms);
      move_max.push_back(e.move_max);
      move_rms.push_back(e.move_rms);
      normal_median.push_back(a50);
      normal_999.push_back(a999);
    }
    const auto median = [](std::vector<double> v) {
      std::sort(v.begin(), v.end());
      return v[v.size() / 2];
    };
    std::printf(
        "fork %s, medians over %zu coarse levels: |dphi| max %.4f rms %.5f; moves max %.4f rms %.5f of the "
        "drag; "
        "normals median %.2f, 99.9%% %.2f degrees\n",
        k.name, move_max.size(), median(phi_max), median(phi_rms), median(move_max), median(move_rms),
        median(normal_median), median(normal_999));
    EXPECT_LT(median(phi_max), 0.03);
    EXPECT_LT(median(phi_rms), 0.0045);
    EXPECT_LT(median(move_max), 0.045);
    EXPECT_LT(median(move_rms), 0.012);
    EXPECT_LT(median(normal_median), 10.5);
    EXPECT_LT(median(normal_999), 17.5);

    // The rest at one level.
    Deformer multi(g, h, coarse(15000));
    ASSERT_TRUE(full.coarseLevel().empty());
    ASSERT_FALSE(multi.coarseLevel().empty());
    const std::size_t m = multi.coarseLevel().points.size();
    EXPECT_GT(m, 15000u * 80 / 100);  // (strays counted in the tuning, then taken out)
    EXPECT_LT(m, 15000u * 115 / 100);
    multi.dragTo(from, to);
    // The other prong, surface points only (a stray between the prongs may follow either).
    double other_full = 0, other_multi = 0;
    for (std::size_t i = 0; i < g.size(); ++i)
      if (surface(i) && g.world(i).x() > 0.5 && g.world(i).y() < -0.01) {
        other_full = std::max(
            other_full,
            static_cast<double>((full.deformedPoints()[i] - (*g.points)[i].getVector3fMap()).norm()));
        other_multi = std::max(
            other_multi,
            static_cast<double>((multi.deformedPoints()[i] - (*g.points)[i].getVector3fMap()).norm()));
      }
    const auto rough_full = roughness(g, full, full.surfaceGraph().graph(), surface);
    const auto rough_multi = roughness(g, multi, full.surfaceGraph().graph(), surface);
    std::printf("fork %s: roughness max %.3f / %.3f, 99.9%% %.3f / %.3f (full / multi)\n", k.name,
                rough_full.first, rough_multi.first, rough_full.second, rough_multi.second);
    std::printf(
        "fork %s: %zu coarse points; other prong %.2f%% / %.2f%% of the drag (full / multi); clusters %zu / "
        "%zu\n",
        k.name, m, 100 * other_full / drag, 100 * other_multi / drag, full.clustering().clusters.size(),
        multi.clustering().clusters.size());
    EXPECT_LT(other_multi, 0.02 * drag);
    // Smooth as the full build: measured within 5% of its 99.9th percentile. Without the
    // gradient (every point of a cell takes its anchor's value: the shape moves in steps) it was
    // 1.4-1.7x.
    EXPECT_LT(rough_multi.second, 1.15 * rough_full.second);
    // Every point is in the clustering, with clusters the solver has.
    const auto& c = multi.clustering();
    const hgd::InterpolationTable& t = multi.interpolationTable();
    ASSERT_EQ(t.size(), g.size());
    for (std::size_t i = 0; i < g.size(); ++i) {
      const hgd::InterpolationTable::Bracket b = t.bracket(i);
      ASSERT_GE(b.lower, 0);
      ASSERT_LT(static_cast<std::size_t>(b.upper), c.clusters.size());
      ASSERT_TRUE(b.alpha >= 0 && b.alpha <= 1) << i;
    }
    EXPECT_TRUE(std::any_of(c.notes.begin(), c.notes.end(),
                            [](const std::string& s) { return s.rfind("multi-resolution", 0) == 0; }));
  }
}

// A bar with both handles, and beside it a box no handle reaches: the unreached points and the
// pieces report count every point (not the coarse ones), the box stays where it is, and a
// handle's points take its transform exactly even though the field was solved on a sample.
TEST(Multires, UnreachedPiecesCountEveryPointAndStay) {
  const hgd::Shape shape = hgd::shapes::barBesideABox(0.004f);
  const hgd::Geometry g = hgd::extractGeometry(shape);
  const hgd::Handles h = hgdtest::endHandles(g, 0.05, 0.95);
  std::size_t box = 0;
  for (std::size_t i = 0; i < g.size(); ++i) box += g.world(i).y() >= 0.5;
  ASSERT_GT(box, 1000u);
  Deformer full(g, h, fullResolution());
  Deformer multi(g, h, coarse(4000));
  ASSERT_FALSE(multi.coarseLevel().empty());
  EXPECT_LT(multi.coarseLevel().points.size(), g.size() / 4);
  EXPECT_EQ(full.unreachablePoints(), box);
  EXPECT_EQ(multi.unreachablePoints(), box);
  EXPECT_EQ(multi.pieces().report.stayed_points, box);
  EXPECT_EQ(multi.pieces().report.stayed_pieces, 1u);
  // A frame move: the handle turns a quarter about z and rises.
  Eigen::Affine3d t = Eigen::Affine3d::Identity();
  t.translate(Eigen::Vector3d(1.0, 0.0, 0.2));
  t.rotate(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));
  t.translate(Eigen::Vector3d(-1.0, 0.0, 0.0));
  multi.setHandleTransform(t);
  double box_moved = 0, handle_error = 0;
  for (std::size_t i = 0; i < g.size(); ++i)
    if (g.world(i).y() >= 0.5)
      box_moved =
          std::max(box_moved,
                   static_cast<double>((multi.deformedPoints()[i] - (*g.points)[i].getVector3fMap()).norm()));
  for (const int i : h.manipulated)
    handle_error = std::max(
        handle_error,
        (multi.deformedWorld(static_cast<std::size_t>(i)) - t * g.world(static_cast<std::size_t>(i))).norm());
  EXPECT_EQ(box_moved, 0.0);
  EXPECT_LT(handle_error, 1e-5);
}

// The report's surface figures on a multi-resolution build are measured on the coarse graph's
// pairs, between the points that stand for their cells (the full resolution has no graph). A bar
// in random order with clumps of strays beside it (each clump a coarse point, an outlier of the
// coarse graph), turned a quarter with E_Prop reweighted to the end, pulls points apart at its
// bend: the pairs, the largest stretch and the split points must be those of the coarse pairs
// put in a graph over every point, strays left out (how the report measured them before).
TEST(Multires, SurfaceStretchIsMeasuredOnTheCoarseGraphsPairs) {
  std::vector<Eigen::Vector3f> p, nrm;
  const float h = 0.004f, w = 0.1f;
  for (float x = 0; x <= 1.0f; x += h)
    for (float t = -w / 2; t < w / 2; t += h) {
      const Eigen::Vector3f along[4] = {{x, t, -w / 2}, {x, w / 2, t}, {x, -t, w / 2}, {x, -w / 2, -t}};
      const Eigen::Vector3f out[4] = {-Eigen::Vector3f::UnitZ(), Eigen::Vector3f::UnitY(),
                                      Eigen::Vector3f::UnitZ(), -Eigen::Vector3f::UnitY()};
      for (int f = 0; f < 4; ++f) {
        p.push_back(along[f]);
        nrm.push_back(out[f]);
      }
    }
  std::mt19937 rng(8);
  std::uniform_real_distribution<float> jitter(-0.0015f, 0.0015f);
  for (int c = 0; c < 6; ++c)  // clumps of five, a third of the bar's width off its side
    for (int k = 0; k < 5; ++k) {
      p.emplace_back(0.15f + 0.13f * static_cast<float>(c) + jitter(rng), 0.35f + jitter(rng), jitter(rng));
      nrm.push_back(Eigen::Vector3f::UnitY());
    }
  std::vector<std::size_t> perm(p.size());
  std::iota(perm.begin(), perm.end(), std::size_t{0});
  std::shuffle(perm.begin(), perm.end(), rng);
  std::vector<Eigen::Vector3f> sp, sn;
  for (const std::size_t i : perm) {
    sp.push_back(p[i]);
    sn.push_back(nrm[i]);
  }
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::cloudShape(sp, sn));
  hgd::Handles handles;
  handles.fixed.emplace_back();
  for (std::size_t i = 0; i < g.size(); ++i) {
    const float x = (*g.points)[i].x + static_cast<float>(g.origin.x());
    if (std::abs((*g.points)[i].y + static_cast<float>(g.origin.y())) > 0.2f) continue;  // not a clump
    if (x < 0.05f) handles.fixed[0].push_back(static_cast<int>(i));
    if (x > 0.95f) handles.manipulated.push_back(static_cast<int>(i));
  }
  DeformOptions o = coarse(3000);
  o.gauss_newton.reweight_rounds = 100;
  Deformer d(g, handles, o);
  ASSERT_FALSE(d.coarseLevel().empty());
  const std::vector<char>& stray = d.surfaceGraph().outliers();
  ASSERT_EQ(stray.size(), d.coarseLevel().points.size());
  ASSERT_GT(std::count(stray.begin(), stray.end(), 1), 0);  // the skip is exercised
  Eigen::Affine3d t = Eigen::Affine3d::Identity();
  t.translate(Eigen::Vector3d(1.0, 0.0, 0.3));
  t.rotate(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY()));
  t.translate(Eigen::Vector3d(-1.0, 0.0, 0.0));
  d.setHandleTransform(t);
  const hgd::SurfaceStretch s = d.surfaceStretch();

  const auto& rest = *g.points;
  const auto& moved_to = d.deformedPoints();
  double moved = 0;
  for (std::size_t i = 0; i < rest.size(); ++i)
    moved = std::max(moved, static_cast<double>((moved_to[i] - rest[i].getVector3fMap()).norm()));
  const hgd::NeighborGraph& graph = d.surfaceGraph().graph();
  const std::vector<int>& at = d.coarseLevel().points;
  std::vector<std::pair<int, int>> pairs;
  for (std::size_t a = 0; a < graph.size(); ++a)
    for (const int* b = graph.begin(a); b != graph.end(a); ++b)
      if (static_cast<int>(a) < *b) pairs.emplace_back(at[a], at[static_cast<std::size_t>(*b)]);
  hgd::NeighborGraph none;
  none.offsets.assign(g.size() + 1, 0);
  std::vector<char> skip(g.size(), 0);
  for (std::size_t a = 0; a < stray.size(); ++a)
    if (stray[a]) skip[static_cast<std::size_t>(at[a])] = 1;
  const hgd::SurfaceStretch want =
      hgd::measureStretch(rest, moved_to, hgd::addEdges(none, pairs), moved, &skip);
  std::printf("coarse pairs %zu, largest stretch %.3f, split points %zu (report: %zu, %.3f, %zu)\n",
              want.pairs, want.max_stretch, want.split_points, s.pairs, s.max_stretch, s.split_points);
  EXPECT_GT(want.split_points, 0u);  // the case pulls points apart
  EXPECT_EQ(s.pairs, want.pairs);
  EXPECT_EQ(s.split_points, want.split_points);
  EXPECT_DOUBLE_EQ(s.max_stretch, want.max_stretch);
}

// New handles on a multi-resolution build: the coarse level depends on the handles (their cells
// are their own), so setHandles() must build it again, and the field's stage must not keep the
// old level's graph. The result must be what a fresh build with those handles gives, to the bit.
TEST(Multires, NewHandlesGiveWhatAFreshBuildGives) {
  const hgd::shapes::PointsAndNormals f = hgd::shapes::sampledFork(60000, 3);
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::cloudShape(f.p, f.n));
  auto handles = [&](double y_lo, double y_hi) {
    hgd::Handles h;
    h.fixed.push_back(hgdtest::pointsWhere(g, 0, -1, 0.1));
    for (std::size_t i = 0; i < g.size(); ++i) {
      const Eigen::Vector3d x = g.world(i);
      if (x.x() > 1.1 && x.y() > y_lo && x.y() < y_hi) h.manipulated.push_back(static_cast<int>(i));
    }
    return h;
  };
  const hgd::Handles upper = handles(0.0, 0.1), lower = handles(-0.1, 0.0);
  Deformer reused(g, upper, coarse(6000));
  reused.setHandles(lower);
  Deformer fresh(g, lower, coarse(6000));
  ASSERT_EQ(reused.coarseLevel().points, fresh.coarseLevel().points);
  EXPECT_EQ(reused.field(), fresh.field());
  EXPECT_EQ(reused.clustering().clusters.size(), fresh.clustering().clusters.size());
  // And it is the lower prong that now carries the field (the base bends too, so the upper
  // prong's tip gets some: measured 818 against 4,702 summed over the tips, and 844 against
  // 4,706 at full resolution).
  double upper_phi = 0, lower_phi = 0;
  for (std::size_t i = 0; i < g.size(); ++i)
    if (g.world(i).x() > 1.0) (g.world(i).y() > 0 ? upper_phi : lower_phi) += reused.field()[i];
  EXPECT_GT(lower_phi, 4 * upper_phi);
}

// A triangle mesh (no strays: every vertex is on the surface) with a joint in the middle: the
// coarse level keeps the joint's own points (its phi range, the bones on either side), and the
// shape after a drag matches the full build's.
TEST(Multires, MeshWithAJointMatchesFullResolution) {
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::barMesh(1.0f, 0.1f, 0.004f));
  ASSERT_FALSE(g.faces.empty());
  hgd::Handles h = hgdtest::endHandles(g, 0.05, 0.95);
  h.joints.push_back(hgdtest::pointsWhere(g, 0, 0.48, 0.52));
  Deformer full(g, h, fullResolution());
  Deformer multi(g, h, coarse(3000));
  ASSERT_FALSE(multi.coarseLevel().empty());
  EXPECT_TRUE(multi.coarseLevel().strays.empty());
  auto kinds = [](const Deformer& d, hgd::ClusterKind k) {
    std::size_t c = 0;
    for (const auto& cl : d.clustering().clusters) c += cl.kind == k;
    return c;
  };
  EXPECT_EQ(kinds(multi, hgd::ClusterKind::Range), kinds(full, hgd::ClusterKind::Range));
  EXPECT_EQ(kinds(multi, hgd::ClusterKind::Iso), kinds(full, hgd::ClusterKind::Iso));
  // The joint's phi range, measured on its own points, is the full build's within the bounds.
  auto range = [&](const Deformer& d) {
    float lo = 1, hi = 0;
    for (const int i : h.joints[0]) {
      lo = std::min(lo, d.field()[static_cast<std::size_t>(i)]);
      hi = std::max(hi, d.field()[static_cast<std::size_t>(i)]);
    }
    return std::make_pair(lo, hi);
  };
  const auto rf = range(full), rm = range(multi);
  const Eigen::Vector3d from(1.0, 0.0, 0.05), to(1.0, 0.0, 0.45);
  const double drag = (to - from).norm();
  full.dragTo(from, to);
  // The agreement depends on the coarse sample (a regular mesh's vertices tie for the nearest
  // to a cell's centre, and which of equals stands for the cell moves it): over eleven levels
  // of 2,500 to 3,500 points the largest move apart was 0.054-0.12 of the drag, and 0.54 at one
  // (2,600 points; 2,700 with ties gone to the first in Morton order: a level whose joint bends
  // elsewhere, not yet understood). So the bounds are on the median over five levels.
  std::vector<double> phi_max, phi_rms, move_max, move_rms;
  for (const std::size_t target : {2800u, 2900u, 3000u, 3100u, 3200u}) {
    Deformer level(g, h, coarse(target));
    level.dragTo(from, to);
    const Errors e = compare(full, level, drag, [](std::size_t) { return true; });
    phi_max.push_back(e.phi_max);
    phi_rms.push_back(e.phi_rms);
    move_max.push_back(e.move_max);
    move_rms.push_back(e.move_rms);
  }
  const auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  std::printf(
      "bar mesh, joint: %zu coarse points; joint phi [%.4f, %.4f] / [%.4f, %.4f]; medians over five levels: "
      "|dphi| max %.4f rms %.5f; moves max %.4f rms %.5f of the drag\n",
      multi.coarseLevel().points.size(), rf.first, rf.second, rm.first, rm.second, median(phi_max),
      median(phi_rms), median(move_max), median(move_rms));
  // Measured: the joint's ends 0.016 and 0.018 apart; medians |dphi| 0.024-0.028 / 0.008-0.009,
  // moves 0.056-0.084 / 0.008-0.014 of the drag (two graphs, two uniform Laplacians: the full
  // build's is kNN plus the mesh edges the normal filter dropped, the coarse level's kNN alone).
  // Bounds: about 1.4x.
  EXPECT_LT(std::abs(rf.first - rm.first), 0.025);
  EXPECT_LT(std::abs(rf.second - rm.second), 0.027);
  EXPECT_LT(median(phi_max), 0.04);
  EXPECT_LT(median(phi_rms), 0.014);
  EXPECT_LT(median(move_max), 0.12);
  EXPECT_LT(median(move_rms), 0.022);
}

// A handle index past the end is refused before the coarse level reads it (the full build's
// field refuses it the same way), naming the index.
TEST(Multires, HandleIndexOutOfRangeIsRefused) {
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::bar(1.0f, 0.1f, 0.01f));
  for (const bool joint : {false, true}) {
    hgd::Handles h = hgdtest::endHandles(g, 0.05, 0.95);
    const int bad = static_cast<int>(g.size());
    if (joint)
      h.joints.push_back({0, bad});
    else
      h.manipulated.push_back(bad);
    try {
      Deformer d(g, h, coarse(500));
      ADD_FAILURE() << "accepted index " << bad;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("handle index " + std::to_string(bad) + " out of range"),
                std::string::npos)
          << e.what();
    }
  }
}

}  // namespace

// What a coarse build holds per point, counted on the heap (not timed): the field (4 bytes), the
// anchor (4), the table's record (20) and the deformed positions (12): 40 bytes a point, plus
// the coarse level's own structures. Not a second copy of the file's normals (12 more), nor
// per-point cluster labels (16), nor the geometry's index maps (8, shared with the caller).
TEST(Multires, DeformerHoldsEachPerPointArrayOnce) {
#if defined(__SANITIZE_ADDRESS__) || !defined(__GLIBC__) || __GLIBC__ < 2 || \
    (__GLIBC__ == 2 && __GLIBC_MINOR__ < 33)
  GTEST_SKIP() << "counted with glibc's mallinfo2 (2.33 on), which a sanitizer's allocator does not keep";
#else
  const hgd::shapes::PointsAndNormals f = hgd::shapes::sampledFork(400000, 9);
  auto g = std::make_shared<hgd::Geometry>(hgd::extractGeometry(hgd::shapes::cloudShape(f.p, f.n)));
  ASSERT_TRUE(g->hasFileNormals());
  hgd::Handles h;
  h.fixed.emplace_back();
  for (std::size_t i = 0; i < g->size(); ++i) {
    const Eigen::Vector3d x = g->world(i);
    if (x.x() < 0.4) h.fixed.back().push_back(static_cast<int>(i));
    if (x.x() > 1.15 && x.y() > 0.0 && x.y() < 0.1) h.manipulated.push_back(static_cast<int>(i));
  }
  // In use in every arena, and in blocks mapped apart (large arrays).
  auto heapInUse = [] {
    const struct mallinfo2 m = mallinfo2();
    return m.uordblks + m.hblkhd;
  };
  const std::size_t before = heapInUse();
  double per_point = 0;
  {
    Deformer d(std::shared_ptr<const hgd::Geometry>(g), h, coarse(4000));
    ASSERT_FALSE(d.coarseLevel().empty());
    d.dragTo({1.2, 0.05, 0.0}, {1.2, 0.15, 0.3});
    (void)d.deformedNormals();  // 12 bytes a point more, derived when asked for
    per_point = static_cast<double>(heapInUse() - before) / static_cast<double>(g->size());
  }
  // Measured 56.3; with the copies named above it would be 92. Bound: 6.5% over the measure.
  std::printf("coarse build: %.1f bytes a point on the heap (with the deformed normals)\n", per_point);
  EXPECT_LT(per_point, 60.0);
#endif
}

// The coarse build fills its table straight from the coarse clustering (prolongInterpolation);
// the route it replaced, per-point labels first (prolongClustering) and the table from them
// (buildInterpolation), must give the same table, record for record, on a cloud with strays
// (which take their anchor's factor) and with a handle overlapping the fixed one (pins: the
// manipulated handle last).
TEST(Multires, TableStraightFromTheCoarseLevelIsTheLabelledRoutes) {
  const hgd::shapes::PointsAndNormals f = hgd::shapes::sampledFork(60000, 3, 0.001, 0.01);
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::cloudShape(f.p, f.n));
  hgd::Handles h;
  h.fixed.emplace_back();
  for (std::size_t i = 0; i < g.size(); ++i) {
    const Eigen::Vector3d x = g.world(i);
    if (g.raw_index[i] >= 60000) continue;
    if (x.x() < 0.4) h.fixed.back().push_back(static_cast<int>(i));
    if (x.x() > 1.15 && x.y() > 0.0 && x.y() < 0.1) h.manipulated.push_back(static_cast<int>(i));
  }
  h.manipulated.push_back(h.fixed[0][0]);  // one point in both
  const hgd::CoarseLevel level = hgd::coarsen(*g.points, h, 6000);
  ASSERT_FALSE(level.strays.empty());
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  for (const int i : level.points) cloud->push_back((*g.points)[static_cast<std::size_t>(i)]);
  const hgd::Handles ch = hgd::coarseHandles(h, level);
  hgd::HarmonicField field;
  field.setInputCloud(cloud);
  field.setHandles(ch.fixed, ch.manipulated);
  std::vector<float> coarse_phi;
  field.compute(coarse_phi);
  std::vector<char> constrained(cloud->size(), 0);
  for (const auto& fixed : ch.fixed)
    for (const int a : fixed) constrained[static_cast<std::size_t>(a)] = 1;
  for (const int a : ch.manipulated) constrained[static_cast<std::size_t>(a)] = 1;
  const std::vector<float> phi =
      hgd::prolongField(*g.points, level, field.surfaceGraph().graph(), coarse_phi, constrained);
  const std::vector<int> sample = hgd::sampleSurface(*cloud, ch, 2000);
  const hgd::Clustering c =
      hgd::buildClusters(*cloud, field.surfaceGraph().graph(), coarse_phi, ch, field.unreachable(), sample,
                         hgd::ClusterOptions{}, {}, field.surfaceGraph().outliers());

  const hgd::InterpolationTable straight = hgd::prolongInterpolation(c, level, coarse_phi, phi, h, *g.points);
  const hgd::InterpolationTable labelled =
      hgd::buildInterpolation(phi, h, hgd::prolongClustering(c, level, coarse_phi, phi), *g.points, nullptr);
  ASSERT_EQ(straight.pairs, labelled.pairs);
  ASSERT_EQ(straight.size(), g.size());
  ASSERT_EQ(labelled.size(), g.size());
  std::size_t differ = 0, blended = 0;
  for (std::size_t i = 0; i < g.size(); ++i) {
    const auto &a = straight.points[i], &b = labelled.points[i];
    differ +=
        a.pair != b.pair || a.alpha != b.alpha || a.p[0] != b.p[0] || a.p[1] != b.p[1] || a.p[2] != b.p[2];
    blended += a.alpha > 0 && a.alpha < 1;
  }
  EXPECT_EQ(differ, 0u);
  EXPECT_GT(blended, g.size() / 4);  // most points sit in a gap: the factor rule was exercised
  ASSERT_EQ(straight.pair_centre.size(), labelled.pair_centre.size());
  for (std::size_t k = 0; k < straight.pair_centre.size(); ++k)
    EXPECT_EQ(straight.pair_centre[k], labelled.pair_centre[k]);
  // The point in both handles moves with the manipulated one.
  const hgd::InterpolationTable::Bracket both = straight.bracket(static_cast<std::size_t>(h.fixed[0][0]));
  EXPECT_EQ(both.lower, c.manipulated);
  EXPECT_EQ(both.upper, c.manipulated);
}

// The coarse level against a reference computed here, point by point: each point's cell is
// floor((p - lo) / side) (lo: the cloud's lowest corner, side: the level's), split by handle
// (a later list wins: joints, then fixed, then the manipulated handle); a cell's coarse point is
// its point nearest the cell's centre (the lowest index of equals), and stands for every point
// of the cell. Strays (a cloud's) are left out of the rule and hang from a coarse point. On a
// cloud in the geometry's Morton order and the same cloud shuffled (where every run of points
// in a cell is one point long), with noise, 1% strays, dense pieces and repeated points; the
// same on 1, 2 and 3 threads.
// A scan-like cloud: a bumpy sphere's 90,000 points with noise, 1% strays, 12 dense pieces and
// 6,000 repeated points (merged scans: equally near any centre), in the geometry's order.
hgd::Geometry scanLikeCloud(std::mt19937& rng) {
  std::vector<Eigen::Vector3f> p, none;
  {
    const hgd::Geometry s = hgd::extractGeometry(hgd::shapes::bumpySphere(90000));
    for (std::size_t i = 0; i < s.size(); ++i) p.push_back(s.world(i).cast<float>());
  }
  std::uniform_real_distribution<float> u(-1.4f, 1.4f), noise(-0.004f, 0.004f);
  for (std::size_t k = 0; k < p.size() / 100; ++k) p.emplace_back(u(rng), u(rng), u(rng));
  p = hgd::shapes::withDensePieces(std::move(p), 12, 800, 0.01f, 5);
  for (auto& x : p) x += Eigen::Vector3f(noise(rng), noise(rng), noise(rng));
  std::uniform_int_distribution<std::size_t> any(0, p.size() - 1);
  for (int k = 0; k < 6000; ++k) p.push_back(p[any(rng)]);
  std::shuffle(p.begin(), p.end(), rng);
  return hgd::extractGeometry(hgd::shapes::cloudShape(p, none));
}

TEST(Multires, EachCellStandsForItsPointsByItsPointNearestTheCentre) {
  std::mt19937 rng(29);
  const hgd::Geometry g = scanLikeCloud(rng);
  pcl::PointCloud<pcl::PointXYZ> shuffled = *g.points;
  std::shuffle(shuffled.begin(), shuffled.end(), rng);

  for (const pcl::PointCloud<pcl::PointXYZ>* cloud : {g.points.get(), &shuffled}) {
    const std::size_t n = cloud->size();
    hgd::Handles h;
    h.fixed.resize(2);
    h.joints.resize(1);
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3f x = (*cloud)[i].getVector3fMap();
      if (x.z() < -0.75f) h.fixed[0].push_back(static_cast<int>(i));
      if (x.y() < -0.8f) h.fixed[1].push_back(static_cast<int>(i));  // overlaps the first
      if (x.x() > 0.8f) h.manipulated.push_back(static_cast<int>(i));
      if (std::abs(x.x()) < 0.05f) h.joints[0].push_back(static_cast<int>(i));
    }
    std::vector<int> cls(n, 0);
    for (const int i : h.joints[0]) cls[static_cast<std::size_t>(i)] = 4;
    for (std::size_t k = 0; k < 2; ++k)
      for (const int i : h.fixed[k]) cls[static_cast<std::size_t>(i)] = 2 + static_cast<int>(k);
    for (const int i : h.manipulated) cls[static_cast<std::size_t>(i)] = 1;
    Eigen::Vector3f lo = (*cloud)[0].getVector3fMap();
    for (const auto& q : *cloud) lo = lo.cwiseMin(q.getVector3fMap());

    for (const bool strays : {false, true}) {
      // The same level on any number of threads (3: blocks that do not split evenly).
      std::vector<hgd::CoarseLevel> levels;
      {
        const ThreadCount restore(omp_get_max_threads());
        for (const int threads : {1, 2, 3}) {
          omp_set_num_threads(threads);
          levels.push_back(hgd::coarsen(*cloud, h, 3000, strays));
        }
      }
      for (std::size_t t = 1; t < levels.size(); ++t) {
        EXPECT_EQ(levels[t].points, levels[0].points) << t + 1 << " threads";
        EXPECT_EQ(levels[t].anchor, levels[0].anchor) << t + 1 << " threads";
        EXPECT_EQ(levels[t].weight, levels[0].weight) << t + 1 << " threads";
        EXPECT_EQ(levels[t].strays, levels[0].strays) << t + 1 << " threads";
        EXPECT_EQ(levels[t].cell, levels[0].cell) << t + 1 << " threads";
      }
      {
        const hgd::CoarseLevel& level = levels[0];
        SCOPED_TRACE(std::string(cloud == &shuffled ? "shuffled" : "Morton order") +
                     (strays ? ", strays" : ""));
        ASSERT_FALSE(level.empty());
        EXPECT_EQ(level.strays.empty(), !strays);
        std::vector<char> stray(n, 0);
        for (const int i : level.strays) stray[static_cast<std::size_t>(i)] = 1;
        // The reference: each cell's points (strays left out), its nearest and its count.
        struct Cell {
          int best = -1;
          float best_d = 0;
          std::uint32_t count = 0;
        };
        std::map<std::array<long, 4>, Cell> cells;
        std::vector<std::array<long, 4>> cell_of(n);
        for (std::size_t i = 0; i < n; ++i) {
          const Eigen::Vector3f r = ((*cloud)[i].getVector3fMap() - lo) / level.cell;
          const Eigen::Vector3f q = r.array().floor();
          cell_of[i] = {static_cast<long>(q.x()), static_cast<long>(q.y()), static_cast<long>(q.z()), cls[i]};
          if (stray[i]) continue;
          Cell& c = cells[cell_of[i]];
          const float d = (r - q - Eigen::Vector3f::Constant(0.5f)).squaredNorm();
          if (c.best < 0 || d < c.best_d) c.best = static_cast<int>(i), c.best_d = d;
          ++c.count;
        }
        ASSERT_EQ(level.points.size(), cells.size());
        std::vector<std::uint32_t> expected_weight(cells.size(), 0);
        std::size_t wrong_point = 0, wrong_weight = 0;
        for (std::size_t i = 0; i < n; ++i) {
          if (stray[i]) continue;
          const Cell& c = cells[cell_of[i]];
          const std::uint32_t a = level.anchor[i];
          ASSERT_LT(a, level.points.size());
          wrong_point += level.points[a] != c.best;
          expected_weight[a] = c.count;
        }
        // A stray hangs from its nearest coarse point (found here by a scan of them all) and
        // adds to its weight.
        std::size_t not_nearest = 0;
        for (const int i : level.strays) {
          const std::uint32_t a = level.anchor[static_cast<std::size_t>(i)];
          ASSERT_LT(a, level.points.size());
          const Eigen::Vector3f x = (*cloud)[static_cast<std::size_t>(i)].getVector3fMap();
          float nearest = INFINITY;
          for (const int c : level.points)
            nearest =
                std::min(nearest, ((*cloud)[static_cast<std::size_t>(c)].getVector3fMap() - x).squaredNorm());
          const float d =
              ((*cloud)[static_cast<std::size_t>(level.points[a])].getVector3fMap() - x).squaredNorm();
          not_nearest += d > nearest * (1 + 1e-5f);
          ++expected_weight[a];
        }
        EXPECT_EQ(not_nearest, 0u);
        for (std::size_t a = 0; a < level.points.size(); ++a)
          wrong_weight += level.weight[a] != expected_weight[a];
        EXPECT_EQ(wrong_point, 0u);
        EXPECT_EQ(wrong_weight, 0u);
        if (strays) {  // about the 1% of strays put in (some land on the surface)
          EXPECT_GT(level.strays.size(), n / 400);
          EXPECT_LT(level.strays.size(), n / 50);
        }
      }
    }
  }
}

// The strays against their rule computed here, by a search of every neighbouring cell: cells as
// above (floor, by class); the cells' median size m (the (cells / 2)-th smallest) and
// few = max(2, m / 4); the typical squared distance to the second nearest point, over every
// point whose index (in the file; here, the cloud's) is a multiple of max(1, n / 2000), among the
// points of the 3 x 3 x 3 cells around it of every class;
// limit = min(side^2, max(9 x their median, their 97th percentile)). A stray is a point of a free
// cell of at most `few` points with fewer than two other points within the limit in those cells.
// The library skips the cells that cannot hold such a point; a cell skipped wrongly changes the
// strays (a skip 0.1 sides too eager at one face turned 837 strays of a table scan into 1,013,
// and fails here: the fringe of off-surface points below puts near points across cell faces).
TEST(Multires, StraysAreThePointsWithFewerThanTwoNearOnes) {
  std::mt19937 rng(41);
  const hgd::Geometry g = scanLikeCloud(rng);
  pcl::PointCloud<pcl::PointXYZ> base = *g.points;
  // A stereo scan's fringe: 5% more points off the surface by 0.5 to 4 point spacings (0.012),
  // in sparse cells whose near points lie across a cell's face.
  {
    std::normal_distribution<float> dir(0.0f, 1.0f);
    std::uniform_real_distribution<float> off(0.006f, 0.048f);
    std::uniform_int_distribution<std::size_t> any(0, base.size() - 1);
    const std::size_t m = base.size() / 20;
    for (std::size_t k = 0; k < m; ++k) {
      const Eigen::Vector3f d = Eigen::Vector3f(dir(rng), dir(rng), dir(rng)).normalized() * off(rng);
      const Eigen::Vector3f x = base[any(rng)].getVector3fMap() + d;
      base.push_back({x.x(), x.y(), x.z()});
    }
  }
  std::shuffle(base.begin(), base.end(), rng);
  const std::size_t n = base.size();
  // The same cloud far from the origin (as georeferenced scans are) and stretched 40 times along
  // x: a coordinate's rounding there (0.03) is up to a seventh of a cell.
  pcl::PointCloud<pcl::PointXYZ> far = base;
  for (auto& q : far) q.getVector3fMap() = Eigen::Vector3f(q.x * 40.0f + 3e5f, q.y + 1e3f, q.z - 2e3f);
  hgd::Handles h;
  h.fixed.resize(1);
  std::vector<int> cls(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f x = base[i].getVector3fMap();
    if (x.z() < -0.75f) h.fixed[0].push_back(static_cast<int>(i)), cls[i] = 2;
    if (x.x() > 0.8f) h.manipulated.push_back(static_cast<int>(i)), cls[i] = 1;
  }
  for (const pcl::PointCloud<pcl::PointXYZ>* shape : {&base, &far})
    for (const std::size_t target : {1500u, 3000u, 6000u, 12000u}) {
      SCOPED_TRACE(std::string(shape == &far ? "far, " : "") + "target " + std::to_string(target));
      const pcl::PointCloud<pcl::PointXYZ>& cloud = *shape;
      Eigen::Vector3f lo = cloud[0].getVector3fMap();
      for (const auto& q : cloud) lo = lo.cwiseMin(q.getVector3fMap());
      const hgd::CoarseLevel level = hgd::coarsen(cloud, h, target, true);
      ASSERT_FALSE(level.empty());
      using Key = std::array<long, 4>;  // class, z, y, x: the library's key order
      std::map<Key, std::vector<std::size_t>> cells;
      std::vector<Key> key(n);
      for (std::size_t i = 0; i < n; ++i) {
        const Eigen::Vector3f q = ((cloud[i].getVector3fMap() - lo) / level.cell).array().floor();
        key[i] = {cls[i], static_cast<long>(q.z()), static_cast<long>(q.y()), static_cast<long>(q.x())};
        cells[key[i]].push_back(i);
      }
      // Calls fn(j) for every point j of the 27 cells around point i, of every class.
      auto around = [&](std::size_t i, auto&& fn) {
        for (long c = 0; c < 3; ++c)
          for (long dz = -1; dz <= 1; ++dz)
            for (long dy = -1; dy <= 1; ++dy)
              for (long dx = -1; dx <= 1; ++dx) {
                const auto it = cells.find({c, key[i][1] + dz, key[i][2] + dy, key[i][3] + dx});
                if (it != cells.end())
                  for (const std::size_t j : it->second) fn(j);
              }
      };
      auto d2 = [&](std::size_t i, std::size_t j) {
        return (cloud[j].getVector3fMap() - cloud[i].getVector3fMap()).squaredNorm();
      };
      std::vector<std::size_t> sizes;
      std::vector<std::size_t> order;  // the points, cells in key order
      for (const auto& [k, points] : cells) {
        sizes.push_back(points.size());
        order.insert(order.end(), points.begin(), points.end());
      }
      std::sort(sizes.begin(), sizes.end());
      const std::size_t median = sizes[sizes.size() / 2], few = std::max<std::size_t>(2, median / 4);
      ASSERT_GE(median, 4u);
      std::vector<float> typical;
      // The sample: every point whose index (in the file; here, the cloud's) is a multiple of
      // the stride.
      const std::size_t stride = std::max<std::size_t>(1, n / 2000);
      for (std::size_t i = 0; i < n; i += stride) {
        float first = INFINITY, second = INFINITY;
        around(i, [&](std::size_t j) {
          if (j == i) return;
          const float d = d2(i, j);
          if (d < first) {
            second = first;
            first = d;
          } else if (d < second) {
            second = d;
          }
        });
        if (std::isfinite(second) && second > 0) typical.push_back(second);
      }
      std::sort(typical.begin(), typical.end());
      const float limit = std::min(level.cell * level.cell, std::max(9.0f * typical[typical.size() / 2],
                                                                     typical[typical.size() * 97 / 100]));
      std::vector<int> expected;
      std::size_t from_beside = 0;  // points kept by near points of other cells only
      for (const auto& [k, points] : cells) {
        if (k[0] != 0 || points.size() > few) continue;
        for (const std::size_t i : points) {
          int near = 0, own = 0;
          around(i, [&](std::size_t j) { near += j != i && d2(i, j) <= limit; });
          for (const std::size_t j : points) own += j != i && d2(i, j) <= limit;
          if (near < 2) expected.push_back(static_cast<int>(i));
          from_beside += own < 2 && near >= 2;
        }
      }
      std::sort(expected.begin(), expected.end());
      EXPECT_EQ(level.strays, expected);
      // The search beyond a point's own cell decided many points (else this would not test it).
      EXPECT_GT(from_beside, 100u);  // 195 to 2,553 here (136 to 2,276 far)
      EXPECT_GT(expected.size(), n / 400);
    }
}

// The surface sample (a voxel grid's point nearest each cell's centre, the first of equals) is the
// same on any number of threads: each thread's block of points keeps its own cells, merged in
// order. The cloud is shuffled, so repeated points fall in different blocks; a merge that let a
// later block win a tie would pick other points than one thread does.
TEST(Multires, SurfaceSampleIsTheSameOnAnyNumberOfThreads) {
  std::mt19937 rng(31);
  const hgd::Geometry g = scanLikeCloud(rng);
  pcl::PointCloud<pcl::PointXYZ> shuffled = *g.points;
  std::shuffle(shuffled.begin(), shuffled.end(), rng);
  hgd::Handles h;
  h.fixed.emplace_back();
  for (std::size_t i = 0; i < shuffled.size(); ++i) {
    if (shuffled[i].z < -0.75f) h.fixed[0].push_back(static_cast<int>(i));
    if (shuffled[i].x > 0.8f) h.manipulated.push_back(static_cast<int>(i));
  }
  std::vector<std::vector<int>> samples;
  {
    const ThreadCount restore(omp_get_max_threads());
    for (const int threads : {1, 2, 3}) {
      omp_set_num_threads(threads);
      samples.push_back(hgd::sampleSurface(shuffled, h, 4000));
    }
  }
  ASSERT_GT(samples[0].size(), 3000u);
  EXPECT_EQ(samples[1], samples[0]);
  EXPECT_EQ(samples[2], samples[0]);
}

// The coarse level depends on the points and their indices in the file, not on the order they
// come in (the geometry's Morton order): the grid's sizing subset and the strays' typical
// distances are taken at file indices on a stride, and of points as near their cell's centre the
// first in the file stands for it. A build that streams the file in its own order relies on it.
// The scan-like cloud (6,000 repeated points: ties at every cell they fall in) in the geometry's
// order and shuffled, each point keeping its file index: the same level, point for point.
TEST(Multires, LevelDependsOnFileIndicesNotOnTheOrderOfThePoints) {
  std::mt19937 rng(43);
  const hgd::Geometry g = scanLikeCloud(rng);
  const std::size_t n = g.size();
  std::vector<std::size_t> perm(n);
  std::iota(perm.begin(), perm.end(), std::size_t{0});
  std::shuffle(perm.begin(), perm.end(), rng);
  pcl::PointCloud<pcl::PointXYZ> shuffled;
  std::vector<int> shuffled_index(n);
  for (std::size_t k = 0; k < n; ++k) {
    shuffled.push_back((*g.points)[perm[k]]);
    shuffled_index[k] = g.raw_index[perm[k]];
  }
  const auto handlesOf = [](const pcl::PointCloud<pcl::PointXYZ>& cloud) {
    hgd::Handles h;
    h.fixed.resize(1);
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      if (cloud[i].z < -0.75f) h.fixed[0].push_back(static_cast<int>(i));
      if (cloud[i].x > 0.8f) h.manipulated.push_back(static_cast<int>(i));
    }
    return h;
  };
  const std::size_t records = g.finite_index.size();
  for (const bool strays : {false, true}) {
    SCOPED_TRACE(strays ? "strays" : "no strays");
    const hgd::CoarseLevel a =
        hgd::coarsen(*g.points, handlesOf(*g.points), 3000, strays, &g.raw_index, records);
    const hgd::CoarseLevel b =
        hgd::coarsen(shuffled, handlesOf(shuffled), 3000, strays, &shuffled_index, records);
    ASSERT_FALSE(a.empty());
    EXPECT_EQ(a.cell, b.cell);
    // By file index: the representatives (in cell order, the same in both), each point's anchor,
    // the weights and the strays.
    std::vector<int> rep_a, rep_b;
    for (const int i : a.points) rep_a.push_back(g.raw_index[static_cast<std::size_t>(i)]);
    for (const int i : b.points) rep_b.push_back(shuffled_index[static_cast<std::size_t>(i)]);
    EXPECT_EQ(rep_a, rep_b);
    EXPECT_EQ(a.weight, b.weight);
    std::vector<std::uint32_t> anchor_a(records, 0), anchor_b(records, 0);
    for (std::size_t k = 0; k < n; ++k) {
      anchor_a[static_cast<std::size_t>(g.raw_index[k])] = a.anchor[k];
      anchor_b[static_cast<std::size_t>(shuffled_index[k])] = b.anchor[k];
    }
    EXPECT_EQ(anchor_a, anchor_b);
    std::vector<int> strays_a, strays_b;
    for (const int i : a.strays) strays_a.push_back(g.raw_index[static_cast<std::size_t>(i)]);
    for (const int i : b.strays) strays_b.push_back(shuffled_index[static_cast<std::size_t>(i)]);
    std::sort(strays_a.begin(), strays_a.end());
    std::sort(strays_b.begin(), strays_b.end());
    EXPECT_EQ(strays_a, strays_b);
    EXPECT_EQ(strays_a.empty(), !strays);
  }
}
