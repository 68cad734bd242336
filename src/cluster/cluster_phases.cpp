// Harmonic-guided clustering, phase by phase (docs/method.md): every point placed in a band or
// a gap of the harmonic field; handle clusters; bones (range clusters); isoclusters, one per
// contour of each isovalue traced on the surface sample; the two bracketing clusters of every
// point spread through its gap; what is still unlabelled, outliers and pieces without a handle;
// barycentres, blend factors and adjacency. buildClusters() runs the phases in that order.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <memory>
#include <numeric>

#include "hgdeform/cluster/clustering.h"
#include "util/parallel.h"
#include "util/phases.h"
#include "util/timer.h"

namespace hgd {

namespace {
// A point's role in the clustering: free, on the manipulated handle, in a part no handle
// reaches, or (k >= 0) on fixed handle k.
constexpr int kFree = -1, kManipulatedRole = -2, kUnreachable = -3;

// The pairs body(i, add) adds for every i in [0, n), gathered on every thread, in no particular
// order; add(a, b) keeps a run of one pair once (neighbouring points mostly repeat the last).
template <typename Body>
std::vector<std::pair<int, int>> gatherPairs(long long n, Body&& body) {
  std::vector<std::pair<int, int>> pairs;
#pragma omp parallel if (n > kParallelMinCostly)
  {
    std::vector<std::pair<int, int>> mine;
    const auto add = [&mine](int a, int b) {
      if (mine.empty() || mine.back() != std::make_pair(a, b)) mine.emplace_back(a, b);
    };
#pragma omp for schedule(static) nowait
    for (long long i = 0; i < n; ++i) body(static_cast<std::size_t>(i), add);
#pragma omp critical
    pairs.insert(pairs.end(), mine.begin(), mine.end());
  }
  return pairs;
}

struct SampleGraph {
  std::vector<int> sites;                    ///< site -> point
  NeighborGraph graph;                       ///< over sites
  std::vector<int> cell_start, cell_points;  ///< site s owns cell_points[cell_start[s] .. [s+1])
};

SampleGraph sampleGraph(const NeighborGraph& graph, const std::vector<int>& sample,
                        const std::vector<int>& role, const std::vector<char>& outlier) {
  SampleGraph sg;
  const std::size_t n = graph.size();
  // Breadth first, a level at a time in parallel: a point first met at level d takes the
  // smallest site among its neighbours at level d - 1 (an atomic minimum), so the cells do not
  // depend on the threads.
  std::unique_ptr<std::atomic<int>[]> cell_of(new std::atomic<int>[n]), level(new std::atomic<int>[n]);
  const long long nn = static_cast<long long>(n);
#pragma omp parallel for schedule(static) if (nn > kParallelMin)
  for (long long i = 0; i < nn; ++i) {
    cell_of[i].store(std::numeric_limits<int>::max(), std::memory_order_relaxed);
    level[i].store(-1, std::memory_order_relaxed);
  }
  std::vector<int> frontier;
  for (int s : sample) {
    const auto x = static_cast<std::size_t>(s);
    if (role[x] == kUnreachable || outlier[x] || level[x].load(std::memory_order_relaxed) >= 0) continue;
    cell_of[x].store(static_cast<int>(sg.sites.size()), std::memory_order_relaxed);
    level[x].store(0, std::memory_order_relaxed);
    sg.sites.push_back(s);
    frontier.push_back(s);
  }
  for (int d = 0; !frontier.empty(); ++d) {
    std::vector<int> next;
    const long long nf = static_cast<long long>(frontier.size());
#pragma omp parallel if (nf > 4096)
    {
      std::vector<int> mine;
#pragma omp for schedule(static) nowait
      for (long long f = 0; f < nf; ++f) {
        const auto x = static_cast<std::size_t>(frontier[static_cast<std::size_t>(f)]);
        const int cx = cell_of[x].load(std::memory_order_relaxed);
        for (const int* j = graph.begin(x); j != graph.end(x); ++j) {
          const auto u = static_cast<std::size_t>(*j);
          if (outlier[u] || role[u] == kUnreachable) continue;
          int lv = level[u].load(std::memory_order_relaxed);
          if (lv < 0 && level[u].compare_exchange_strong(lv, d + 1, std::memory_order_relaxed)) {
            mine.push_back(*j);
            lv = d + 1;
          }
          if (lv != d + 1) continue;
          int cur = cell_of[u].load(std::memory_order_relaxed);
          while (cx < cur && !cell_of[u].compare_exchange_weak(cur, cx, std::memory_order_relaxed)) {
          }
        }
      }
#pragma omp critical
      next.insert(next.end(), mine.begin(), mine.end());
    }
    frontier.swap(next);
  }
  std::vector<int> cell(n);
#pragma omp parallel for schedule(static) if (nn > kParallelMin)
  for (long long i = 0; i < nn; ++i) {
    const int c = cell_of[i].load(std::memory_order_relaxed);
    cell[static_cast<std::size_t>(i)] = c == std::numeric_limits<int>::max() ? -1 : c;
  }
  const std::size_t ns = sg.sites.size();
  // Cell pairs across edges, per thread, then made one graph (addEdges sorts each site's row
  // and drops repeats: a sort of every pair first cost more than the rest of the phase).
  const std::vector<std::pair<int, int>> pairs = gatherPairs(nn, [&](std::size_t i, auto&& add) {
    const int a = cell[i];
    if (a < 0) return;
    for (const int* j = graph.begin(i); j != graph.end(i); ++j) {
      const int b = cell[static_cast<std::size_t>(*j)];
      if (b > a) add(a, b);
    }
  });
  NeighborGraph empty;
  empty.offsets.assign(ns + 1, 0);
  sg.graph = addEdges(empty, pairs);
  // Cells as lists (counting sort by site, in point order).
  sg.cell_start.assign(ns + 1, 0);
  for (std::size_t i = 0; i < n; ++i)
    if (cell[i] >= 0) ++sg.cell_start[static_cast<std::size_t>(cell[i]) + 1];
  for (std::size_t s = 0; s < ns; ++s) sg.cell_start[s + 1] += sg.cell_start[s];
  sg.cell_points.resize(static_cast<std::size_t>(sg.cell_start[ns]));
  std::vector<int> fill(sg.cell_start.begin(), sg.cell_start.end() - 1);
  for (std::size_t i = 0; i < n; ++i)
    if (cell[i] >= 0)
      sg.cell_points[static_cast<std::size_t>(fill[static_cast<std::size_t>(cell[i])]++)] =
          static_cast<int>(i);
  return sg;
}

// The state the phases share: the inputs, and per point its role, band or gap, and its two
// bracketing clusters (lower: the one below its harmonic value, upper: above).
struct ClusterPhases {
  ClusterPhases(const pcl::PointCloud<pcl::PointXYZ>& points_in, const NeighborGraph& graph_in,
                const std::vector<float>& phi_in, const Handles& handles_in,
                const std::vector<int>& unreachable_in, const std::vector<int>& sample_in,
                const ClusterOptions& options_in, const std::vector<int>& follow_in,
                const std::vector<char>& outlier_in)
      : points(points_in),
        graph(graph_in),
        phi(phi_in),
        handles(handles_in),
        unreachable(unreachable_in),
        sample(sample_in),
        options(options_in),
        follow(follow_in),
        outlier(outlier_in) {}

  const pcl::PointCloud<pcl::PointXYZ>& points;
  const NeighborGraph& graph;
  const std::vector<float>& phi;
  const Handles& handles;
  const std::vector<int>& unreachable;
  const std::vector<int>& sample;
  const ClusterOptions& options;
  const std::vector<int>& follow;
  const std::vector<char>& outlier;
  Clustering c;
  const std::vector<Band>& bands = c.bands;
  std::size_t n = 0;
  long long nn = 0;
  int nb = 0, top = 0;
  std::vector<int> role;  // kFree, kManipulatedRole, kUnreachable, or k >= 0: fixed handle k
  std::vector<char> in_sample;
  std::vector<int> band, gap;     // band[i] = b inside band b, else gap[i] = g between g and g + 1
  std::vector<int> fixed_id;      // fixed handle -> its cluster
  std::vector<int> lower, upper;  // the two bracketing clusters of every point
  std::vector<int> lower_queue,
      upper_queue;             // seeds: lower labels spread upwards into a gap, upper downwards
  std::vector<int> copy_from;  // a point that took another's clusters takes its blend factor too

  int newCluster(ClusterKind kind, int lvl, int handle, double value) {
    Cluster cl;
    cl.id = static_cast<int>(c.clusters.size());
    cl.kind = kind;
    cl.level = lvl;
    cl.harmonic_value = value;
    cl.handle = handle;
    c.clusters.push_back(cl);
    return cl.id;
  }

  void placePoints() {
    role.assign(n, kFree);
    for (int i : unreachable) role[static_cast<std::size_t>(i)] = kUnreachable;
    for (std::size_t k = 0; k < handles.fixed.size(); ++k)
      for (int i : handles.fixed[k]) role[static_cast<std::size_t>(i)] = static_cast<int>(k);
    for (int i : handles.manipulated) role[static_cast<std::size_t>(i)] = kManipulatedRole;
    in_sample.assign(n, 0);
    for (int s : sample) in_sample[static_cast<std::size_t>(s)] = 1;

    // Where each point lies: inside band b (band[i] = b, gap[i] = -1), or in the gap between
    // bands g and g + 1 (band[i] = -1, gap[i] = g). Handle points lie in their handle's band.
    band.assign(n, -1);
    gap.assign(n, -1);
    std::vector<double> bounds;  // lo of every band, for the search
    for (const auto& b : bands) bounds.push_back(b.lo);
    for (std::size_t i = 0; i < n; ++i) {
      if (role[i] == kUnreachable) continue;
      if (role[i] >= 0) {
        band[i] = 0;
        continue;
      }
      if (role[i] == kManipulatedRole) {
        band[i] = top;
        continue;
      }
      const double v = phi[i];
      // The last band whose lo <= v (skipping the fixed band, which holds handle points only).
      int b =
          static_cast<int>(std::upper_bound(bounds.begin() + 1, bounds.end() - 1, v) - bounds.begin()) - 1;
      const Band& bb = bands[static_cast<std::size_t>(b)];
      if (bb.kind == Band::Kind::Range && v > bb.lo && v < bb.hi)
        band[i] = b;
      else
        gap[i] = (bb.kind == Band::Kind::Range && v >= bb.hi) || bb.kind != Band::Kind::Range ? b : b - 1;
      if (gap[i] >= top) gap[i] = top - 1;
    }
  }

  void handleClusters() {
    // Handle clusters: the sample points of each handle (all its points if it has fewer than 3).
    auto handleMembers = [&](const std::vector<int>& idx, Cluster& cl) {
      for (int i : idx)
        if (in_sample[static_cast<std::size_t>(i)]) cl.members.push_back(i);
      for (std::size_t k = 0; k < idx.size() && cl.members.size() < 3; ++k)
        if (!in_sample[static_cast<std::size_t>(idx[k])]) cl.members.push_back(idx[k]);
    };
    fixed_id.assign(handles.fixed.size(), -1);
    for (std::size_t k = 0; k < handles.fixed.size(); ++k) {
      fixed_id[k] = newCluster(ClusterKind::Fixed, 0, static_cast<int>(k), 0.0);
      handleMembers(handles.fixed[k], c.clusters.back());
    }
    c.manipulated = newCluster(ClusterKind::Manipulated, top, -1, 1.0);
    handleMembers(handles.manipulated, c.clusters.back());
  }

  void startLabels() {
    lower.assign(n, -1);
    upper.assign(n, -1);
    for (std::size_t i = 0; i < n; ++i) {
      if (role[i] >= 0) lower[i] = upper[i] = fixed_id[static_cast<std::size_t>(role[i])];
      if (role[i] == kManipulatedRole) lower[i] = upper[i] = c.manipulated;
    }
  }

  // Bones: a range cluster per connected piece of a range band.
  void bones() {
    std::vector<int> stack, members;
    for (std::size_t s = 0; s < n; ++s) {
      if (band[s] < 0 || lower[s] >= 0 || bands[static_cast<std::size_t>(band[s])].kind != Band::Kind::Range)
        continue;
      const int b = band[s];
      const int id = newCluster(ClusterKind::Range, b, -1, 0.0);
      double sum_phi = 0;
      members.clear();
      lower[s] = upper[s] = id;
      stack.assign(1, static_cast<int>(s));
      while (!stack.empty()) {
        const auto x = static_cast<std::size_t>(stack.back());
        stack.pop_back();
        members.push_back(static_cast<int>(x));
        sum_phi += phi[x];
        for (const int* j = graph.begin(x); j != graph.end(x); ++j) {
          const auto u = static_cast<std::size_t>(*j);
          if (band[u] == b && lower[u] < 0) {
            lower[u] = upper[u] = id;
            stack.push_back(static_cast<int>(u));
          }
        }
      }
      Cluster& cl = c.clusters.back();
      cl.harmonic_value = sum_phi / static_cast<double>(members.size());
      for (int m : members)
        if (in_sample[static_cast<std::size_t>(m)]) cl.members.push_back(m);
      for (std::size_t k = 0; k < members.size() && cl.members.size() < 3; ++k)
        if (!in_sample[static_cast<std::size_t>(members[k])]) cl.members.push_back(members[k]);
    }
  }

  void seedFromBands() {
    // Points inside interval bands seed the gaps on either side.
    for (std::size_t i = 0; i < n; ++i) {
      if (band[i] < 0 || lower[i] < 0) continue;
      lower_queue.push_back(static_cast<int>(i));
      upper_queue.push_back(static_cast<int>(i));
    }
  }

  void isoclusters() {
    // Isolines, traced on the surface sample rather than on every point, so that the clusters
    // do not depend on the density or the noise of the cloud: every sample point (a site) owns
    // the points nearest it along the graph (its cell), two sites are adjacent when their cells
    // touch, and an isoline is the sites at either end of a site pair that crosses the isovalue.
    // Each connected piece of it (a contour) is one isocluster. Cells follow the graph, so two
    // branches at the same harmonic value stay apart as they are on the surface.
    const SampleGraph sg = sampleGraph(graph, sample, role, outlier);
    std::vector<int> iso_bands;
    for (int b = 0; b < nb; ++b)
      if (bands[static_cast<std::size_t>(b)].kind == Band::Kind::Iso) iso_bands.push_back(b);
    const std::size_t ns = sg.sites.size();
    std::vector<int> on_line(ns, -1), seen(ns, -1), trace, piece;
    for (int b : iso_bands) {
      const double v = bands[static_cast<std::size_t>(b)].lo;
      auto sitePhi = [&](std::size_t s) {
        return static_cast<double>(phi[static_cast<std::size_t>(sg.sites[s])]);
      };
      for (std::size_t s = 0; s < ns; ++s)
        for (const int* t = sg.graph.begin(s); t != sg.graph.end(s); ++t) {
          const double a = sitePhi(s), e = sitePhi(static_cast<std::size_t>(*t));
          if ((a < v && v <= e) || (e < v && v <= a)) {
            on_line[s] = b;
            break;
          }
        }
      for (std::size_t seed = 0; seed < ns; ++seed) {
        if (on_line[seed] != b || seen[seed] == b) continue;
        piece.clear();
        seen[seed] = b;
        trace.assign(1, static_cast<int>(seed));
        while (!trace.empty()) {
          const auto x = static_cast<std::size_t>(trace.back());
          trace.pop_back();
          piece.push_back(static_cast<int>(x));
          for (const int* t = sg.graph.begin(x); t != sg.graph.end(x); ++t) {
            const auto u = static_cast<std::size_t>(*t);
            if (on_line[u] == b && seen[u] != b) {
              seen[u] = b;
              trace.push_back(static_cast<int>(u));
            }
          }
        }
        // Fewer sites than an affine fit needs: a tip just crossing the isovalue, left to its
        // neighbours' clusters.
        if (static_cast<int>(piece.size()) < options.min_contour) continue;
        const int id = newCluster(ClusterKind::Iso, b, -1, v);
        Cluster& cl = c.clusters.back();
        std::sort(piece.begin(), piece.end());
        for (int site : piece) cl.members.push_back(sg.sites[static_cast<std::size_t>(site)]);
        // The contour's cells seed the gaps on either side of it.
        for (int site : piece)
          for (int m = sg.cell_start[static_cast<std::size_t>(site)];
               m < sg.cell_start[static_cast<std::size_t>(site) + 1]; ++m) {
            const int pt = sg.cell_points[static_cast<std::size_t>(m)];
            const auto x = static_cast<std::size_t>(pt);
            if (gap[x] == b && lower[x] < 0) {
              lower[x] = id;
              lower_queue.push_back(pt);
            } else if (gap[x] == b - 1 && upper[x] < 0) {
              upper[x] = id;
              upper_queue.push_back(pt);
            }
          }
      }
    }
  }

  void spreadIntoGaps() {
    // Nearest cluster along the surface within each gap: a lower label from band b spreads into
    // gap b, an upper label from band b into gap b - 1.
    // The two spreads are independent (each writes its own labels): one thread each.
    auto spread = [&](const std::vector<int>& seeds, std::vector<int>& label, int offset) {
      std::vector<int> q(seeds);
      for (std::size_t head = 0; head < q.size(); ++head) {
        const auto x = static_cast<std::size_t>(q[head]);
        if (outlier[x]) continue;  // an outlier takes a label but passes it on to nobody
        const int g = c.clusters[static_cast<std::size_t>(label[x])].level - offset;
        for (const int* j = graph.begin(x); j != graph.end(x); ++j) {
          const auto u = static_cast<std::size_t>(*j);
          if (label[u] < 0 && gap[u] == g) {
            label[u] = label[x];
            q.push_back(static_cast<int>(u));
          }
        }
      }
    };
#pragma omp parallel sections if (nn > kParallelMin)
    {
#pragma omp section
      spread(lower_queue, lower, 0);
#pragma omp section
      spread(upper_queue, upper, 1);
    }
  }

  void labelTheRest() {
    // A gap region that meets only one side (a part touching one kind of handle only) takes
    // that side for both.
    for (std::size_t i = 0; i < n; ++i) {
      if (lower[i] < 0) lower[i] = upper[i];
      if (upper[i] < 0) upper[i] = lower[i];
    }
    // Reached points still without clusters (a region whose only contour was too short, cut
    // off from its gap by it) take those of the nearest labelled point along the graph: first
    // through inliers, then through outliers too.
    copy_from.assign(n, -1);
    bool unlabelled = false;
    for (std::size_t i = 0; i < n && !unlabelled; ++i) unlabelled = lower[i] < 0 && role[i] != kUnreachable;
    for (const bool through_outliers : {false, true}) {
      if (!unlabelled) break;
      std::vector<int> q;  // labelled points next to unlabelled ones
      for (std::size_t i = 0; i < n; ++i) {
        if (lower[i] < 0 || (!through_outliers && outlier[i])) continue;
        for (const int* j = graph.begin(i); j != graph.end(i); ++j)
          if (lower[static_cast<std::size_t>(*j)] < 0 && role[static_cast<std::size_t>(*j)] != kUnreachable) {
            q.push_back(static_cast<int>(i));
            break;
          }
      }
      for (std::size_t head = 0; head < q.size(); ++head) {
        const auto x = static_cast<std::size_t>(q[head]);
        if (!through_outliers && outlier[x]) continue;
        for (const int* j = graph.begin(x); j != graph.end(x); ++j) {
          const auto u = static_cast<std::size_t>(*j);
          if (lower[u] >= 0 || role[u] == kUnreachable) continue;
          lower[u] = lower[x];
          upper[u] = upper[x];
          copy_from[u] = copy_from[x] >= 0 ? copy_from[x] : static_cast<int>(x);
          q.push_back(static_cast<int>(u));
        }
      }
    }
    // An outlier moves as the surface point it hangs from (its nearest graph neighbour that is
    // no outlier) does: a space deformation, not whatever label reached it first.
    for (std::size_t i = 0; i < n; ++i) {
      if (!outlier[i] || role[i] == kUnreachable) continue;
      int best = -1;
      float best_d = INFINITY;
      for (const int* j = graph.begin(i); j != graph.end(i); ++j) {
        const auto u = static_cast<std::size_t>(*j);
        if (outlier[u] || lower[u] < 0) continue;
        const float d = (points[u].getVector3fMap() - points[i].getVector3fMap()).squaredNorm();
        if (d < best_d) {
          best_d = d;
          best = *j;
        }
      }
      if (best < 0) continue;
      const auto b = static_cast<std::size_t>(best);
      lower[i] = lower[b];
      upper[i] = upper[b];
      copy_from[i] = copy_from[b] >= 0 ? copy_from[b] : best;
    }
  }

  // Points that touch no handle: those that follow a reached point take its clusters (set
  // below, with its blend factor); the others become static clusters, one per piece.
  void piecesWithoutHandle() {
    std::vector<int> stack;
    for (std::size_t s = 0; s < n; ++s) {
      if (lower[s] >= 0) continue;
      if (follow.size() == n && follow[s] >= 0) {
        const auto t = static_cast<std::size_t>(follow[s]);
        lower[s] = lower[t];
        upper[s] = upper[t];
        copy_from[s] = copy_from[t] >= 0 ? copy_from[t] : static_cast<int>(t);
        continue;
      }
      const int id = newCluster(ClusterKind::Static, 0, -1, 0.0);
      lower[s] = upper[s] = id;
      stack.assign(1, static_cast<int>(s));
      while (!stack.empty()) {
        const auto x = static_cast<std::size_t>(stack.back());
        stack.pop_back();
        if (in_sample[x]) c.clusters.back().members.push_back(static_cast<int>(x));
        for (const int* j = graph.begin(x); j != graph.end(x); ++j) {
          const auto u = static_cast<std::size_t>(*j);
          if (lower[u] < 0) {
            lower[u] = upper[u] = id;
            stack.push_back(static_cast<int>(u));
          }
        }
      }
    }
  }

  void barycentres() {
    for (auto& cl : c.clusters) {
      std::sort(cl.members.begin(), cl.members.end());
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (int i : cl.members) sum += points[static_cast<std::size_t>(i)].getVector3fMap().cast<double>();
      if (!cl.members.empty()) cl.barycentre = sum / static_cast<double>(cl.members.size());
    }
  }

  void blendFactors() {
    // Blend factors (eq. 1): a gap point's place between the facing ends of its two bands.
    c.alpha.assign(n, 0.0f);
    c.nearest.resize(n);
#pragma omp parallel for schedule(dynamic, kDynamicChunkCostly) if (nn > kParallelMinCostly)
    for (long long ii = 0; ii < nn; ++ii) {
      const auto i = static_cast<std::size_t>(ii);
      if (gap[i] >= 0 && lower[i] != upper[i]) {
        const double a = bands[static_cast<std::size_t>(gap[i])].hi,
                     b = bands[static_cast<std::size_t>(gap[i]) + 1].lo;
        c.alpha[i] = b > a ? static_cast<float>(std::clamp((phi[i] - a) / (b - a), 0.0, 1.0)) : 0.0f;
      }
    }
    // In order (a point can copy from one that copied before it: an outlier that passed a label on).
    for (std::size_t i = 0; i < n; ++i) {
      if (copy_from[i] >= 0) c.alpha[i] = c.alpha[static_cast<std::size_t>(copy_from[i])];
      c.nearest[i] = c.alpha[i] < 0.5f ? lower[i] : upper[i];
    }
  }

  void adjacency() {
    // Adjacent clusters: the two sides of a gap region, and interval pieces that touch.
    auto isStatic = [&](int id) {
      return c.clusters[static_cast<std::size_t>(id)].kind == ClusterKind::Static;
    };
    // Gathered on every thread, then sorted and made unique: the same list whatever the threads.
    c.adjacency = gatherPairs(nn, [&](std::size_t i, auto&& add) {
      if (lower[i] != upper[i]) add(std::min(lower[i], upper[i]), std::max(lower[i], upper[i]));
      if (band[i] < 0) return;
      for (const int* j = graph.begin(i); j != graph.end(i); ++j) {
        const auto u = static_cast<std::size_t>(*j);
        if (band[u] >= 0 && band[u] != band[i] && !isStatic(lower[i]) && !isStatic(lower[u]))
          add(std::min(lower[i], lower[u]), std::max(lower[i], lower[u]));
      }
    });
    std::sort(c.adjacency.begin(), c.adjacency.end());
    c.adjacency.erase(std::unique(c.adjacency.begin(), c.adjacency.end()), c.adjacency.end());
  }
};

}  // namespace

Clustering buildClusters(const pcl::PointCloud<pcl::PointXYZ>& points, const NeighborGraph& graph,
                         const std::vector<float>& phi, const Handles& handles,
                         const std::vector<int>& unreachable, const std::vector<int>& sample,
                         const ClusterOptions& options, const std::vector<int>& follow,
                         const std::vector<char>& outliers) {
  PhaseClock clock;
  const std::size_t n = points.size();
  const std::vector<char> no_outliers(outliers.size() == n ? 0 : n, 0);
  ClusterPhases p(points, graph, phi, handles, unreachable, sample, options, follow,
                  outliers.size() == n ? outliers : no_outliers);
  p.n = n;
  p.nn = static_cast<long long>(n);
  p.c.sample = sample;
  p.c.bands = Clustering::makeBands(phi, handles.joints, options, &p.c.notes);
  p.nb = static_cast<int>(p.c.bands.size());
  p.top = p.nb - 1;
  p.placePoints();
  clock.lap("cluster.place");
  p.handleClusters();
  p.startLabels();
  p.bones();
  p.seedFromBands();
  clock.lap("cluster.seeds");
  p.isoclusters();
  clock.lap("cluster.isoclusters");
  p.spreadIntoGaps();
  p.labelTheRest();
  p.piecesWithoutHandle();
  clock.lap("cluster.labels");
  p.barycentres();
  p.blendFactors();
  p.adjacency();
  clock.lap("cluster.blend");
  p.c.lower = std::move(p.lower);
  p.c.upper = std::move(p.upper);
  return std::move(p.c);
}

}  // namespace hgd
