#include "hgdeform/clustering.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <unordered_map>

#include "timer.h"

namespace hgd {

namespace {

struct CellKey {
  int x, y, z, c;
  bool operator==(const CellKey& o) const { return x == o.x && y == o.y && z == o.z && c == o.c; }
};
struct CellHash {
  std::size_t operator()(const CellKey& k) const {
    std::size_t h = static_cast<std::size_t>(k.x) * 73856093u;
    h ^= static_cast<std::size_t>(k.y) * 19349663u;
    h ^= static_cast<std::size_t>(k.z) * 83492791u;
    h ^= static_cast<std::size_t>(k.c) * 2654435761u;
    return h;
  }
};

// One point per occupied (cell, class): the one nearest the cell's centre.
std::vector<int> voxelSample(const pcl::PointCloud<pcl::PointXYZ>& points, const std::vector<int>& cls,
                             const Eigen::Vector3f& lo, float h) {
  std::unordered_map<CellKey, std::pair<float, int>, CellHash> best;
  best.reserve(points.size() / 4 + 16);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3f q = (points[i].getVector3fMap() - lo) / h;
    const Eigen::Vector3f f = q.array().floor();
    const CellKey key{static_cast<int>(f.x()), static_cast<int>(f.y()), static_cast<int>(f.z()), cls[i]};
    const float d = (q - f - Eigen::Vector3f::Constant(0.5f)).squaredNorm();
    auto [it, inserted] = best.try_emplace(key, d, static_cast<int>(i));
    if (!inserted && d < it->second.first) it->second = {d, static_cast<int>(i)};
  }
  std::vector<int> out;
  out.reserve(best.size());
  for (const auto& kv : best) out.push_back(kv.second.second);
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace

std::vector<int> sampleSurface(const pcl::PointCloud<pcl::PointXYZ>& points, const Handles& handles,
                               int target) {
  const std::size_t n = points.size();
  if (target <= 0 || static_cast<std::size_t>(target) >= n) {
    std::vector<int> all(n);
    std::iota(all.begin(), all.end(), 0);
    return all;
  }
  std::vector<int> cls(n, 0);
  for (std::size_t k = 0; k < handles.fixed.size(); ++k)
    for (int i : handles.fixed[k]) cls[static_cast<std::size_t>(i)] = 2 + static_cast<int>(k);
  for (int i : handles.manipulated) cls[static_cast<std::size_t>(i)] = 1;
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(INFINITY), hi = -lo;
  for (const auto& p : points) {
    lo = lo.cwiseMin(p.getVector3fMap());
    hi = hi.cwiseMax(p.getVector3fMap());
  }
  const float diag = std::max((hi - lo).norm(), 1e-12f);
  // A surface sample grows as 1/h^2: start from the diagonal and correct a few times.
  float h = diag / std::sqrt(static_cast<float>(target));
  std::vector<int> sample;
  for (int round = 0; round < 6; ++round) {
    sample = voxelSample(points, cls, lo, h);
    const double ratio = static_cast<double>(sample.size()) / target;
    if (ratio > 0.85 && ratio < 1.15) break;
    // Curves grow as 1/h, volumes as 1/h^3; the square root is a safe middle.
    h *= static_cast<float>(std::clamp(std::sqrt(ratio), 0.25, 4.0));
  }
  return sample;
}

std::vector<Band> Clustering::makeBands(const std::vector<float>& phi,
                                        const std::vector<std::vector<int>>& joints,
                                        const ClusterOptions& options, std::vector<std::string>* notes) {
  std::vector<Band> bands;
  bands.push_back({Band::Kind::Fixed, 0.0, 0.0});
  if (joints.empty()) {
    const int n = std::max(0, options.isoclusters);
    for (int l = 1; l <= n; ++l) {
      const double v = static_cast<double>(l) / (n + 1);
      bands.push_back({Band::Kind::Iso, v, v});
    }
  } else {
    // Each joint's phi range; overlapping ranges merge (two knees at the same height, say).
    std::vector<std::pair<double, double>> ranges;
    for (const auto& j : joints) {
      double lo = 1, hi = 0;
      for (int i : j) {
        lo = std::min(lo, static_cast<double>(phi[static_cast<std::size_t>(i)]));
        hi = std::max(hi, static_cast<double>(phi[static_cast<std::size_t>(i)]));
      }
      ranges.emplace_back(lo, hi);
    }
    std::vector<std::size_t> order(ranges.size());
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(),
              [&](std::size_t a, std::size_t b) { return ranges[a] < ranges[b]; });
    std::vector<std::pair<double, double>> merged;
    std::vector<std::vector<std::size_t>> members;
    for (std::size_t k : order) {
      if (!merged.empty() && ranges[k].first <= merged.back().second) {
        merged.back().second = std::max(merged.back().second, ranges[k].second);
        members.back().push_back(k);
      } else {
        merged.push_back(ranges[k]);
        members.push_back({k});
      }
    }
    if (notes)
      for (const auto& m : members)
        if (m.size() > 1) {
          std::string text = "joints";
          for (std::size_t k : m) text += " " + std::to_string(k);
          text += " span overlapping harmonic ranges and act as one joint";
          notes->push_back(text);
        }
    const int per_joint = std::max(1, options.joint_isoclusters);
    double previous = 0;  // upper end of the last band
    for (const auto& [a, b] : merged) {
      if (a > previous) bands.push_back({Band::Kind::Range, previous, a});
      for (int l = 1; l <= per_joint; ++l) {
        const double v = a + (b - a) * l / (per_joint + 1);
        if (v > bands.back().hi) bands.push_back({Band::Kind::Iso, v, v});
      }
      previous = b;
    }
    if (previous < 1) bands.push_back({Band::Kind::Range, previous, 1.0});
  }
  bands.push_back({Band::Kind::Manipulated, 1.0, 1.0});
  return bands;
}

Clustering buildClusters(const pcl::PointCloud<pcl::PointXYZ>& points, const NeighborGraph& graph,
                         const std::vector<float>& phi, const Handles& handles,
                         const std::vector<int>& unreachable, const std::vector<int>& sample,
                         const ClusterOptions& options) {
  Clustering c;
  c.sample = sample;
  const std::size_t n = points.size();
  c.bands = Clustering::makeBands(phi, handles.joints, options, &c.notes);
  const auto& bands = c.bands;
  const int nb = static_cast<int>(bands.size());
  const int top = nb - 1;

  // Roles: -1 free, -2 manipulated, -3 unreachable, k >= 0 fixed handle k.
  std::vector<int> role(n, -1);
  for (int i : unreachable) role[static_cast<std::size_t>(i)] = -3;
  for (std::size_t k = 0; k < handles.fixed.size(); ++k)
    for (int i : handles.fixed[k]) role[static_cast<std::size_t>(i)] = static_cast<int>(k);
  for (int i : handles.manipulated) role[static_cast<std::size_t>(i)] = -2;
  std::vector<char> in_sample(n, 0);
  for (int s : sample) in_sample[static_cast<std::size_t>(s)] = 1;

  // Where each point lies: inside band b (band[i] = b, gap[i] = -1), or in the gap between
  // bands g and g + 1 (band[i] = -1, gap[i] = g). Handle points lie in their handle's band.
  std::vector<int> band(n, -1), gap(n, -1);
  std::vector<double> bounds;  // lo of every band, for the search
  for (const auto& b : bands) bounds.push_back(b.lo);
  for (std::size_t i = 0; i < n; ++i) {
    if (role[i] == -3) continue;
    if (role[i] >= 0) {
      band[i] = 0;
      continue;
    }
    if (role[i] == -2) {
      band[i] = top;
      continue;
    }
    const double v = phi[i];
    // The last band whose lo <= v (skipping the fixed band, which holds handle points only).
    int b = static_cast<int>(std::upper_bound(bounds.begin() + 1, bounds.end() - 1, v) - bounds.begin()) - 1;
    const Band& bb = bands[static_cast<std::size_t>(b)];
    if (bb.kind == Band::Kind::Range && v > bb.lo && v < bb.hi)
      band[i] = b;
    else
      gap[i] = (bb.kind == Band::Kind::Range && v >= bb.hi) || bb.kind != Band::Kind::Range ? b : b - 1;
    if (gap[i] >= top) gap[i] = top - 1;
  }

  auto newCluster = [&](ClusterKind kind, int lvl, int handle, double value) {
    Cluster cl;
    cl.id = static_cast<int>(c.clusters.size());
    cl.kind = kind;
    cl.level = lvl;
    cl.phi = value;
    cl.handle = handle;
    c.clusters.push_back(cl);
    return cl.id;
  };
  // Handle clusters: the sample points of each handle (all its points if it has fewer than 3).
  auto handleMembers = [&](const std::vector<int>& idx, Cluster& cl) {
    for (int i : idx)
      if (in_sample[static_cast<std::size_t>(i)]) cl.members.push_back(i);
    for (std::size_t k = 0; k < idx.size() && cl.members.size() < 3; ++k)
      if (!in_sample[static_cast<std::size_t>(idx[k])]) cl.members.push_back(idx[k]);
  };
  std::vector<int> fixed_id(handles.fixed.size());
  for (std::size_t k = 0; k < handles.fixed.size(); ++k) {
    fixed_id[k] = newCluster(ClusterKind::Fixed, 0, static_cast<int>(k), 0.0);
    handleMembers(handles.fixed[k], c.clusters.back());
  }
  c.manipulated = newCluster(ClusterKind::Manipulated, top, -1, 1.0);
  handleMembers(handles.manipulated, c.clusters.back());

  std::vector<int> down(n, -1), up(n, -1);
  std::vector<int> down_queue, up_queue;  // seeds: down labels spread upwards into a gap, up downwards
  std::vector<int> stack, members;
  for (std::size_t i = 0; i < n; ++i) {
    if (role[i] >= 0) down[i] = up[i] = fixed_id[static_cast<std::size_t>(role[i])];
    if (role[i] == -2) down[i] = up[i] = c.manipulated;
  }
  // Bones: a range cluster per connected piece of a range band.
  for (std::size_t s = 0; s < n; ++s) {
    if (band[s] < 0 || down[s] >= 0 || bands[static_cast<std::size_t>(band[s])].kind != Band::Kind::Range)
      continue;
    const int b = band[s];
    const int id = newCluster(ClusterKind::Range, b, -1, 0.0);
    double sum_phi = 0;
    members.clear();
    down[s] = up[s] = id;
    stack.assign(1, static_cast<int>(s));
    while (!stack.empty()) {
      const auto x = static_cast<std::size_t>(stack.back());
      stack.pop_back();
      members.push_back(static_cast<int>(x));
      sum_phi += phi[x];
      for (const int* j = graph.begin(x); j != graph.end(x); ++j) {
        const auto u = static_cast<std::size_t>(*j);
        if (band[u] == b && down[u] < 0) {
          down[u] = up[u] = id;
          stack.push_back(static_cast<int>(u));
        }
      }
    }
    Cluster& cl = c.clusters.back();
    cl.phi = sum_phi / static_cast<double>(members.size());
    for (int m : members)
      if (in_sample[static_cast<std::size_t>(m)]) cl.members.push_back(m);
    for (std::size_t k = 0; k < members.size() && cl.members.size() < 3; ++k)
      if (!in_sample[static_cast<std::size_t>(members[k])]) cl.members.push_back(members[k]);
  }
  // Points inside interval bands seed the gaps on either side.
  for (std::size_t i = 0; i < n; ++i) {
    if (band[i] < 0 || down[i] < 0) continue;
    down_queue.push_back(static_cast<int>(i));
    up_queue.push_back(static_cast<int>(i));
  }

  // Isolines: the points on either side of an edge that crosses an isovalue, per iso band.
  std::vector<std::vector<int>> on_line(bands.size());
  std::vector<int> iso_bands;
  std::vector<double> iso_values;
  for (int b = 0; b < nb; ++b)
    if (bands[static_cast<std::size_t>(b)].kind == Band::Kind::Iso) {
      iso_bands.push_back(b);
      iso_values.push_back(bands[static_cast<std::size_t>(b)].lo);
    }
  // An edge crosses the isovalues v with phi_i < v <= phi_u: those from the count of
  // isovalues <= phi_i to the count <= phi_u, per point once (most edges cross none). Edges in
  // parallel, each thread collecting its own lists.
  std::vector<int> below(n);  // isovalues <= phi
  const long long nn = static_cast<long long>(n);
#pragma omp parallel for schedule(static) if (nn > kParallelMin)
  for (long long i = 0; i < nn; ++i)
    below[static_cast<std::size_t>(i)] =
        static_cast<int>(std::upper_bound(iso_values.begin(), iso_values.end(),
                                          static_cast<double>(phi[static_cast<std::size_t>(i)])) -
                         iso_values.begin());
#pragma omp parallel if (nn > kParallelMin)
  {
    std::vector<std::vector<int>> mine(iso_bands.size());
#pragma omp for schedule(static) nowait
    for (long long ii = 0; ii < nn; ++ii) {
      const auto i = static_cast<std::size_t>(ii);
      if (role[i] == -3) continue;
      for (const int* j = graph.begin(i); j != graph.end(i); ++j) {
        const auto u = static_cast<std::size_t>(*j);
        if (!(phi[i] < phi[u])) continue;
        for (int l = below[i]; l < below[u]; ++l) {
          mine[static_cast<std::size_t>(l)].push_back(static_cast<int>(i));
          mine[static_cast<std::size_t>(l)].push_back(static_cast<int>(u));
        }
      }
    }
#pragma omp critical
    for (std::size_t l = 0; l < iso_bands.size(); ++l) {
      auto& line = on_line[static_cast<std::size_t>(iso_bands[l])];
      line.insert(line.end(), mine[l].begin(), mine[l].end());
    }
  }
  // Contours: connected pieces of each isoline; every piece of enough points is an isocluster.
  // Traced for all isovalues in parallel (each thread with its own marks), then made clusters
  // in band order, so that cluster ids and the spreads' seeds do not depend on the threads.
  std::vector<std::vector<std::vector<int>>> contours(bands.size());
  const long long n_iso = static_cast<long long>(iso_bands.size());
#pragma omp parallel if (nn > kParallelMin && n_iso > 1)
  {
    std::vector<int> mark(n, -1), seen(n, -1), trace;
#pragma omp for schedule(dynamic, 1)
    for (long long k = 0; k < n_iso; ++k) {
      const int b = iso_bands[static_cast<std::size_t>(k)];
      auto& line = on_line[static_cast<std::size_t>(b)];
      std::sort(line.begin(), line.end());
      line.erase(std::unique(line.begin(), line.end()), line.end());
      for (int i : line) mark[static_cast<std::size_t>(i)] = b;
      for (int seed : line) {
        if (seen[static_cast<std::size_t>(seed)] == b) continue;
        std::vector<int> piece;
        seen[static_cast<std::size_t>(seed)] = b;
        trace.assign(1, seed);
        while (!trace.empty()) {
          const auto x = static_cast<std::size_t>(trace.back());
          trace.pop_back();
          piece.push_back(static_cast<int>(x));
          // Two hops: on an unevenly sampled surface consecutive crossing edges need not
          // share a point or an edge, and one-hop pieces of a single isoline would become
          // separate clusters (at 1M points of the Armadillo, 12 instead of 5 above the feet).
          for (const int* j = graph.begin(x); j != graph.end(x); ++j) {
            const auto u = static_cast<std::size_t>(*j);
            if (mark[u] == b && seen[u] != b) {
              seen[u] = b;
              trace.push_back(static_cast<int>(u));
            }
            for (const int* w = graph.begin(u); w != graph.end(u); ++w) {
              const auto v2 = static_cast<std::size_t>(*w);
              if (mark[v2] == b && seen[v2] != b) {
                seen[v2] = b;
                trace.push_back(static_cast<int>(v2));
              }
            }
          }
        }
        contours[static_cast<std::size_t>(b)].push_back(std::move(piece));
      }
    }
  }
  for (int b : iso_bands) {
    const double v = bands[static_cast<std::size_t>(b)].lo;
    for (auto& piece : contours[static_cast<std::size_t>(b)]) {
      if (static_cast<int>(piece.size()) < options.min_contour) continue;
      const int id = newCluster(ClusterKind::Iso, b, -1, v);
      Cluster& cl = c.clusters.back();
      for (int m : piece)
        if (in_sample[static_cast<std::size_t>(m)]) cl.members.push_back(m);
      if (cl.members.size() < 3) {  // a short contour: its points nearest the isovalue
        std::sort(piece.begin(), piece.end(), [&](int x, int y) {
          return std::abs(phi[static_cast<std::size_t>(x)] - v) <
                 std::abs(phi[static_cast<std::size_t>(y)] - v);
        });
        for (std::size_t k = 0; k < piece.size() && cl.members.size() < 3; ++k)
          if (!in_sample[static_cast<std::size_t>(piece[k])]) cl.members.push_back(piece[k]);
      }
      // The contour seeds the gaps on either side of it.
      for (int m : piece) {
        const auto x = static_cast<std::size_t>(m);
        if (gap[x] == b && down[x] < 0) {
          down[x] = id;
          down_queue.push_back(m);
        } else if (gap[x] == b - 1 && up[x] < 0) {
          up[x] = id;
          up_queue.push_back(m);
        }
      }
    }
  }
  // Nearest cluster along the surface within each gap: a down label from band b spreads into
  // gap b, an up label from band b into gap b - 1.
  // The two spreads are independent (each writes its own labels): one thread each.
  auto spread = [&](const std::vector<int>& seeds, std::vector<int>& label, int offset) {
    std::vector<int> q(seeds);
    for (std::size_t head = 0; head < q.size(); ++head) {
      const auto x = static_cast<std::size_t>(q[head]);
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
    spread(down_queue, down, 0);
#pragma omp section
    spread(up_queue, up, 1);
  }
  // A gap region that meets only one side (a part touching one kind of handle only) takes
  // that side for both; parts touching no handle become static clusters.
  for (std::size_t i = 0; i < n; ++i) {
    if (down[i] < 0) down[i] = up[i];
    if (up[i] < 0) up[i] = down[i];
  }
  for (std::size_t s = 0; s < n; ++s) {
    if (down[s] >= 0) continue;
    const int id = newCluster(ClusterKind::Static, 0, -1, 0.0);
    down[s] = up[s] = id;
    stack.assign(1, static_cast<int>(s));
    while (!stack.empty()) {
      const auto x = static_cast<std::size_t>(stack.back());
      stack.pop_back();
      if (in_sample[x]) c.clusters.back().members.push_back(static_cast<int>(x));
      for (const int* j = graph.begin(x); j != graph.end(x); ++j) {
        const auto u = static_cast<std::size_t>(*j);
        if (down[u] < 0) {
          down[u] = up[u] = id;
          stack.push_back(static_cast<int>(u));
        }
      }
    }
  }
  for (auto& cl : c.clusters) {
    std::sort(cl.members.begin(), cl.members.end());
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int i : cl.members) sum += points[static_cast<std::size_t>(i)].getVector3fMap().cast<double>();
    if (!cl.members.empty()) cl.barycenter = sum / static_cast<double>(cl.members.size());
  }
  // Blend factors (eq. 1): a gap point's place between the facing ends of its two bands.
  c.alpha.assign(n, 0.0f);
  c.piece.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (gap[i] >= 0 && down[i] != up[i]) {
      const double a = bands[static_cast<std::size_t>(gap[i])].hi,
                   b = bands[static_cast<std::size_t>(gap[i]) + 1].lo;
      c.alpha[i] = b > a ? static_cast<float>(std::clamp((phi[i] - a) / (b - a), 0.0, 1.0)) : 0.0f;
    }
    c.piece[i] = c.alpha[i] < 0.5f ? down[i] : up[i];
  }
  // Adjacent clusters: the two sides of a gap region, and interval pieces that touch.
  auto isStatic = [&](int id) {
    return c.clusters[static_cast<std::size_t>(id)].kind == ClusterKind::Static;
  };
  auto addPair = [&](int a, int b) {  // neighbouring points mostly repeat the last pair
    const std::pair<int, int> pr(std::min(a, b), std::max(a, b));
    if (c.adjacency.empty() || c.adjacency.back() != pr) c.adjacency.push_back(pr);
  };
  for (std::size_t i = 0; i < n; ++i) {
    if (down[i] != up[i]) addPair(down[i], up[i]);
    if (band[i] < 0) continue;
    for (const int* j = graph.begin(i); j != graph.end(i); ++j) {
      const auto u = static_cast<std::size_t>(*j);
      if (band[u] >= 0 && band[u] != band[i] && !isStatic(down[i]) && !isStatic(down[u]))
        addPair(down[i], down[u]);
    }
  }
  std::sort(c.adjacency.begin(), c.adjacency.end());
  c.adjacency.erase(std::unique(c.adjacency.begin(), c.adjacency.end()), c.adjacency.end());
  c.down = std::move(down);
  c.up = std::move(up);
  return c;
}

}  // namespace hgd
