// The harmonic field (docs/method.md; its graph: docs/scans.md) on shapes whose answer is known.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <map>
#include <numeric>
#include <random>
#include <string>

#include "../src/field/laplacian.h"  // the Dirichlet solve, the multilevel solver's reference
#include "hgdeform/field/harmonic_field.h"
#include "hgdeform/graph/knn.h"
#include "hgdeform/graph/neighbor_graph.h"
#include "hgdeform/io/geometry.h"
#include "support/shapes.h"
#include "test_util.h"

using hgdtest::pointsWhere;

namespace {

std::vector<float> fieldOf(const hgd::Geometry& g, const std::vector<std::vector<int>>& fixed,
                           const std::vector<int>& manipulated, hgd::FieldOptions opt = {},
                           hgd::HarmonicField* out = nullptr) {
  hgd::HarmonicField local;
  hgd::HarmonicField& f = out ? *out : local;
  f.setInputCloud(g.points);
  if (g.hasFileNormals()) f.setInputNormals(g.file_normals);
  if (!g.faces.empty()) f.setPolygons(g.faces);
  f.setOptions(opt);
  f.setHandles(fixed, manipulated);
  std::vector<float> phi;
  f.compute(phi);
  return phi;
}

double correlation(const std::vector<double>& a, const std::vector<double>& b) {
  const double n = static_cast<double>(a.size());
  const double ma = std::accumulate(a.begin(), a.end(), 0.0) / n,
               mb = std::accumulate(b.begin(), b.end(), 0.0) / n;
  double sab = 0, saa = 0, sbb = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    sab += (a[i] - ma) * (b[i] - mb);
    saa += (a[i] - ma) * (a[i] - ma);
    sbb += (b[i] - mb) * (b[i] - mb);
  }
  return sab / std::sqrt(saa * sbb);
}

TEST(Field, BarIsLinearAndMonotone) {
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::bar(1.0f, 0.1f, 0.01f));
  const auto fixed = pointsWhere(g, 0, -1, 0.0);
  const auto manip = pointsWhere(g, 0, 1.0, 2);
  const std::vector<float> phi = fieldOf(g, {fixed}, manip);
  for (int i : fixed) EXPECT_EQ(phi[static_cast<std::size_t>(i)], 0.0f);
  for (int i : manip) EXPECT_EQ(phi[static_cast<std::size_t>(i)], 1.0f);
  std::vector<double> x, v;
  for (std::size_t i = 0; i < g.size(); ++i) {
    ASSERT_GE(phi[i], 0.0f);
    ASSERT_LE(phi[i], 1.0f);
    x.push_back(g.world(i).x());
    v.push_back(phi[i]);
  }
  const double r = correlation(x, v);
  std::printf("bar: R^2 of phi against x = %.5f\n", r * r);
  EXPECT_GE(r * r, 0.99);
  // Monotone: the mean over each slab of x grows.
  std::vector<double> sum(25, 0), cnt(25, 0);
  for (std::size_t i = 0; i < g.size(); ++i) {
    const auto b = static_cast<std::size_t>(std::min(24, static_cast<int>(x[i] * 25)));
    sum[b] += v[i];
    cnt[b] += 1;
  }
  for (std::size_t b = 1; b < 25; ++b) EXPECT_GT(sum[b] / cnt[b], sum[b - 1] / cnt[b - 1]) << "slab " << b;
}

TEST(Field, MeshAndSampledCloudAgree) {
  const hgd::Shape mesh_shape = hgd::shapes::barMesh(1.0f, 0.1f, 0.01f);
  const hgd::Geometry mesh = hgd::extractGeometry(mesh_shape);
  ASSERT_FALSE(mesh.faces.empty());
  // A cloud sampled uniformly by area from the mesh's triangles (no faces, no normals), and
  // for each sample the mesh field interpolated at the same place.
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u01(0, 1);
  std::vector<Eigen::Vector3f> pts;
  std::vector<std::array<int, 3>> tri;
  std::vector<Eigen::Vector3f> bary;
  for (const auto& f : mesh.faces)
    for (int k = 0; k < 2; ++k) {
      float a = u01(rng), b = u01(rng);
      if (a + b > 1) {
        a = 1 - a;
        b = 1 - b;
      }
      const std::array<int, 3> t{static_cast<int>(f.vertices[0]), static_cast<int>(f.vertices[1]),
                                 static_cast<int>(f.vertices[2])};
      pts.push_back((1 - a - b) * (*mesh.points)[static_cast<std::size_t>(t[0])].getVector3fMap() +
                    a * (*mesh.points)[static_cast<std::size_t>(t[1])].getVector3fMap() +
                    b * (*mesh.points)[static_cast<std::size_t>(t[2])].getVector3fMap() +
                    mesh.origin.cast<float>());
      tri.push_back(t);
      bary.emplace_back(1 - a - b, a, b);
    }
  const hgd::Geometry cloud = hgd::extractGeometry(hgd::shapes::cloudShape(pts, {}));
  const auto pc = fieldOf(cloud, {pointsWhere(cloud, 0, -1, 0.01)}, pointsWhere(cloud, 0, 0.99, 2));
  for (bool ring : {false, true}) {
    hgd::FieldOptions opt;
    opt.mesh_ring = ring;
    const auto pm = fieldOf(mesh, {pointsWhere(mesh, 0, -1, 0.01)}, pointsWhere(mesh, 0, 0.99, 2), opt);
    std::vector<double> a, b;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      double v = 0;
      for (int k = 0; k < 3; ++k)
        v += bary[i][k] * pm[static_cast<std::size_t>(tri[i][static_cast<std::size_t>(k)])];
      a.push_back(v);
      b.push_back(pc[static_cast<std::size_t>(cloud.finite_index[i])]);  // geometry order is spatial
    }
    const double r = correlation(a, b);
    std::printf("mesh (%s) vs sampled cloud: correlation %.5f over %zu points\n", ring ? "1-ring" : "kNN", r,
                pts.size());
    EXPECT_GE(r, 0.98);
  }
}

TEST(Field, DetachedPieceIsReportedAndZero) {
  hgd::Shape s = hgd::shapes::bar(1.0f, 0.1f, 0.02f);
  const hgd::Shape island = hgd::shapes::bar(0.2f, 0.1f, 0.02f);
  // Append the island, shifted far away, to the bar's points.
  const std::size_t n0 = s.size();
  s.cloud.data.insert(s.cloud.data.end(), island.cloud.data.begin(), island.cloud.data.end());
  s.cloud.width += island.cloud.width;
  s.cloud.row_step = s.cloud.point_step * s.cloud.width;
  for (std::size_t i = n0; i < s.size(); ++i) {
    float y;
    std::memcpy(&y, s.cloud.data.data() + i * s.cloud.point_step + 4, 4);
    y += 5.0f;
    std::memcpy(s.cloud.data.data() + i * s.cloud.point_step + 4, &y, 4);
    float x;  // and away from the handles' x range
    std::memcpy(&x, s.cloud.data.data() + i * s.cloud.point_step, 4);
    x += 0.4f;
    std::memcpy(s.cloud.data.data() + i * s.cloud.point_step, &x, 4);
  }
  const hgd::Geometry g = hgd::extractGeometry(s);
  hgd::HarmonicField f;
  const auto phi = fieldOf(g, {pointsWhere(g, 0, -1, 0.0)}, pointsWhere(g, 0, 1.0, 2), {}, &f);
  EXPECT_EQ(f.unreachable().size(), g.size() - n0);
  for (std::size_t i = 0; i < g.size(); ++i) {
    ASSERT_TRUE(std::isfinite(phi[i]));
    if (i >= n0) {
      EXPECT_EQ(phi[i], 0.0f);
    }
  }
}

// Reachability on a large graph of many pieces (the parallel union-find): 300 chains
// interleaved in index order, constraints on the first 150 only. Exactly the other chains'
// points are unreachable, and the constrained chains get their harmonic (linear) values.
TEST(Field, ManyPiecesOnALargeGraph) {
  const int chains = 300, length = 200, n = chains * length;
  hgd::NeighborGraph graph;
  graph.offsets.assign(1, 0);
  for (int i = 0; i < n; ++i) {
    if (i >= chains) graph.adj.push_back(i - chains);
    if (i + chains < n) graph.adj.push_back(i + chains);
    graph.offsets.push_back(static_cast<int>(graph.adj.size()));
  }
  std::vector<char> constrained(static_cast<std::size_t>(n), 0);
  std::vector<double> value(static_cast<std::size_t>(n), 0.0);
  for (int c = 0; c < chains / 2; ++c) {  // ends of chain c: 0 and 1
    constrained[static_cast<std::size_t>(c)] = 1;
    constrained[static_cast<std::size_t>(c + (length - 1) * chains)] = 1;
    value[static_cast<std::size_t>(c + (length - 1) * chains)] = 1.0;
  }
  hgd::FieldOptions opt;
  opt.solver = hgd::FieldSolver::Exact;
  std::vector<int> unreachable;
  hgd::FieldTimings timings;
  hgd::solveDirichlet(graph, constrained, value, opt, unreachable, timings);
  ASSERT_EQ(unreachable.size(), static_cast<std::size_t>(n / 2));
  for (int i : unreachable) EXPECT_GE(i % chains, chains / 2);
  double worst = 0;
  for (int i = 0; i < n; ++i)
    if (i % chains < chains / 2)
      worst = std::max(worst, std::abs(value[static_cast<std::size_t>(i)] - (i / chains) / (length - 1.0)));
  EXPECT_LT(worst, 1e-9);
}

// A sheet folded back on itself, the two layers 1 mm apart with opposite normals. The field
// must follow the surface around the fold, not jump the gap.
TEST(Field, NormalFilterKeepsThinSheetsApart) {
  std::vector<Eigen::Vector3f> p, n;
  const float h = 2.0f, len = 100.0f, gap = 1.0f;  // millimetres
  for (float x = 0; x <= len + 1e-3f; x += h)
    for (float y = 0; y <= 40.0f + 1e-3f; y += h) {
      p.emplace_back(x, y, 0.0f);
      n.emplace_back(0, 0, -1);
      p.emplace_back(x, y, gap);
      n.emplace_back(0, 0, 1);
    }
  for (float y = 0; y <= 40.0f + 1e-3f; y += h)  // the fold
    for (int k = 1; k < 4; ++k) {
      const float a = static_cast<float>(M_PI) * k / 4;
      p.emplace_back(len + gap / 2 * std::sin(a), y, gap / 2 - gap / 2 * std::cos(a));
      n.emplace_back(std::sin(a), 0, -std::cos(a));
    }
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::cloudShape(p, n));
  std::vector<int> fixed, manip;
  for (std::size_t i = 0; i < g.size(); ++i) {
    const Eigen::Vector3d w = g.world(i);
    if (w.x() < 0.5 && w.z() < 0.5) fixed.push_back(static_cast<int>(i));
    if (w.x() < 0.5 && w.z() > 0.5) manip.push_back(static_cast<int>(i));
  }
  auto gapAt = [&](const std::vector<float>& phi, double x) {
    double lower = 0, upper = 0, cl = 0, cu = 0;
    for (std::size_t i = 0; i < g.size(); ++i) {
      const Eigen::Vector3d w = g.world(i);
      if (std::abs(w.x() - x) > 0.5 || w.x() > len) continue;
      (w.z() < 0.5 ? lower : upper) += phi[i];
      (w.z() < 0.5 ? cl : cu) += 1;
    }
    return upper / cu - lower / cl;
  };
  const auto filtered = fieldOf(g, {fixed}, manip);
  hgd::FieldOptions off;
  off.normal_filter = false;
  const auto leaky = fieldOf(g, {fixed}, manip, off);
  // Along the surface the layers are 2*len apart at x = 20: the field differs by ~0.8 there.
  std::printf("thin sheets at x=20: filtered gap %.3f, unfiltered gap %.3f\n", gapAt(filtered, 20),
              gapAt(leaky, 20));
  EXPECT_GT(gapAt(filtered, 20), 0.6);
  EXPECT_GT(gapAt(filtered, 50), 0.3);
  EXPECT_LT(gapAt(leaky, 20), 0.3);  // without the filter the field leaks across
}

TEST(Field, MultilevelMatchesExact) {
  for (std::size_t n : {8000u, 20000u, 60000u, 120000u}) {
    const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::bumpySphere(n));
    std::vector<int> fixed, manip;
    for (std::size_t i = 0; i < g.size(); ++i) {
      const Eigen::Vector3d w = g.world(i);
      if (w.z() < -0.85) fixed.push_back(static_cast<int>(i));
      if (w.x() > 0.9) manip.push_back(static_cast<int>(i));
    }
    hgd::FieldOptions exact, multi;
    exact.solver = hgd::FieldSolver::Exact;
    multi.solver = hgd::FieldSolver::Multilevel;
    hgd::HarmonicField fe, fm;
    const auto pe = fieldOf(g, {fixed}, manip, exact, &fe);
    const auto pm = fieldOf(g, {fixed}, manip, multi, &fm);
    double worst = 0;
    for (std::size_t i = 0; i < pe.size(); ++i)
      worst = std::max(worst, static_cast<double>(std::abs(pe[i] - pm[i])));
    std::printf(
        "bumpy sphere %zu: max |dphi| %.2e, exact solve %.0f ms, multilevel %.0f ms (%d iterations)\n", n,
        worst, fe.timings().solve_ms, fm.timings().solve_ms, fm.timings().iterations);
    // What the README claims: measured 1.07e-3, 1.22e-3, 1.65e-3 and 2.39e-3 at the four sizes
    // (the sums are deterministic whatever the threads; 1.1e-3, 9.2e-4, 7.0e-4 and 2.4e-3 with a
    // direct level of up to 4,000 unknowns instead of 1,000); 3e-3 leaves a quarter of margin.
    EXPECT_LE(worst, 3e-3);
  }
}

TEST(Field, ReusesGraphWhenOnlyHandlesChange) {
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::bar(1.0f, 0.1f, 0.01f));
  hgd::HarmonicField f;
  fieldOf(g, {pointsWhere(g, 0, -1, 0.0)}, pointsWhere(g, 0, 1.0, 2), {}, &f);
  const int* adjacency_before = f.surfaceGraph().graph().adj.data();
  f.setHandles({pointsWhere(g, 0, 0.45, 0.55)}, pointsWhere(g, 0, 1.0, 2));
  std::vector<float> phi;
  f.compute(phi);
  EXPECT_EQ(f.surfaceGraph().graph().adj.data(), adjacency_before);  // the same graph, not rebuilt
  EXPECT_EQ(f.timings().knn_ms, 0.0);
  EXPECT_EQ(f.timings().normals_ms, 0.0);
  for (int i : pointsWhere(g, 0, 0.45, 0.55)) EXPECT_EQ(phi[static_cast<std::size_t>(i)], 0.0f);
}

}  // namespace

// extractGeometry orders points in space whatever the file's order, and its index maps stay
// exact: a shuffled cloud gets neighbours close in memory, and every point maps back.
TEST(Geometry, SpatialOrderWithExactIndexMaps) {
  const hgd::Geometry sphere = hgd::extractGeometry(hgd::shapes::bumpySphere(40000));
  std::vector<Eigen::Vector3f> pts;
  for (std::size_t i = 0; i < sphere.size(); ++i) pts.push_back(sphere.world(i).cast<float>());
  std::mt19937 rng(11);
  std::shuffle(pts.begin(), pts.end(), rng);
  pts.insert(pts.begin() + 123, Eigen::Vector3f(NAN, 0, 0));  // a NaN point keeps its place in the file
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::cloudShape(pts, {}));
  ASSERT_EQ(g.size(), pts.size() - 1);
  EXPECT_EQ(g.finite_index[123], -1);
  for (std::size_t k = 0; k < g.size(); ++k) {
    const auto raw = static_cast<std::size_t>(g.raw_index[k]);
    ASSERT_EQ(g.finite_index[raw], static_cast<int>(k));
    ASSERT_LE((g.world(k) - pts[raw].cast<double>()).norm(), 1e-6);
  }
  // Mean index distance between a point and its 10 nearest: a small fraction of n.
  const hgd::KnnTable t = hgd::computeKnn(*g.points, 10);
  double spread = 0;
  for (std::size_t i = 0; i < g.size(); ++i)
    for (int m = 0; m < t.k; ++m)
      spread += std::abs(static_cast<double>(t.row(i)[m]) - static_cast<double>(i));
  spread /= static_cast<double>(g.size() * static_cast<std::size_t>(t.k));
  std::printf("mean index distance to the 10 nearest: %.0f of %zu points\n", spread, g.size());
  EXPECT_LT(spread, 0.02 * static_cast<double>(g.size()));
}
