// The graph stage (docs/scans.md): the exact k nearest neighbours (the grid search and its
// fallbacks), the nearest of a set of points, the filtered neighbour graph, and graphs with edges
// added.
#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "../src/graph/grid_knn.h"  // the grid search itself: which clouds it keeps
#include "../src/graph/nearest.h"   // strays hang from the nearest coarse point
#include "hgdeform/graph/knn.h"
#include "hgdeform/graph/neighbor_graph.h"
#include "hgdeform/graph/normal_filter.h"
#include "hgdeform/io/geometry.h"
#include "support/shapes.h"
#include "support/threads.h"
#include "test_util.h"

#ifndef HGD_SANITIZED
#define HGD_SANITIZED 0
#endif

using hgdtest::ThreadCount;

namespace {

/// Brute-force references check every this many of the points they would (tests/CMakeLists.txt:
/// a quarter under the sanitizers, where they took five minutes of CI).
constexpr std::size_t kCheckEvery = HGD_SANITIZED ? 4 : 1;

}  // namespace

// computeKnn against brute force: the same distances in the same order, on clouds that take
// the grid path (surfaces, a plane, a line, a volume) and ones that leave it (far outliers).
TEST(Knn, ExactOnSurfacesVolumesAndOutliers) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1, 1);
  std::normal_distribution<float> noise(0, 0.002f);
  const auto cloudOf = [](const std::vector<Eigen::Vector3f>& v) {
    pcl::PointCloud<pcl::PointXYZ> c;
    for (const auto& p : v) c.push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
    return c;
  };
  std::map<std::string, std::vector<Eigen::Vector3f>> clouds;
  {
    const hgd::Shape s = hgd::shapes::bumpySphere(30000);
    const hgd::Geometry g = hgd::extractGeometry(s);
    auto& v = clouds["bumpy sphere 30k"];
    for (const auto& p : *g.points) v.push_back(p.getVector3fMap());
    auto& w = clouds["bumpy sphere with 40 far outliers"];  // searched against every point
    w = v;
    for (int i = 0; i < 40; ++i) w.emplace_back(50 * u(rng), 50 * u(rng), 1000 + 50 * u(rng));
    // Strays in the shape's box, as a scan has them: those too far for the grid's shells are
    // searched alone (here against every point); the rest stay the grid's.
    auto& st = clouds["bumpy sphere with 1% strays"];
    st = v;
    for (int i = 0; i < 300; ++i) st.emplace_back(1.6f * u(rng), 1.6f * u(rng), 1.6f * u(rng));
    std::shuffle(st.begin(), st.end(), rng);  // strays anywhere in the order, as in a file
    // Far outliers too many to search against every point: a k-d tree for them alone.
    auto& ft = clouds["bumpy sphere with 3000 far outliers"];
    ft = v;
    for (int i = 0; i < 3000; ++i) ft.emplace_back(50 * u(rng), 50 * u(rng), 1000 + 50 * u(rng));
    // Small dense pieces (a character's eyes and teeth): their crowded cells get a finer grid.
    clouds["bumpy sphere with 43 dense pieces"] = hgd::shapes::withDensePieces(v, 43, 400, 0.002f, 5);
    auto& c = clouds["bumpy sphere with a dense clump"];  // too crowded for a grid: the k-d tree
    c = v;
    for (int i = 0; i < 6000; ++i) c.emplace_back(0.3f + 1e-4f * u(rng), 1e-4f * u(rng), 1e-4f * u(rng));
  }
  for (int i = 0; i < 20000; ++i) clouds["noisy plane"].emplace_back(u(rng), 0.01f * u(rng), noise(rng));
  for (int i = 0; i < 5000; ++i) {
    const float t = u(rng);
    clouds["line"].emplace_back(t, 2 * t + 1, 0.5f);
  }
  for (int i = 0; i < 20000; ++i) clouds["volume"].emplace_back(u(rng), u(rng), u(rng));
  for (const auto& [name, pts] : clouds) {
    SCOPED_TRACE(name);
    // Brute force on a spread subset of the points (every point is queried by computeKnn), and
    // on every point at a distance from the others (strays, outliers: another path).
    std::vector<std::size_t> check;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      // (and every 7th point of the dense pieces, which follow the sphere's 30,000)
      if (i % (97 * kCheckEvery) == 0 ||
          (name.find("pieces") != std::string::npos && i >= 30000 && i % (7 * kCheckEvery) == 0)) {
        check.push_back(i);
        continue;
      }
      float nearest = INFINITY;
      for (std::size_t j = 0; j < pts.size() && nearest > 0.01f; ++j)
        if (j != i) nearest = std::min(nearest, (pts[j] - pts[i]).squaredNorm());
      if (nearest > 0.01f) check.push_back(i);  // 0.1 away from everything: ~10 spacings
    }
    for (const int k : {10, 16}) {
      const auto cloud = cloudOf(pts);
      const hgd::KnnTable t = hgd::computeKnn(cloud, k);
      ASSERT_EQ(t.k, k);
      std::size_t wrong = 0;
      std::vector<float> d(pts.size());
      for (const std::size_t i : check) {
        for (std::size_t j = 0; j < pts.size(); ++j)
          d[j] = j == i ? INFINITY : (pts[j] - pts[i]).squaredNorm();
        std::vector<float> best(d);
        std::nth_element(best.begin(), best.begin() + k - 1, best.end());
        const float kth = best[static_cast<std::size_t>(k) - 1];
        float previous = 0;
        for (int m = 0; m < k; ++m) {
          const int j = t.row(i)[m];
          const float dj = j == static_cast<int>(i) ? INFINITY : d[static_cast<std::size_t>(j)];
          // Every listed neighbour is among the k nearest (ties at the k-th distance aside) and
          // the list is sorted.
          if (!(dj <= kth) || dj < previous) ++wrong;
          previous = dj;
        }
      }
      EXPECT_EQ(wrong, 0u) << "k = " << k;
    }
  }
}

// The neighbour graph is the symmetric closure of the kNN relation, without self-loops,
// repeats or pairs across a thin gap: checked against a set-based construction, on a cloud
// large enough for the parallel passes: a sphere inside a copy 1% larger whose normals face it
// (a third of a spacing apart: pairs between the layers are across a thin gap), with some
// normals flipped on both layers (pairs beside each other stay) and duplicate rows. The dropped pairs are
// listed exactly.
// Small pieces so dense beside a large sparse surface that one grid for all would cost too much
// (the grid used to give up and send every point to a k-d tree): the crowd gets a finer grid of
// its own, and the grid search keeps the cloud, exact. Pieces of coincident points (duplicates:
// no grid splits them) stay on the one grid when it can afford them.
TEST(Knn, CrowdedPiecesStayOnTheGrid) {
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::bumpySphere(30000));
  std::vector<Eigen::Vector3f> sphere;
  for (const auto& p : *g.points) sphere.push_back(p.getVector3fMap());
  std::map<std::string, std::vector<Eigen::Vector3f>> clouds;
  clouds["43 dense pieces"] = hgd::shapes::withDensePieces(sphere, 43, 3000, 0.002f, 5);
  clouds["43 pieces of 400 duplicates"] = hgd::shapes::withDensePieces(sphere, 43, 400, 0.0f, 5);
  for (const auto& [name, pts] : clouds) {
    SCOPED_TRACE(name);
    const std::size_t n = pts.size();
    const int kk = 11;  // k = 10 and the point itself
    std::vector<float> xyz;
    for (const auto& p : pts) xyz.insert(xyz.end(), {p.x(), p.y(), p.z()});
    std::vector<int> idx(n * kk, -2);
    std::vector<float> d2(n * kk);
    std::vector<std::uint32_t> far;
    ASSERT_TRUE(hgd::gridKnn(xyz.data(), n, kk, idx.data(), d2.data(), far));
    std::vector<char> is_far(n, 0);
    for (const auto f : far) is_far[f] = 1;
    EXPECT_LE(far.size(), n / 1000);
    // Every 11th point of the pieces and every 97th of the sphere against brute force: each
    // listed neighbour among the kk nearest, and the kk-th distance (to float rounding: the
    // search sums the squares in its own order).
    std::size_t wrong = 0, checked = 0;
    std::vector<float> d(n);
    for (std::size_t i = 0; i < n; ++i) {
      if (is_far[i] || !(i >= 30000 ? i % (11 * kCheckEvery) == 0 : i % (97 * kCheckEvery) == 0)) continue;
      for (std::size_t j = 0; j < n; ++j) d[j] = (pts[j] - pts[i]).squaredNorm();
      std::vector<float> sorted(d);
      std::nth_element(sorted.begin(), sorted.begin() + (kk - 1), sorted.end());
      const float kth = sorted[kk - 1], tol = 1e-5f * kth + 1e-12f;
      bool ok = std::abs(d2[i * kk + kk - 1] - kth) <= tol;
      for (int m = 0; m < kk; ++m) {
        const int j = idx[i * kk + static_cast<std::size_t>(m)];
        ok = ok && j >= 0 && static_cast<std::size_t>(j) < n && d[static_cast<std::size_t>(j)] <= kth + tol;
      }
      wrong += !ok;
      ++checked;
    }
    EXPECT_GT(checked, 1000u / kCheckEvery);
    EXPECT_EQ(wrong, 0u);
  }
}

// Few queries are answered against every target, many through a k-d tree: both must give the
// nearest target, checked in double against every target, on a noisy sphere in random order
// with far queries, duplicated targets (ties) and query counts on both sides of the switch.
TEST(Knn, NearestAmongIsTheNearestTargetWhateverTheQueryCount) {
  std::mt19937 rng(31);
  std::normal_distribution<float> gauss(0.0f, 1.0f);
  pcl::PointCloud<pcl::PointXYZ> pts;
  for (int i = 0; i < 30000; ++i) {
    Eigen::Vector3f v(gauss(rng), gauss(rng), gauss(rng));
    v = v.normalized() * (1.0f + 0.01f * gauss(rng));
    if (i % 97 == 0) v *= 40.0f;  // far strays
    pts.push_back(pcl::PointXYZ(v.x(), v.y(), v.z()));
  }
  std::vector<int> all(pts.size());
  std::iota(all.begin(), all.end(), 0);
  std::shuffle(all.begin(), all.end(), rng);
  std::vector<int> targets(all.begin(), all.begin() + 20000);
  for (int d = 0; d < 50; ++d) targets.push_back(targets[static_cast<std::size_t>(d) * 7]);  // ties
  for (const std::size_t count :
       {std::size_t{1}, std::size_t{63}, std::size_t{64}, std::size_t{65}, std::size_t{3000}}) {
    std::vector<int> queries(all.begin() + 20000, all.begin() + 20000 + static_cast<long>(count));
    queries.push_back(targets[5]);  // a query on a target: distance 0
    const std::vector<int> hit = hgd::nearestAmong(pts, targets, queries);
    ASSERT_EQ(hit.size(), queries.size());
    for (std::size_t m = 0; m < queries.size(); ++m) {
      const Eigen::Vector3d q = pts[static_cast<std::size_t>(queries[m])].getVector3fMap().cast<double>();
      double best = INFINITY;
      for (const int t : targets)
        best = std::min(best,
                        (pts[static_cast<std::size_t>(t)].getVector3fMap().cast<double>() - q).squaredNorm());
      ASSERT_GE(hit[m], 0) << count << " queries, query " << m;
      ASSERT_LT(static_cast<std::size_t>(hit[m]), targets.size());
      const double got = (pts[static_cast<std::size_t>(targets[static_cast<std::size_t>(hit[m])])]
                              .getVector3fMap()
                              .cast<double>() -
                          q)
                             .squaredNorm();
      // Float distances: equal to the double minimum within float rounding of the squared distance.
      EXPECT_LE(got, best * (1 + 1e-5) + 1e-12) << count << " queries, query " << m;
    }
  }
}

// Among targets at the same distance (a lattice's, duplicates) the k-d tree keeps the one its
// descent meets first. The scan of a few queries must give the very same hits: a call of 10
// queries (the scan's size) against the same 10 followed by 90 more (the tree's).
TEST(Knn, NearestAmongKeepsTheTreesChoiceAmongEquals) {
  pcl::PointCloud<pcl::PointXYZ> pts;
  std::vector<int> targets, queries;
  for (int x = 0; x < 32; ++x)
    for (int y = 0; y < 4; ++y) {
      targets.push_back(static_cast<int>(pts.size()));
      pts.push_back(pcl::PointXYZ(static_cast<float>(x), static_cast<float>(y), 0.0f));
    }
  targets.push_back(targets[40]);  // a duplicate target
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> cell(0, 30);
  for (int k = 0; k < 100; ++k) {
    // Half-way between lattice points along x, y or both: two or four targets tie.
    const float x = static_cast<float>(cell(rng)) + 0.5f,
                y = static_cast<float>(k % 3) + (k % 2 ? 0.5f : 0.0f);
    queries.push_back(static_cast<int>(pts.size()));
    pts.push_back(pcl::PointXYZ(x, y, 0.0f));
  }
  const std::vector<int> few(queries.begin(), queries.begin() + 10);
  const std::vector<int> by_scan = hgd::nearestAmong(pts, targets, few);
  const std::vector<int> by_tree = hgd::nearestAmong(pts, targets, queries);
  for (std::size_t m = 0; m < few.size(); ++m) EXPECT_EQ(by_scan[m], by_tree[m]) << "query " << m;
  // A duplicated target queried at its own position: the tree's choice of the two, too.
  const std::vector<int> on_dup = hgd::nearestAmong(pts, targets, {targets[40]});
  std::vector<int> many(70, targets[40]);
  EXPECT_EQ(on_dup[0], hgd::nearestAmong(pts, targets, many)[0]);
}

TEST(Knn, GraphIsTheSymmetricFilteredRelation) {
  const hgd::Geometry inner = hgd::extractGeometry(hgd::shapes::bumpySphere(15000, 0.0f));
  std::vector<Eigen::Vector3f> p, nv;
  std::mt19937 rng(3);
  for (const float scale : {1.0f, 1.01f})
    for (std::size_t i = 0; i < inner.size(); ++i) {
      p.push_back(inner.world(i).cast<float>() * scale);
      Eigen::Vector3f n = (*inner.file_normals)[i].getNormalVector3fMap() * (scale > 1 ? -1.0f : 1.0f);
      if (rng() % 7 == 0) n *= -1.0f;
      nv.push_back(n);
    }
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::cloudShape(p, nv));
  hgd::KnnTable knn = hgd::computeKnn(*g.points, 12);
  const pcl::PointCloud<pcl::Normal>& normals = *g.file_normals;
  ASSERT_EQ(normals.size(), g.size());
  // Rows with a self entry and a repeated neighbour (as computeKnn leaves for coincident points).
  for (std::size_t i = 0; i < knn.size(); i += 101) {
    int* row = knn.index.data() + i * static_cast<std::size_t>(knn.k);
    row[3] = static_cast<int>(i);
    row[5] = row[4];
  }
  for (const bool filter : {false, true}) {
    SCOPED_TRACE(filter ? "normal filter" : "no filter");
    const int k = 10;
    std::vector<std::pair<int, int>> dropped;
    const hgd::NeighborGraph graph =
        hgd::knnGraph(knn, k, filter ? &normals : nullptr, g.points.get(), &dropped);
    std::vector<std::vector<int>> expected(knn.size());
    std::vector<std::pair<int, int>> expected_dropped;
    for (std::size_t i = 0; i < knn.size(); ++i)
      for (int m = 0; m < k; ++m) {
        const int j = knn.row(i)[m];
        if (j == static_cast<int>(i)) continue;
        const auto uj = static_cast<std::size_t>(j);
        // Independently of acrossThinGap: the pair is between the layers when the radii
        // differ, and across the gap when its normals also oppose (a flip on one side makes
        // them agree); beside each other on one layer, opposing normals do not matter.
        const float ri = (*g.points)[i].getVector3fMap().norm(), rj = (*g.points)[uj].getVector3fMap().norm();
        const bool oppose = normals[i].getNormalVector3fMap().dot(normals[uj].getNormalVector3fMap()) < 0;
        if (filter && std::abs(ri - rj) > 0.005f && oppose) {
          expected_dropped.emplace_back(std::min<int>(static_cast<int>(i), j),
                                        std::max<int>(static_cast<int>(i), j));
          continue;
        }
        expected[i].push_back(j);
        expected[uj].push_back(static_cast<int>(i));
      }
    std::sort(expected_dropped.begin(), expected_dropped.end());
    expected_dropped.erase(std::unique(expected_dropped.begin(), expected_dropped.end()),
                           expected_dropped.end());
    ASSERT_EQ(graph.size(), knn.size());
    std::size_t differ = 0, edges = 0;
    for (std::size_t i = 0; i < knn.size(); ++i) {
      auto& e = expected[i];
      std::sort(e.begin(), e.end());
      e.erase(std::unique(e.begin(), e.end()), e.end());
      edges += e.size();
      if (!std::equal(e.begin(), e.end(), graph.begin(i), graph.end(i)) ||
          static_cast<std::size_t>(graph.degree(i)) != e.size())
        ++differ;
    }
    std::printf("%s: %zu edges, %zu dropped\n", filter ? "filtered" : "unfiltered", edges / 2,
                dropped.size());
    EXPECT_EQ(differ, 0u);
    EXPECT_EQ(dropped, expected_dropped);
    if (filter) {
      EXPECT_GT(dropped.size(), g.size() / 4);  // the layers do meet in the kNN
    }
  }
}

// The filter's rule on the cases it must tell apart.
TEST(Knn, ThinGapIsNotARidge) {
  using V = Eigen::Vector3f;
  // Two sides of a sheet: one above the other, normals opposite (back to back, face to face),
  // also with the neighbour beside by twice the gap.
  EXPECT_TRUE(hgd::acrossThinGap(V(0, 0, 0), V(0, 0, -1), V(0, 0, 0.5f), V(0, 0, 1)));
  EXPECT_TRUE(hgd::acrossThinGap(V(0, 0, 0), V(0, 0, 1), V(0, 0, 0.5f), V(0, 0, -1)));
  EXPECT_TRUE(hgd::acrossThinGap(V(0, 0, 0), V(0, 0, 1), V(1.0f, 0, 0.5f), V(0, 0, -2)));
  // At the rim of a sheet whose layers are a third of a spacing apart, a neighbour on the
  // other layer 2.5 spacings aside (7.6 degrees out of the tangent plane).
  EXPECT_TRUE(hgd::acrossThinGap(V(0, 0, 0), V(0, 0, 1), V(2.5f, 0, -0.333f), V(0, 0, -1)));
  // A sawtooth crest: faces at +-55 degrees, normals turned 110 degrees: kept, whatever the
  // offset.
  const float a = 55.0f * static_cast<float>(M_PI) / 180.0f;
  const V left(-std::cos(a), 0, -std::sin(a)), right(std::cos(a), 0, -std::sin(a));  // down the faces
  const V nl(-std::sin(a), 0, std::cos(a)), nr(std::sin(a), 0, std::cos(a));
  for (const float t : {0.3f, 1.0f, 2.0f}) EXPECT_FALSE(hgd::acrossThinGap(left * t, nl, right, nr)) << t;
  // A flipped normal on a flat patch or a gently curved one (3 and 5 degrees out of the
  // tangent plane): the neighbour is beside it, not above it.
  EXPECT_FALSE(hgd::acrossThinGap(V(0, 0, 0), V(0, 0, 1), V(1, 0, 0.05f), V(0, 0, -1)));
  EXPECT_FALSE(hgd::acrossThinGap(V(0, 0, 0), V(0, 0, 1), V(1, 0, 0.087f), V(0, 0, -1)));
  // Coincident points and zero normals: never across a gap.
  EXPECT_FALSE(hgd::acrossThinGap(V(0, 0, 0), V(0, 0, 1), V(0, 0, 0), V(0, 0, -1)));
  EXPECT_FALSE(hgd::acrossThinGap(V(0, 0, 0), V(0, 0, 0), V(0, 0, 1), V(0, 0, -1)));
}

// Graphs with edges added (the isoclusters' site graph, a mesh's dropped edges) against rows
// made here with std::set: both directions, self-loops and repeats dropped, rows sorted; on a
// graph large enough to be built on every thread, and a small one, at 1, 2 and 3 threads; with
// the edges in a random order, repeated, some already in the graph, and on an empty graph.
TEST(Graphs, AddedEdgesMakeTheSameRowsOnAnyNumberOfThreads) {
  const ThreadCount restore(omp_get_max_threads());
  for (const std::size_t n : {std::size_t{40}, std::size_t{30000}}) {
    std::mt19937 rng(static_cast<unsigned>(n));
    std::uniform_int_distribution<int> node(0, static_cast<int>(n) - 1);
    std::vector<std::set<int>> base_rows(n);
    for (std::size_t i = 0; i < n; ++i)
      for (int k = 0; k < 3; ++k) {
        const int j = node(rng);
        if (j == static_cast<int>(i)) continue;
        base_rows[i].insert(j);
        base_rows[static_cast<std::size_t>(j)].insert(static_cast<int>(i));
      }
    hgd::NeighborGraph base, empty;
    base.offsets.assign(1, 0);
    for (const auto& row : base_rows) {
      base.adj.insert(base.adj.end(), row.begin(), row.end());
      base.offsets.push_back(static_cast<int>(base.adj.size()));
    }
    empty.offsets.assign(n + 1, 0);
    std::vector<std::pair<int, int>> edges;
    for (std::size_t e = 0; e < 7 * n; ++e) {
      const int a = node(rng);
      edges.emplace_back(a, e % 97 == 0 ? a : node(rng));  // some self-loops
    }
    for (std::size_t e = 0; e < n; ++e)
      edges.push_back(edges[static_cast<std::size_t>(node(rng)) % edges.size()]);
    for (std::size_t i = 0; i < n; i += 5)
      if (!base_rows[i].empty())
        edges.emplace_back(*base_rows[i].begin(), static_cast<int>(i));  // in the graph
    std::shuffle(edges.begin(), edges.end(), rng);
    std::vector<std::set<int>> added_rows(n);
    for (const auto& [a, b] : edges)
      if (a != b) {
        added_rows[static_cast<std::size_t>(a)].insert(b);
        added_rows[static_cast<std::size_t>(b)].insert(a);
      }
    const auto expect_rows = [&](const hgd::NeighborGraph& g, bool with_base, int threads) {
      ASSERT_EQ(g.size(), n);
      ASSERT_EQ(g.offsets.front(), 0);
      ASSERT_EQ(static_cast<std::size_t>(g.offsets.back()), g.adj.size());
      for (std::size_t i = 0; i < n; ++i) {
        std::set<int> want = added_rows[i];
        if (with_base) want.insert(base_rows[i].begin(), base_rows[i].end());
        const std::vector<int> got(g.begin(i), g.end(i));
        ASSERT_EQ(got, std::vector<int>(want.begin(), want.end()))
            << "row " << i << " of " << n << (with_base ? ", graph" : ", empty graph") << ", " << threads
            << " threads";
      }
    };
    for (const int threads : {1, 2, 3}) {
      omp_set_num_threads(threads);
      expect_rows(hgd::addEdges(base, edges), true, threads);
      expect_rows(hgd::addEdges(empty, edges), false, threads);
      expect_rows(hgd::unionGraph(base, hgd::addEdges(empty, edges)), true, threads);
    }
  }
}
