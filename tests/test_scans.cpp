// Data shaped like users' scans (docs/scans.md): stored normals with random signs or flipped
// patches, one shape at several densities with noise and outliers, scenes of several objects,
// sharp ridges and corners, a thin folded sheet. Every shape is made here, in file order
// shuffled as scans arrive, with its surface neighbours known from how it was made, so that
// the tear and split metrics below are computed independently of the library:
// - torn: a point whose displacement differs from the median displacement of its 10 nearest
//   rest neighbours by more than 0.25x the drag distance;
// - split: a point whose distance to a surface neighbour more than triples and grows by more
//   than 2% of the drag distance.
#include <pcl/kdtree/kdtree_flann.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "hgdeform/app/runner.h"
#include "hgdeform/deformer/deformer.h"
#include "hgdeform/field/harmonic_field.h"
#include "support/shapes.h"
#include "test_util.h"

namespace {

using V3 = Eigen::Vector3f;

// A procedural surface: points and normals in file order, and the pairs of points that are
// neighbours on the surface (by construction: grid or mesh adjacency), i < j.
struct Surface {
  std::vector<V3> p, n;
  std::vector<std::pair<int, int>> pairs;
  std::vector<pcl::Vertices> faces;
  std::size_t size() const { return p.size(); }
  // Appends another surface (its indices shifted).
  void append(const Surface& o) {
    const int base = static_cast<int>(p.size());
    p.insert(p.end(), o.p.begin(), o.p.end());
    n.insert(n.end(), o.n.begin(), o.n.end());
    for (const auto& e : o.pairs) pairs.emplace_back(e.first + base, e.second + base);
    for (pcl::Vertices f : o.faces) {
      for (auto& v : f.vertices) v += base;
      faces.push_back(f);
    }
  }
};

// A grid surface x(u, v) over nu x nv samples (u wrapping round when `wrap_u`), with the
// normals `normal(u, v)`; 4-neighbour pairs, and two triangles per cell.
template <typename Pos, typename Nrm>
Surface grid(int nu, int nv, bool wrap_u, Pos pos, Nrm normal) {
  Surface s;
  auto id = [&](int i, int j) { return (i % nu) * nv + j; };
  for (int i = 0; i < nu; ++i)
    for (int j = 0; j < nv; ++j) {
      const float u = static_cast<float>(i) / static_cast<float>(wrap_u ? nu : nu - 1);
      const float v = static_cast<float>(j) / static_cast<float>(nv - 1);
      s.p.push_back(pos(u, v));
      s.n.push_back(normal(u, v).normalized());
    }
  for (int i = 0; i < (wrap_u ? nu : nu - 1); ++i)
    for (int j = 0; j < nv; ++j) {
      s.pairs.emplace_back(std::min(id(i, j), id(i + 1, j)), std::max(id(i, j), id(i + 1, j)));
      if (j + 1 < nv) {
        const auto tri = [&](int a, int b, int c) {
          pcl::Vertices t;
          t.vertices.resize(3);
          t.vertices[0] = a;
          t.vertices[1] = b;
          t.vertices[2] = c;
          s.faces.push_back(t);
        };
        tri(id(i, j), id(i + 1, j), id(i + 1, j + 1));
        tri(id(i, j), id(i + 1, j + 1), id(i, j + 1));
      }
    }
  for (int i = 0; i < nu; ++i)
    for (int j = 0; j + 1 < nv; ++j) s.pairs.emplace_back(id(i, j), id(i, j + 1));
  return s;
}

// An open tube along x: length `len`, radius r, spacing ~h, outward normals.
Surface tube(float len, float r, float h) {
  const int nu = static_cast<int>(std::lround(2 * M_PI * r / h)),
            nv = static_cast<int>(std::lround(len / h)) + 1;
  const auto pos = [=](float u, float v) -> V3 {
    const float a = 2 * static_cast<float>(M_PI) * u;
    return V3(v * len, r * std::cos(a), r * std::sin(a));
  };
  const auto nrm = [=](float u, float) -> V3 {
    const float a = 2 * static_cast<float>(M_PI) * u;
    return V3(0, std::cos(a), std::sin(a));
  };
  return grid(nu, nv, true, pos, nrm);
}

// File order shuffled (scans and resamples arrive in no order); pairs and faces follow.
void shuffle(Surface& s, unsigned seed) {
  std::vector<int> perm(s.size());
  std::iota(perm.begin(), perm.end(), 0);
  std::mt19937 rng(seed);
  std::shuffle(perm.begin(), perm.end(), rng);  // old index -> new index
  Surface t;
  t.p.resize(s.size());
  t.n.resize(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) {
    t.p[static_cast<std::size_t>(perm[i])] = s.p[i];
    t.n[static_cast<std::size_t>(perm[i])] = s.n[i];
  }
  for (const auto& e : s.pairs) {
    const int a = perm[static_cast<std::size_t>(e.first)], b = perm[static_cast<std::size_t>(e.second)];
    t.pairs.emplace_back(std::min(a, b), std::max(a, b));
  }
  for (pcl::Vertices f : s.faces) {
    for (auto& v : f.vertices) v = perm[static_cast<std::size_t>(v)];
    t.faces.push_back(f);
  }
  s = std::move(t);
}

hgd::Shape toShape(const Surface& s, bool normals, bool mesh) {
  hgd::Shape shape = hgd::shapes::cloudShape(s.p, normals ? s.n : std::vector<V3>{});
  if (mesh) shape.polygons = s.faces;
  return shape;
}

std::vector<V3> positions(const hgd::Shape& shape) {
  std::vector<V3> out(shape.size());
  for (std::size_t i = 0; i < out.size(); ++i) {
    float v[3];
    std::memcpy(v, shape.cloud.data.data() + i * shape.cloud.point_step, sizeof v);
    out[i] = V3(v[0], v[1], v[2]);
  }
  return out;
}

std::vector<long long> where(const Surface& s, const std::function<bool(const V3&)>& f) {
  std::vector<long long> out;
  for (std::size_t i = 0; i < s.size(); ++i)
    if (f(s.p[i])) out.push_back(static_cast<long long>(i));
  return out;
}

struct Outcome {
  hgd::DeformReport report;
  std::vector<V3> deformed;
};

// `hgdeform deform` on a shape made here: handles as file indices, one drag.
Outcome deform(const Surface& s, const std::vector<long long>& fixed,
               const std::vector<long long>& manipulated, const Eigen::Vector3d& from,
               const Eigen::Vector3d& to, bool normals = true, bool mesh = false, int isovalues = 16) {
  hgd::Shape shape = toShape(s, normals, mesh);
  hgd::Scenario sc;
  if (!fixed.empty()) sc.fixed.push_back(hgd::Region::fromIndices(fixed));
  sc.manipulated = hgd::Region::fromIndices(manipulated);
  sc.clusters = isovalues;
  hgd::Move m;
  m.drag.from = from;
  m.drag.to = to;
  sc.moves.push_back(m);
  Outcome r;
  r.report = hgd::deformShape(shape, sc);
  r.deformed = positions(shape);
  return r;
}

// Torn points (see the top of the file), among the points where `count` is true (all when
// empty).
std::size_t tornPoints(const std::vector<V3>& rest, const std::vector<V3>& deformed, double drag,
                       const std::vector<char>& count = {}) {
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  for (const V3& x : rest) cloud->push_back(pcl::PointXYZ(x.x(), x.y(), x.z()));
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
  tree.setInputCloud(cloud);
  std::size_t torn = 0;
  pcl::Indices nb;
  std::vector<float> d2;
  for (std::size_t i = 0; i < rest.size(); ++i) {
    if (!count.empty() && !count[i]) continue;
    tree.nearestKSearch((*cloud)[i], 11, nb, d2);
    Eigen::Vector3f med;
    for (int a = 0; a < 3; ++a) {
      std::vector<float> c;
      for (const auto j : nb)
        if (static_cast<std::size_t>(j) != i)
          c.push_back(deformed[static_cast<std::size_t>(j)][a] - rest[static_cast<std::size_t>(j)][a]);
      std::nth_element(c.begin(), c.begin() + static_cast<long>(c.size() / 2), c.end());
      med[a] = c[c.size() / 2];
    }
    if ((deformed[i] - rest[i] - med).norm() > 0.25 * drag) ++torn;
  }
  return torn;
}

struct Split {
  std::size_t points = 0;
  double max_stretch = 1;
};

// Split points over the surface's own neighbour pairs (see the top of the file).
Split splitPoints(const Surface& s, const std::vector<V3>& deformed, double drag) {
  Split out;
  std::vector<char> split(s.size(), 0);
  for (const auto& [i, j] : s.pairs) {
    const auto ui = static_cast<std::size_t>(i), uj = static_cast<std::size_t>(j);
    const double r = (s.p[ui] - s.p[uj]).norm(), d = (deformed[ui] - deformed[uj]).norm();
    if (!(r > 0)) continue;
    out.max_stretch = std::max(out.max_stretch, d / r);
    if (d > 3 * r && d - r > 0.02 * drag) split[ui] = split[uj] = 1;
  }
  out.points = static_cast<std::size_t>(std::count(split.begin(), split.end(), 1));
  return out;
}

// The harmonic field in file order, from the stage the deformer uses (points as given, so
// that no index map is involved); handles as file indices.
std::vector<float> field(const Surface& s, const std::vector<long long>& fixed,
                         const std::vector<long long>& manipulated, bool normals = true,
                         const std::vector<V3>* normal_override = nullptr) {
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  pcl::PointCloud<pcl::Normal>::Ptr nrm(new pcl::PointCloud<pcl::Normal>);
  for (std::size_t i = 0; i < s.size(); ++i) {
    cloud->push_back(pcl::PointXYZ(s.p[i].x(), s.p[i].y(), s.p[i].z()));
    const V3 v = normal_override ? (*normal_override)[i] : s.n[i];
    nrm->push_back(pcl::Normal(v.x(), v.y(), v.z()));
  }
  hgd::HarmonicField f;
  f.setInputCloud(cloud);
  if (normals) f.setInputNormals(nrm);
  std::vector<std::vector<int>> fx(1);
  for (const long long i : fixed) fx[0].push_back(static_cast<int>(i));
  std::vector<int> mp(manipulated.begin(), manipulated.end());
  f.setHandles(fx, mp);
  std::vector<float> phi;
  f.compute(phi);
  return phi;
}

// The largest jump of the field across a surface neighbour pair, relative to the field's
// local gradient there: the 80th percentile of |Δφ| / |Δx| over the surface pairs whose
// midpoints lie within `radius` of the pair's (pairs across the gradient have |Δφ| near 0, so
// a median would halve the gradient; a crease line crossing the ball is under a tenth of its
// pairs). Pairs inside a handle (`constrained` at both ends: φ is
// constant there by definition) are left out. A crease (a pair that lost its link) stands out
// by an order of magnitude; a smooth field stays near 1.
double worstJumpRatio(const Surface& s, const std::vector<float>& phi, const std::vector<char>& constrained,
                      float radius) {
  pcl::PointCloud<pcl::PointXYZ>::Ptr mids(new pcl::PointCloud<pcl::PointXYZ>);
  std::vector<float> grad;
  for (const auto& [i, j] : s.pairs) {
    const auto ui = static_cast<std::size_t>(i), uj = static_cast<std::size_t>(j);
    if (constrained[ui] && constrained[uj]) continue;
    const V3 m = 0.5f * (s.p[ui] + s.p[uj]);
    mids->push_back(pcl::PointXYZ(m.x(), m.y(), m.z()));
    const float len = (s.p[ui] - s.p[uj]).norm();
    grad.push_back(len > 0 ? std::abs(phi[ui] - phi[uj]) / len : 0.0f);
  }
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
  tree.setInputCloud(mids);
  const float global = *std::max_element(grad.begin(), grad.end());
  double worst = 0;
  pcl::Indices nb;
  std::vector<float> d2;
  for (std::size_t e = 0; e < grad.size(); ++e) {
    if (grad[e] < 0.05f * global) continue;  // too flat to crease
    tree.radiusSearch((*mids)[e], radius, nb, d2);
    std::vector<float> g;
    for (const auto k : nb) g.push_back(grad[static_cast<std::size_t>(k)]);
    const std::size_t q = g.size() * 4 / 5;
    std::nth_element(g.begin(), g.begin() + static_cast<long>(q), g.end());
    const float local = std::max(g[q], 0.05f * global);
    worst = std::max(worst, static_cast<double>(grad[e] / local));
  }
  return worst;
}

bool mentions(const std::vector<std::string>& lines, const std::string& part) {
  return std::any_of(lines.begin(), lines.end(),
                     [&](const std::string& l) { return hgdtest::contains(l, part); });
}

double maxAbsDiff(const std::vector<float>& a, const std::vector<float>& b) {
  double m = 0;
  for (std::size_t i = 0; i < a.size(); ++i) m = std::max(m, static_cast<double>(std::abs(a[i] - b[i])));
  return m;
}

}  // namespace

namespace {

// The tube of the first tests: 1 long, radius 0.1, spacing 0.01 (6,300 points, shuffled), the
// end x < 0.05 fixed, x > 0.95 dragged sideways by 0.4.
struct TubeCase {
  Surface s = tube(1.0f, 0.1f, 0.01f);
  std::vector<long long> fixed, manipulated;
  Eigen::Vector3d from{1.0, 0.1, 0.0}, to{1.0, 0.5, 0.0};
  TubeCase() {
    shuffle(s, 1);
    fixed = where(s, [](const V3& x) { return x.x() < 0.05f; });
    manipulated = where(s, [](const V3& x) { return x.x() > 0.95f; });
  }
};

// Stored normals whose signs are random (merged scans, meshes resampled with face normals)
// give the same field and the same motion as consistent ones: nothing is cut off, nothing is
// left behind. Before the filter re-oriented such normals, half the kNN pairs were dropped
// and the tube fell apart into islands that stayed put.
TEST(Scans, RandomNormalSignsGiveTheSameFieldAndMotion) {
  TubeCase c;
  Surface random = c.s;
  std::mt19937 rng(7);
  for (V3& n : random.n)
    if (rng() % 2) n = -n;
  const std::vector<float> consistent = field(c.s, c.fixed, c.manipulated);
  const std::vector<float> signs = field(random, c.fixed, c.manipulated);
  const double diff = maxAbsDiff(consistent, signs);
  const Outcome a = deform(c.s, c.fixed, c.manipulated, c.from, c.to);
  const Outcome b = deform(random, c.fixed, c.manipulated, c.from, c.to);
  const double drag = (c.to - c.from).norm();
  const std::size_t torn = tornPoints(random.p, b.deformed, drag);
  const Split split = splitPoints(random, b.deformed, drag);
  std::printf(
      "random signs: max |dphi| %.2e; clusters %zu / %zu; unreachable %zu; torn %zu; split %zu "
      "(stretch %.2f)\n",
      diff, a.report.clusters, b.report.clusters, b.report.unreachable, torn, split.points,
      split.max_stretch);
  EXPECT_LE(diff, 1e-3);  // the multilevel solve's tolerance
  EXPECT_EQ(b.report.unreachable, 0u);
  EXPECT_EQ(b.report.clusters, a.report.clusters);
  EXPECT_EQ(torn, 0u);
  EXPECT_EQ(split.points, 0u);
  EXPECT_TRUE(b.report.warnings.empty()) << b.report.warnings.front();
  double moved = 0;
  for (std::size_t i = 0; i < c.s.size(); ++i)
    moved = std::max(moved, static_cast<double>((a.deformed[i] - b.deformed[i]).norm()));
  std::printf("random signs: largest difference from the consistent run %.2e (drag %.2f)\n", moved, drag);
  EXPECT_LE(moved, 0.01 * drag);
#ifndef HGD_TEST_BEFORE
  EXPECT_TRUE(mentions(b.report.notes, "not consistently oriented"));
  EXPECT_FALSE(mentions(a.report.notes, "not consistently oriented"));
#endif
}

// A patch of flipped normals (a scan merged from two views, one registered inside out) is
// not cut off: the field is the same, and the patch moves with its surroundings.
TEST(Scans, PatchOfFlippedNormalsStaysAttached) {
  TubeCase c;
  Surface flipped = c.s;
  std::size_t patch = 0;
  for (std::size_t i = 0; i < flipped.size(); ++i) {
    const V3& x = flipped.p[i];
    if (x.x() > 0.4f && x.x() < 0.6f && std::atan2(x.z(), x.y()) > 0 && std::atan2(x.z(), x.y()) < 1.2f) {
      flipped.n[i] = -flipped.n[i];
      ++patch;
    }
  }
  const double diff = maxAbsDiff(field(c.s, c.fixed, c.manipulated), field(flipped, c.fixed, c.manipulated));
  const Outcome r = deform(flipped, c.fixed, c.manipulated, c.from, c.to);
  const double drag = (c.to - c.from).norm();
  const std::size_t torn = tornPoints(flipped.p, r.deformed, drag);
  const Split split = splitPoints(flipped, r.deformed, drag);
  std::printf(
      "flipped patch of %zu points: max |dphi| %.2e; clusters %zu; unreachable %zu; torn %zu; "
      "split %zu (stretch %.2f)\n",
      patch, diff, r.report.clusters, r.report.unreachable, torn, split.points, split.max_stretch);
  EXPECT_GT(patch, 200u);
  EXPECT_LE(diff, 1e-3);
  EXPECT_EQ(r.report.unreachable, 0u);
  EXPECT_EQ(torn, 0u);
  EXPECT_EQ(split.points, 0u);
  EXPECT_TRUE(r.report.warnings.empty()) << r.report.warnings.front();
}

// The fork of hgd::shapes::sampledFork as a test surface (no pairs: a sampled cloud).
Surface sampledFork(std::size_t n, unsigned seed, double noise = 0, double outliers = 0) {
  hgd::shapes::PointsAndNormals f = hgd::shapes::sampledFork(n, seed, noise, outliers);
  Surface s;
  s.p = std::move(f.p);
  s.n = std::move(f.n);
  return s;
}

// The same fork at three densities, and with noise and outliers: the cluster count does not
// grow with density (isolines traced on the surface sample), the prongs stay apart (the other
// prong does not follow; outliers between the prongs hang from one surface and do not carry
// the field across), no surface point is left behind or torn.
TEST(Scans, ClusterCountsDoNotDependOnDensityOrNoise) {
  struct Case {
    const char* name;
    std::size_t n;
    double noise, outliers;
  };
  const Case cases[] = {{"30k", 30000, 0, 0},
                        {"120k", 120000, 0, 0},
                        {"480k", 480000, 0, 0},
                        {"120k, noise 0.3% of the diagonal", 120000, 0.003, 0},
                        {"120k, 1% outliers", 120000, 0, 0.01},
                        {"120k, noise 0.3% + 1% outliers", 120000, 0.003, 0.01}};
  std::vector<std::size_t> clusters;
  for (const Case& k : cases) {
    SCOPED_TRACE(k.name);
    const Surface s = sampledFork(k.n, 11, k.noise, k.outliers);
    const std::vector<long long> fixed = where(s, [](const V3& x) { return x.x() < 0.4f; });
    const std::vector<long long> manipulated =
        where(s, [](const V3& x) { return x.x() > 1.15f && x.y() > 0.0f && x.y() < 0.1f; });
    const Eigen::Vector3d from(1.2, 0.05, 0.0), to(1.2, 0.15, 0.3);
    const Outcome r = deform(s, fixed, manipulated, from, to);
    const double drag = (to - from).norm();
    // Torn surface points (an outlier between a prong that moves and one that stays has no
    // one displacement to agree with).
    std::vector<char> surface(s.size(), 0);
    std::fill(surface.begin(), surface.begin() + static_cast<long>(k.n), 1);
    const std::size_t torn = tornPoints(s.p, r.deformed, drag, surface);
    // The other prong (surface points only: an outlier between the prongs may follow either).
    double other = 0;
    for (std::size_t i = 0; i < k.n; ++i)
      if (s.p[i].x() > 0.5f && s.p[i].y() < -0.01f)
        other = std::max(other, static_cast<double>((r.deformed[i] - s.p[i]).norm()));
    std::printf("fork %s: %zu clusters, unreachable %zu, torn %zu, other prong moved %.2f%% of the drag\n",
                k.name, r.report.clusters, r.report.unreachable, torn, 100 * other / drag);
    clusters.push_back(r.report.clusters);
    EXPECT_EQ(torn, 0u);
    EXPECT_LT(other, 0.02 * drag);
    if (k.outliers == 0) {
      EXPECT_EQ(r.report.unreachable, 0u);
    }
  }
  // Densities: within 25% of each other; noise, outliers, and both at once: within 25% of the
  // clean cloud (measured: the same count, 18, in all six). Both at once used to give 26: a
  // stray in the gap, within the noise's reach of both prongs, was not far enough to be
  // flagged and joined them; it is nobody's neighbour, and now a stray for that.
  const auto [lo, hi] = std::minmax_element(clusters.begin(), clusters.begin() + 3);
  EXPECT_LE(static_cast<double>(*hi), 1.25 * static_cast<double>(*lo));
  const auto near = [&](std::size_t c, double factor) {
    return std::abs(static_cast<double>(c) - static_cast<double>(clusters[1])) <=
           factor * static_cast<double>(clusters[1]);
  };
  EXPECT_TRUE(near(clusters[3], 0.25)) << clusters[3];
  EXPECT_TRUE(near(clusters[4], 0.25)) << clusters[4];
  EXPECT_TRUE(near(clusters[5], 0.25)) << clusters[5];
}

// Strays inside the dragged handle's box, in the gap between the prongs and nearer the prong
// that should stay (a user's box drawn a little wide): they move with the handle, but they are
// no constraint of the field. As constrained leaves they passed the handle's value to the
// other prong's tip, which then moved with the drag (at 200k points with noise and outliers:
// 25 clusters against 18, and that prong's tip at a harmonic value of 0.48).
TEST(Scans, StraysInsideAHandleDoNotPullAnotherPart) {
  Surface s = sampledFork(30000, 3);
  const std::size_t surface = s.size();
  // Three strays 0.025 apart: 0.015 from the other prong, 0.025 from the dragged one.
  for (int i = 0; i < 3; ++i) {
    s.p.push_back(
        V3(1.165f + 0.015f * static_cast<float>(i), -0.005f, -0.02f + 0.02f * static_cast<float>(i)));
    s.n.push_back(V3(0, 0, 1));
  }
  const std::vector<long long> fixed = where(s, [](const V3& x) { return x.x() < 0.4f; });
  const std::vector<long long> manipulated =
      where(s, [](const V3& x) { return x.x() > 1.15f && x.y() > -0.01f && x.y() < 0.1f; });
  const Eigen::Vector3d from(1.2, 0.05, 0.0), to(1.2, 0.15, 0.3);
  const Outcome r = deform(s, fixed, manipulated, from, to);
  const double drag = (to - from).norm();
  double other = 0, strays = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const double moved = static_cast<double>((r.deformed[i] - s.p[i]).norm());
    if (i < surface && s.p[i].x() > 0.5f && s.p[i].y() < -0.01f) other = std::max(other, moved);
    if (i >= surface) strays = std::max(strays, static_cast<double>((r.deformed[i] - s.p[i]).norm()));
  }
  std::vector<char> on_surface(s.size(), 0);
  std::fill(on_surface.begin(), on_surface.begin() + static_cast<long>(surface), 1);
  const std::size_t torn = tornPoints(s.p, r.deformed, drag, on_surface);
  std::printf(
      "strays in the handle: %zu clusters, other prong moved %.2f%% of the drag, strays %.2f, torn %zu, "
      "split %zu\n",
      r.report.clusters, 100 * other / drag, strays / drag, torn, r.report.surface.split_points);
  EXPECT_LT(other, 0.006 * drag);  // measured 0.30% (0.90% when the strays were constraints)
  EXPECT_GT(strays, 0.5 * drag);   // they are in the handle: they move with it
  EXPECT_EQ(torn, 0u);
  EXPECT_EQ(r.report.surface.split_points, 0u);  // a stray's pair to its anchor is no surface pair
  EXPECT_LE(r.report.clusters, 18u);
}

// A small sphere sampled on a golden spiral.
Surface sphere(const V3& centre, float r, std::size_t n) {
  Surface s;
  const double golden = M_PI * (3 - std::sqrt(5.0));
  for (std::size_t i = 0; i < n; ++i) {
    const double z = 1 - 2 * (static_cast<double>(i) + 0.5) / static_cast<double>(n);
    const double rho = std::sqrt(1 - z * z), a = golden * static_cast<double>(i);
    const V3 d(static_cast<float>(rho * std::cos(a)), static_cast<float>(rho * std::sin(a)),
               static_cast<float>(z));
    s.p.push_back(centre + r * d);
    s.n.push_back(d);
  }
  return s;
}

// A scene: a tube with both handles, an "eye" inside it close to its wall (a separate piece of
// the neighbour graph, three spacings from the wall), and another object on the table, well
// apart. The eye follows the tube; the other object stays; both are said.
TEST(Scans, PiecesWithoutAHandleFollowOrStayAndAreReported) {
  Surface scene = tube(1.0f, 0.1f, 0.004f);
  const std::size_t tube_points = scene.size();
  scene.append(sphere({0.8f, 0.058f, 0}, 0.03f, 700));  // inside, 0.012 from the wall
  const std::size_t eye_end = scene.size();
  scene.append(sphere({0.5f, -0.6f, 0}, 0.15f, 4000));  // 0.35 from the tube
  const std::vector<long long> fixed =
      where(scene, [](const V3& x) { return x.x() < 0.05f && std::abs(x.y()) <= 0.1001f; });
  std::vector<long long> manipulated;
  for (std::size_t i = 0; i < tube_points; ++i)
    if (scene.p[i].x() > 0.95f) manipulated.push_back(static_cast<long long>(i));
  Surface shuffled = scene;  // the deform sees the scene in no order; indices map back below
  std::vector<int> perm(scene.size());
  std::iota(perm.begin(), perm.end(), 0);
  std::mt19937 rng(3);
  std::shuffle(perm.begin(), perm.end(), rng);
  for (std::size_t i = 0; i < scene.size(); ++i) {
    shuffled.p[static_cast<std::size_t>(perm[i])] = scene.p[i];
    shuffled.n[static_cast<std::size_t>(perm[i])] = scene.n[i];
  }
  std::vector<long long> fx, mp;
  for (const long long i : fixed) fx.push_back(perm[static_cast<std::size_t>(i)]);
  for (const long long i : manipulated) mp.push_back(perm[static_cast<std::size_t>(i)]);
  const Eigen::Vector3d from(1.0, 0.0, 0.1), to(1.0, 0.3, 0.2);
  const Outcome r = deform(shuffled, fx, mp, from, to);
  const double drag = (to - from).norm();
  std::vector<V3> deformed(scene.size());
  for (std::size_t i = 0; i < scene.size(); ++i) deformed[i] = r.deformed[static_cast<std::size_t>(perm[i])];
  // The eye stays where it was against the tube's wall: each eye point keeps its distance to
  // the wall point nearest it at rest (an eye left behind pokes through the wall), and the eye
  // keeps its shape.
  double eye_lag = 0;
  std::vector<Eigen::Vector3d> eye_rest, eye_now;
  for (std::size_t i = tube_points; i < eye_end; ++i) {
    std::size_t nearest = 0;
    float best = 1e9f;
    for (std::size_t j = 0; j < tube_points; ++j) {
      const float d = (scene.p[j] - scene.p[i]).squaredNorm();
      if (d < best) {
        best = d;
        nearest = j;
      }
    }
    eye_lag = std::max(eye_lag, static_cast<double>(std::abs((deformed[i] - deformed[nearest]).norm() -
                                                             (scene.p[i] - scene.p[nearest]).norm())));
    eye_rest.push_back(scene.p[i].cast<double>());
    eye_now.push_back(deformed[i].cast<double>());
  }
  const double eye_residual = hgdtest::rigidResidual(eye_rest, eye_now);
  double other_moved = 0;
  for (std::size_t i = eye_end; i < scene.size(); ++i)
    other_moved = std::max(other_moved, static_cast<double>((deformed[i] - scene.p[i]).norm()));
  std::vector<char> count(scene.size(), 1);
  const std::size_t torn = tornPoints(scene.p, deformed, drag, count);
  std::printf(
      "scene: unreachable %zu; eye's distance to the wall changed by %.2f%% of the drag, its shape "
      "by %.2f%% (RMS); other object moved %.2e; torn %zu\n",
      r.report.unreachable, 100 * eye_lag / drag, 100 * eye_residual / drag, other_moved, torn);
  for (const auto& w : r.report.warnings) std::printf("  warning: %s\n", w.c_str());
  EXPECT_EQ(torn, 0u);
  EXPECT_LE(eye_lag, 0.05 * drag);
  EXPECT_LE(eye_residual, 0.05 * drag);
  EXPECT_LE(other_moved, 1e-6);  // float rounding through the local frame
#ifndef HGD_TEST_BEFORE
  EXPECT_EQ(r.report.pieces.followed_points, eye_end - tube_points);
  EXPECT_EQ(r.report.pieces.followed_pieces, 1u);
  EXPECT_EQ(r.report.pieces.stayed_points, scene.size() - eye_end);
  EXPECT_EQ(r.report.pieces.stayed_pieces, 1u);
  EXPECT_TRUE(mentions(r.report.warnings, "700 points in 1 piece that touch no handle lie against"));
  EXPECT_TRUE(mentions(r.report.warnings, "4000 points in 1 piece that touch no handle lie apart"));
#endif
}

// The manipulated handle on an object of its own (no fixed handle there): that object moves
// rigidly with the handle, the other stays, and the warning says so.
TEST(Scans, PieceWithOnlyTheManipulatedHandleMovesRigidly) {
  Surface scene = tube(1.0f, 0.1f, 0.01f);
  const std::size_t tube_points = scene.size();
  scene.append(sphere({0.5f, 0.5f, 0}, 0.15f, 2000));
  const std::vector<long long> fixed =
      where(scene, [](const V3& x) { return x.x() < 0.05f && x.y() < 0.2f; });
  const std::vector<long long> manipulated = where(scene, [](const V3& x) { return x.y() > 0.6f; });
  const Eigen::Vector3d from(0.5, 0.65, 0), to(0.7, 0.8, 0.1);
  const Outcome r = deform(scene, fixed, manipulated, from, to);
  std::vector<Eigen::Vector3d> before, after;
  for (std::size_t i = tube_points; i < scene.size(); ++i) {
    before.push_back(scene.p[i].cast<double>());
    after.push_back(r.deformed[i].cast<double>());
  }
  const double residual = hgdtest::rigidResidual(before, after);
  double tube_moved = 0;
  for (std::size_t i = 0; i < tube_points; ++i)
    tube_moved = std::max(tube_moved, static_cast<double>((r.deformed[i] - scene.p[i]).norm()));
  std::printf("rigid piece: residual %.2e, tube moved %.2e\n", residual, tube_moved);
  for (const auto& w : r.report.warnings) std::printf("  warning: %s\n", w.c_str());
  EXPECT_LE(residual, 1e-3 * 0.15);  // 0.1% of the sphere's radius (measured: 0.05%)
  EXPECT_LE(tube_moved, 1e-6);       // float rounding through the local frame
#ifndef HGD_TEST_BEFORE
  EXPECT_EQ(r.report.pieces.rigid_points, scene.size() - tube_points);
  EXPECT_TRUE(mentions(r.report.warnings,
                       "2000 points in 1 piece that holds the manipulated handle but no "
                       "fixed handle move rigidly"));
#endif
}

}  // namespace

namespace {

// A strip x in [0, 1], y in [0, 0.3] folded into a sawtooth: teeth 0.1 wide whose faces rise at
// 55 degrees, so that the normal turns by 110 degrees over each crest and valley. Sampled
// along the profile's arc length (9 samples a face, none on a crest or in a valley, each with
// its face's normal: a resampled mesh's face normals) and across at 0.01.
Surface sawtooth() {
  const int teeth = 10, per_face = 9, faces = 2 * teeth;
  const float a = 55.0f * static_cast<float>(M_PI) / 180.0f, half = 0.05f;
  const int nu = faces * per_face, nv = 31;
  auto profile = [=](float u, V3* normal) {
    // Sample i of the profile lies at (i + 0.5) / per_face faces along it: none on a crest.
    const float f = (std::round(u * static_cast<float>(nu - 1)) + 0.5f) / static_cast<float>(per_face);
    const int k = std::min(faces - 1, static_cast<int>(f));
    const float t = f - static_cast<float>(k);
    const float sign = k % 2 == 0 ? 1.0f : -1.0f;  // rising, falling
    const float x = (static_cast<float>(k) + t) * half;
    const float z = (k % 2 == 0 ? t : 1 - t) * half * std::tan(a);
    if (normal) *normal = V3(-sign * std::sin(a), 0, std::cos(a));
    return V3(x, 0, z);
  };
  return grid(
      nu, nv, false, [=](float u, float v) -> V3 { return profile(u, nullptr) + V3(0, 0.3f * v, 0); },
      [=](float u, float) -> V3 {
        V3 n;
        profile(u, &n);
        return n;
      });
}

struct CreaseRun {
  std::size_t split = 0, torn = 0;
  double stretch = 1, jump = 0;
};

CreaseRun creaseCase(const char* name, const Surface& s, const std::vector<long long>& fixed,
                     const std::vector<long long>& manipulated, const Eigen::Vector3d& from,
                     const Eigen::Vector3d& to, bool mesh, float spacing) {
  CreaseRun out;
  const Outcome r = deform(s, fixed, manipulated, from, to, !mesh, mesh);
  const double drag = (to - from).norm();
  const Split split = splitPoints(s, r.deformed, drag);
  out.split = split.points;
  out.stretch = split.max_stretch;
  out.torn = tornPoints(s.p, r.deformed, drag);
  hgd::Geometry g = hgd::extractGeometry(toShape(s, !mesh, mesh));
  hgd::Handles h;
  h.fixed.emplace_back();
  for (const long long i : fixed) h.fixed[0].push_back(g.finite_index[static_cast<std::size_t>(i)]);
  for (const long long i : manipulated) h.manipulated.push_back(g.finite_index[static_cast<std::size_t>(i)]);
  hgd::Deformer d(g, h);
  std::vector<float> phi(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) phi[i] = d.field()[static_cast<std::size_t>(g.finite_index[i])];
  std::vector<char> constrained(s.size(), 0);
  for (const long long i : fixed) constrained[static_cast<std::size_t>(i)] = 1;
  for (const long long i : manipulated) constrained[static_cast<std::size_t>(i)] = 1;
  out.jump = worstJumpRatio(s, phi, constrained, 4 * spacing);
  std::printf(
      "%s: split %zu (largest stretch %.2f), torn %zu, worst field jump %.2fx the local gradient, "
      "clusters %zu\n",
      name, out.split, out.stretch, out.torn, out.jump, r.report.clusters);
#ifndef HGD_TEST_BEFORE
  // The report measures the same thing on its own pairs (the mesh's edges, else the graph):
  // on clouds the graph must hold no pair across a thin gap, which would come apart and be
  // called a split (at the rim of a sheet whose layers are a third of a spacing apart, the
  // filter's old 9 degrees kept pairs 7.6 degrees out of the plane: 8 false split points).
  EXPECT_EQ(r.report.surface.split_points, out.split);
  std::printf("  the report: %zu split points, largest stretch %.2f\n", r.report.surface.split_points,
              r.report.surface.max_stretch);
  EXPECT_EQ(mentions(r.report.warnings, "the surface is pulled apart at"), r.report.surface.split_points > 0);
#endif
  return out;
}

// Sharp ridges (the normal turning past 90 degrees at every crest) neither crease the field
// nor split the surface: as a cloud with normals and as a clean mesh.
TEST(Creases, SawtoothRidgesStayContinuous) {
  Surface s = sawtooth();
  shuffle(s, 5);
  const std::vector<long long> fixed = where(s, [](const V3& x) { return x.x() < 0.1f; });
  const std::vector<long long> manipulated = where(s, [](const V3& x) { return x.x() > 0.9f; });
  const Eigen::Vector3d from(1.0, 0.15, 0.0), to(1.0, 0.3, 0.35);
  for (const bool mesh : {false, true}) {
    SCOPED_TRACE(mesh ? "mesh" : "cloud with normals");
    const CreaseRun c =
        creaseCase(mesh ? "sawtooth mesh" : "sawtooth cloud", s, fixed, manipulated, from, to, mesh, 0.01f);
    EXPECT_EQ(c.split, 0u);
    EXPECT_EQ(c.torn, 0u);
    EXPECT_LE(c.jump, 3.0);
    EXPECT_LE(c.stretch, 1.6);
  }
}

// A cube's surface on a lattice, each edge point with the normal of one of its faces (as a
// scanner's estimate would pick either side): normals turn by 90 degrees across every edge.
Surface cube(int cells) {
  Surface s;
  std::vector<int> id(static_cast<std::size_t>((cells + 1) * (cells + 1) * (cells + 1)), -1);
  auto at = [&](int i, int j, int k) -> int& {
    return id[static_cast<std::size_t>((i * (cells + 1) + j) * (cells + 1) + k)];
  };
  for (int i = 0; i <= cells; ++i)
    for (int j = 0; j <= cells; ++j)
      for (int k = 0; k <= cells; ++k) {
        const int g[3] = {i, j, k};
        V3 n = V3::Zero();
        for (int a = 0; a < 3 && n.isZero(); ++a)
          if (g[a] == 0 || g[a] == cells) n[a] = g[a] == 0 ? -1.0f : 1.0f;
        if (n.isZero()) continue;
        at(i, j, k) = static_cast<int>(s.size());
        s.p.push_back(V3(static_cast<float>(i), static_cast<float>(j), static_cast<float>(k)) /
                      static_cast<float>(cells));
        s.n.push_back(n);
      }
  for (int i = 0; i <= cells; ++i)
    for (int j = 0; j <= cells; ++j)
      for (int k = 0; k <= cells; ++k) {
        if (at(i, j, k) < 0) continue;
        if (i < cells && at(i + 1, j, k) >= 0) s.pairs.emplace_back(at(i, j, k), at(i + 1, j, k));
        if (j < cells && at(i, j + 1, k) >= 0) s.pairs.emplace_back(at(i, j, k), at(i, j + 1, k));
        if (k < cells && at(i, j, k + 1) >= 0) s.pairs.emplace_back(at(i, j, k), at(i, j, k + 1));
      }
  return s;
}

// A cube with sharp edges, one corner fixed, the opposite corner dragged out and aside.
TEST(Creases, CubeDraggedAtACornerStaysWhole) {
  Surface s = cube(50);
  shuffle(s, 9);
  const std::vector<long long> fixed = where(s, [](const V3& x) { return x.norm() < 0.3f; });
  const std::vector<long long> manipulated =
      where(s, [](const V3& x) { return (x - V3(1, 1, 1)).norm() < 0.2f; });
  const CreaseRun c =
      creaseCase("cube", s, fixed, manipulated, {1.0, 1.0, 1.0}, {1.3, 1.25, 0.85}, false, 0.02f);
  EXPECT_EQ(c.split, 0u);
  EXPECT_EQ(c.torn, 0u);
  EXPECT_LE(c.jump, 3.0);
}

// A thin sheet folded back on itself: two layers under a sample spacing apart (spacing
// 0.01), joined along the fold at x = 1. A handle on each layer at the open end: the top one
// lifted, the bottom one fixed. kNN joins the layers everywhere; the filter must cut every
// such pair (else the field leaks across and the top drags the bottom) and keep the fold (else
// the sheet tears there). The field is checked against the harmonic function of the unfolded
// strip, linear in the distance along the surface from the top handle to the bottom one.
void foldedSheet(float gap) {
  SCOPED_TRACE("gap " + std::to_string(gap));
  const float h = 0.01f;
  const int nx = 101, ny = 41;
  Surface s;
  std::vector<int> top(static_cast<std::size_t>(nx * ny)), bottom(top.size()),
      fold(static_cast<std::size_t>(ny));
  std::vector<float> along;  // distance along the surface from the top handle's edge (x = 0.1)
  for (int layer = 0; layer < 2; ++layer)
    for (int i = 0; i < nx; ++i)
      for (int j = 0; j < ny; ++j) {
        const float x = static_cast<float>(i) * h, y = static_cast<float>(j) * h;
        (layer ? bottom : top)[static_cast<std::size_t>(i * ny + j)] = static_cast<int>(s.size());
        s.p.push_back(V3(x, y, layer ? -gap / 2 : gap / 2));
        s.n.push_back(V3(0, 0, layer ? -1.0f : 1.0f));
        const float fold_len = 2 * std::sqrt(2.0f) * gap / 2;
        along.push_back(layer ? 0.9f + fold_len + (1.0f - x) : x - 0.1f);
      }
  for (int j = 0; j < ny; ++j) {
    fold[static_cast<std::size_t>(j)] = static_cast<int>(s.size());
    s.p.push_back(V3(1.0f + gap / 2, static_cast<float>(j) * h, 0));
    s.n.push_back(V3(1, 0, 0));
    along.push_back(0.9f + std::sqrt(2.0f) * gap / 2);
  }
  for (const auto* layer : {&top, &bottom})
    for (int i = 0; i < nx; ++i)
      for (int j = 0; j < ny; ++j) {
        const int a = (*layer)[static_cast<std::size_t>(i * ny + j)];
        if (i + 1 < nx) s.pairs.emplace_back(a, (*layer)[static_cast<std::size_t>((i + 1) * ny + j)]);
        if (j + 1 < ny) s.pairs.emplace_back(a, (*layer)[static_cast<std::size_t>(i * ny + j + 1)]);
      }
  for (int j = 0; j < ny; ++j) {
    const int f = fold[static_cast<std::size_t>(j)];
    s.pairs.emplace_back(top[static_cast<std::size_t>((nx - 1) * ny + j)], f);
    s.pairs.emplace_back(bottom[static_cast<std::size_t>((nx - 1) * ny + j)], f);
    if (j + 1 < ny) s.pairs.emplace_back(f, fold[static_cast<std::size_t>(j + 1)]);
  }
  for (auto& e : s.pairs)
    if (e.first > e.second) std::swap(e.first, e.second);
  const std::vector<long long> manipulated =
      where(s, [](const V3& x) { return x.x() < 0.1f - 1e-4f && x.z() > 0; });
  const std::vector<long long> fixed =
      where(s, [](const V3& x) { return x.x() < 0.1f - 1e-4f && x.z() < 0; });
  // The expected field: 1 - (distance along the surface) / (the whole way to the other handle).
  const float total = along[static_cast<std::size_t>(bottom[static_cast<std::size_t>(10 * ny)])];
  const std::vector<float> phi = field(s, fixed, manipulated);
  double worst = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const float expected = std::clamp(1.0f - along[i] / total, 0.0f, 1.0f);
    worst = std::max(worst, static_cast<double>(std::abs(phi[i] - expected)));
  }
  const CreaseRun c =
      creaseCase("folded sheet", s, fixed, manipulated, {0.0, 0.2, gap / 2}, {-0.1, 0.2, 0.3}, false, h);
  std::printf("folded sheet, gap %.3f: the field differs from the unfolded strip's by %.3f at most\n", gap,
              worst);
  EXPECT_LE(worst, 0.03);
  EXPECT_EQ(c.split, 0u);
  EXPECT_LE(c.jump, 3.0);
}

// A mesh folded flat on itself with no radius at all: two layers 0.005 apart (half a spacing),
// joined along x = 1 by one row of faces straight across the gap, each vertex with its own
// layer's normal (+z on top, -z below), as a file gives them. The fold's edges are then pairs
// across a thin gap by the filter's rule, but they are mesh edges, and mesh edges are never
// dropped: the field runs round the fold as on the unfolded strip, and the fold holds. Were
// they dropped, the top layer would hold the manipulated handle alone and move rigidly, and
// the fold would tear.
TEST(Creases, MeshEdgesAcrossAFoldAreNeverDropped) {
  const float h = 0.01f, gap = 0.005f;
  const int nx = 101, ny = 21;
  Surface s;
  std::vector<float> along;  // distance along the surface from the top handle's edge (x = 0.1)
  auto id = [&](int layer, int i, int j) { return (layer * nx + i) * ny + j; };
  for (int layer = 0; layer < 2; ++layer)
    for (int i = 0; i < nx; ++i)
      for (int j = 0; j < ny; ++j) {
        const float x = static_cast<float>(i) * h;
        s.p.push_back(V3(x, static_cast<float>(j) * h, layer ? -gap / 2 : gap / 2));
        s.n.push_back(V3(0, 0, layer ? -1.0f : 1.0f));
        along.push_back(layer ? 0.9f + gap + (1.0f - x) : x - 0.1f);
      }
  auto quad = [&](int a, int b, int c, int d) {
    for (const auto& tri : {std::array<int, 3>{a, b, c}, std::array<int, 3>{a, c, d}}) {
      pcl::Vertices f;
      f.vertices.assign(tri.begin(), tri.end());
      s.faces.push_back(f);
    }
    for (const auto& [u, v] : {std::pair<int, int>{a, b}, {b, c}, {c, d}, {d, a}})
      s.pairs.emplace_back(std::min(u, v), std::max(u, v));
  };
  for (int layer = 0; layer < 2; ++layer)
    for (int i = 0; i + 1 < nx; ++i)
      for (int j = 0; j + 1 < ny; ++j)
        quad(id(layer, i, j), id(layer, i + 1, j), id(layer, i + 1, j + 1), id(layer, i, j + 1));
  for (int j = 0; j + 1 < ny; ++j)  // the fold: straight across the gap
    quad(id(0, nx - 1, j), id(1, nx - 1, j), id(1, nx - 1, j + 1), id(0, nx - 1, j + 1));
  std::sort(s.pairs.begin(), s.pairs.end());
  s.pairs.erase(std::unique(s.pairs.begin(), s.pairs.end()), s.pairs.end());
  const std::vector<long long> manipulated =
      where(s, [](const V3& x) { return x.x() < 0.1f - 1e-4f && x.z() > 0; });
  const std::vector<long long> fixed =
      where(s, [](const V3& x) { return x.x() < 0.1f - 1e-4f && x.z() < 0; });
  const Eigen::Vector3d from(0.0, 0.1, gap / 2), to(-0.1, 0.1, 0.3);
  const Outcome r = deform(s, fixed, manipulated, from, to, true, true);
  const double drag = (to - from).norm();
  const Split split = splitPoints(s, r.deformed, drag);
  // The field, against the unfolded strip's (linear in the distance along the surface).
  hgd::Geometry g = hgd::extractGeometry(toShape(s, true, true));
  hgd::Handles hs;
  hs.fixed.emplace_back();
  for (const long long i : fixed) hs.fixed[0].push_back(g.finite_index[static_cast<std::size_t>(i)]);
  for (const long long i : manipulated) hs.manipulated.push_back(g.finite_index[static_cast<std::size_t>(i)]);
  hgd::Deformer d(g, hs);
  const float total = along[static_cast<std::size_t>(id(1, 10, 0))];
  double worst = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const float expected = std::clamp(1.0f - along[i] / total, 0.0f, 1.0f);
    worst = std::max(worst, static_cast<double>(
                                std::abs(d.field()[static_cast<std::size_t>(g.finite_index[i])] - expected)));
  }
  std::printf(
      "fold as a mesh: field off the unfolded strip's by %.3f at most; split %zu (stretch %.2f); report "
      "%zu\n",
      worst, split.points, split.max_stretch, r.report.surface.split_points);
  EXPECT_LE(worst, 0.03);
  EXPECT_EQ(split.points, 0u);
  EXPECT_EQ(r.report.surface.split_points, 0u);
  EXPECT_EQ(r.report.unreachable, 0u);
  EXPECT_EQ(r.report.pieces.rigid_points, 0u);
}

// Half a spacing apart, and a third (the pairs across the gap then lie within 17 degrees of
// the tangent plane: correct normals must not be taken for inconsistent ones and re-oriented
// across the gap, which would switch the filter off).
TEST(Creases, FoldedSheetNeitherLeaksNorTears) {
  foldedSheet(0.005f);
  foldedSheet(0.003f);
}

}  // namespace

namespace {

// Three nested tori (closed, so no rim reaches further than the rest), 0.85 spacings apart,
// normals alternating (two thin gaps): the outer two are out of each other's kNN reach, the
// middle one within reach of both, and every pair between them is across a thin gap. The
// middle torus holds no handle and is joined back to the surface, but to one side only: the
// outer torus's manipulated handle must not reach the inner torus's fixed one through it (each
// then holds one handle only and keeps its value, 1 or 0, throughout).
TEST(Creases, NestedLayersStayApartThroughALayerBetween) {
  Surface s;
  const float major = 20.0f;
  const int nu = 126;
  for (int layer = 0; layer < 3; ++layer) {
    const float minor = 4.0f + 0.85f * static_cast<float>(layer);
    const int nv = static_cast<int>(std::lround(2 * M_PI * minor));
    for (int i = 0; i < nu; ++i)
      for (int j = 0; j < nv; ++j) {
        const float u = 2 * static_cast<float>(M_PI) * static_cast<float>(i) / static_cast<float>(nu);
        const float v = 2 * static_cast<float>(M_PI) * static_cast<float>(j) / static_cast<float>(nv);
        const V3 out(std::cos(v) * std::cos(u), std::cos(v) * std::sin(u), std::sin(v));
        s.p.push_back(V3(major * std::cos(u), major * std::sin(u), 0) + minor * out);
        s.n.push_back(layer == 1 ? V3(-out) : out);
      }
  }
  shuffle(s, 4);
  // The layer of a point: its distance from the torus's core circle.
  const auto layer = [major](const V3& x) {
    const float d = V3(x.x(), x.y(), 0).norm() - major;
    const float r = std::sqrt(d * d + x.z() * x.z());
    return static_cast<int>(std::lround((r - 4.0f) / 0.85f));
  };
  const std::vector<long long> fixed = where(s, [&](const V3& x) { return layer(x) == 0 && x.x() > 15; });
  const std::vector<long long> manipulated =
      where(s, [&](const V3& x) { return layer(x) == 2 && x.x() > 15; });
  const std::vector<float> phi = field(s, fixed, manipulated);
  double top = 0, bottom = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (layer(s.p[i]) == 2) top = std::max(top, std::abs(1.0 - phi[i]));
    if (layer(s.p[i]) == 0) bottom = std::max(bottom, static_cast<double>(std::abs(phi[i])));
  }
  std::printf("nested tori: the outer one's field departs from 1 by %.3g, the inner one's from 0 by %.3g\n",
              top, bottom);
  EXPECT_LE(top, 1e-6);
  EXPECT_LE(bottom, 1e-6);
}

}  // namespace

namespace {

// A small scan (under the 4,000-point sample, so every point is a sample point) with strays
// around it: the strays are found, and none is a sample point or a cluster member (an affine
// fit through a stray far off the surface would tilt its cluster).
TEST(Scans, SmallCloudKeepsStraysOutOfTheSample) {
  Surface s = tube(1.0f, 0.1f, 0.02f);
  const std::size_t surface = s.size();
  std::mt19937 rng(8);
  std::uniform_real_distribution<float> u(-0.4f, 0.4f);
  for (int k = 0; k < 30; ++k) {
    s.p.push_back(V3(0.5f + u(rng), 0.25f + std::abs(u(rng)), u(rng)));  // above the tube, well off it
    s.n.push_back(V3(0, 1, 0));
  }
  const hgd::Geometry g = hgd::extractGeometry(toShape(s, true, false));
  hgd::Handles h;
  h.fixed.emplace_back();
  for (std::size_t i = 0; i < g.size(); ++i) {
    const double x = g.world(i).x();
    if (static_cast<std::size_t>(g.raw_index[i]) < surface && x < 0.05)
      h.fixed[0].push_back(static_cast<int>(i));
    if (static_cast<std::size_t>(g.raw_index[i]) < surface && x > 0.95)
      h.manipulated.push_back(static_cast<int>(i));
  }
  hgd::Deformer d(g, h);
  const auto stray = [&](int i) {
    return static_cast<std::size_t>(g.raw_index[static_cast<std::size_t>(i)]) >= surface;
  };
  std::size_t flagged = 0, sampled = 0, members = 0;
  for (std::size_t i = 0; i < g.size(); ++i)
    flagged +=
        stray(static_cast<int>(i)) && !d.surfaceGraph().outliers().empty() && d.surfaceGraph().outliers()[i];
  for (const int i : d.clustering().sample) sampled += stray(i);
  for (const auto& cl : d.clustering().clusters)
    for (const int i : cl.members) members += stray(i);
  std::printf("small cloud: %zu of 30 strays found; %zu in the sample, %zu in clusters\n", flagged, sampled,
              members);
  EXPECT_EQ(flagged, 30u);
  EXPECT_EQ(sampled, 0u);
  EXPECT_EQ(members, 0u);
}

}  // namespace
