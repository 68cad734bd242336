#include "hgdeform/clustering.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <numeric>
#include <unordered_map>

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

Clustering buildClusters(const pcl::PointCloud<pcl::PointXYZ>& points,
                         const pcl::PointCloud<pcl::Normal>& normals, const std::vector<float>& phi,
                         const Handles& handles, const std::vector<int>& unreachable,
                         const std::vector<int>& sample, const ClusterOptions& options) {
  Clustering c;
  c.sample = sample;
  const int n_iso = std::max(0, options.isoclusters);
  const int top = n_iso + 1;
  c.levels.resize(static_cast<std::size_t>(top) + 1);
  for (int l = 0; l <= top; ++l) c.levels[static_cast<std::size_t>(l)] = static_cast<double>(l) / top;
  const double spacing = 1.0 / top;
  const std::size_t m = sample.size();

  // Roles of shape points: -1 free, -2 manipulated, -3 unreachable, k >= 0 fixed handle k.
  std::vector<int> role(points.size(), -1);
  for (int i : unreachable) role[static_cast<std::size_t>(i)] = -3;
  for (std::size_t k = 0; k < handles.fixed.size(); ++k)
    for (int i : handles.fixed[k]) role[static_cast<std::size_t>(i)] = static_cast<int>(k);
  for (int i : handles.manipulated) role[static_cast<std::size_t>(i)] = -2;

  // Sample graph: kNN among sample points, normal-filtered, symmetric.
  pcl::PointCloud<pcl::PointXYZ> sp;
  pcl::PointCloud<pcl::Normal> sn;
  sp.resize(m);
  sn.resize(m);
  for (std::size_t s = 0; s < m; ++s) {
    sp[s] = points[static_cast<std::size_t>(sample[s])];
    sn[s] = normals[static_cast<std::size_t>(sample[s])];
  }
  const NeighborGraph g = knnGraph(computeKnn(sp, options.k_sample), options.k_sample, &sn);

  auto roleOf = [&](std::size_t s) { return role[static_cast<std::size_t>(sample[s])]; };
  auto phiOf = [&](std::size_t s) { return static_cast<double>(phi[static_cast<std::size_t>(sample[s])]); };
  c.sample_level.resize(m);
  for (std::size_t s = 0; s < m; ++s) {
    const int r = roleOf(s);
    if (r == -2)
      c.sample_level[s] = top;
    else if (r >= 0 || r == -3)
      c.sample_level[s] = 0;
    else
      c.sample_level[s] = std::clamp(static_cast<int>(std::lround(phiOf(s) * top)), 0, top);
  }
  c.sample_piece.assign(m, -1);

  auto newCluster = [&](ClusterKind kind, int level, int handle) {
    Cluster cl;
    cl.id = static_cast<int>(c.clusters.size());
    cl.kind = kind;
    cl.level = level;
    cl.phi = c.levels[static_cast<std::size_t>(level)];
    cl.handle = handle;
    c.clusters.push_back(cl);
    return cl.id;
  };

  // Fixed handles: one cluster each; the level-0 region around a handle joins it by BFS.
  std::vector<int> fixed_id(handles.fixed.size());
  for (std::size_t k = 0; k < handles.fixed.size(); ++k)
    fixed_id[k] = newCluster(ClusterKind::Fixed, 0, static_cast<int>(k));
  c.manipulated = newCluster(ClusterKind::Manipulated, top, -1);

  std::deque<int> queue;
  for (std::size_t s = 0; s < m; ++s) {
    const int r = roleOf(s);
    if (r >= 0) {
      c.sample_piece[s] = fixed_id[static_cast<std::size_t>(r)];
      c.clusters[static_cast<std::size_t>(c.sample_piece[s])].members.push_back(sample[s]);
      queue.push_back(static_cast<int>(s));
    } else if (r == -2) {
      c.sample_piece[s] = c.manipulated;
      c.clusters[static_cast<std::size_t>(c.manipulated)].members.push_back(sample[s]);
    }
  }
  // Level-0 free points take the fixed handle they are connected to within level 0.
  auto grow = [&](bool within_level) {
    while (!queue.empty()) {
      const auto v = static_cast<std::size_t>(queue.front());
      queue.pop_front();
      for (const int* j = g.begin(v); j != g.end(v); ++j) {
        const auto u = static_cast<std::size_t>(*j);
        if (c.sample_piece[u] >= 0 || roleOf(u) == -3 || c.sample_level[u] != 0) continue;
        if (within_level && c.sample_level[v] != 0) continue;
        c.sample_piece[u] = c.sample_piece[v];
        queue.push_back(static_cast<int>(u));
      }
    }
  };
  grow(true);
  // Top level: everything there belongs to the manipulated handle's side.
  for (std::size_t s = 0; s < m; ++s)
    if (c.sample_piece[s] < 0 && c.sample_level[s] == top) c.sample_piece[s] = c.manipulated;

  // Isoclusters: connected pieces of each level's region; members are the points in the band.
  std::vector<int> stack;
  const double band = options.band * spacing;
  for (std::size_t s = 0; s < m; ++s) {
    const int l = c.sample_level[s];
    if (c.sample_piece[s] >= 0 || l == 0 || l == top) continue;
    const int id = newCluster(ClusterKind::Iso, l, -1);
    std::vector<int> piece;
    c.sample_piece[s] = id;
    stack.assign(1, static_cast<int>(s));
    while (!stack.empty()) {
      const auto v = static_cast<std::size_t>(stack.back());
      stack.pop_back();
      piece.push_back(static_cast<int>(v));
      for (const int* j = g.begin(v); j != g.end(v); ++j) {
        const auto u = static_cast<std::size_t>(*j);
        if (c.sample_piece[u] < 0 && c.sample_level[u] == l && roleOf(u) == -1) {
          c.sample_piece[u] = id;
          stack.push_back(static_cast<int>(u));
        }
      }
    }
    const double v_l = c.levels[static_cast<std::size_t>(l)];
    auto& members = c.clusters[static_cast<std::size_t>(id)].members;
    for (int v : piece)
      if (std::abs(phiOf(static_cast<std::size_t>(v)) - v_l) <= band)
        members.push_back(sample[static_cast<std::size_t>(v)]);
    if (members.size() < 3) {  // a thin piece: take the points nearest the isovalue
      std::sort(piece.begin(), piece.end(), [&](int a, int b) {
        return std::abs(phiOf(static_cast<std::size_t>(a)) - v_l) <
               std::abs(phiOf(static_cast<std::size_t>(b)) - v_l);
      });
      members.clear();
      for (std::size_t q = 0; q < piece.size() && q < 3; ++q)
        members.push_back(sample[static_cast<std::size_t>(piece[q])]);
    }
    std::sort(members.begin(), members.end());
  }
  // Level-0 points cut off from their handle within level 0: nearest fixed handle over the graph.
  for (std::size_t s = 0; s < m; ++s)
    if (c.sample_piece[s] >= 0 &&
        c.clusters[static_cast<std::size_t>(c.sample_piece[s])].kind == ClusterKind::Fixed)
      queue.push_back(static_cast<int>(s));
  grow(false);
  // Whatever is left (unreachable parts): static clusters, one per connected piece.
  for (std::size_t s = 0; s < m; ++s) {
    if (c.sample_piece[s] >= 0) continue;
    const int id = newCluster(ClusterKind::Static, 0, -1);
    c.sample_piece[s] = id;
    stack.assign(1, static_cast<int>(s));
    while (!stack.empty()) {
      const auto v = static_cast<std::size_t>(stack.back());
      stack.pop_back();
      c.clusters[static_cast<std::size_t>(id)].members.push_back(sample[v]);
      for (const int* j = g.begin(v); j != g.end(v); ++j)
        if (c.sample_piece[static_cast<std::size_t>(*j)] < 0) {
          c.sample_piece[static_cast<std::size_t>(*j)] = id;
          stack.push_back(*j);
        }
    }
  }
  for (auto& cl : c.clusters) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int i : cl.members) sum += points[static_cast<std::size_t>(i)].getVector3fMap().cast<double>();
    if (!cl.members.empty()) cl.barycenter = sum / static_cast<double>(cl.members.size());
  }

  // Adjacency: pieces joined by a sample edge across levels.
  for (std::size_t s = 0; s < m; ++s)
    for (const int* j = g.begin(s); j != g.end(s); ++j) {
      const auto u = static_cast<std::size_t>(*j);
      const int a = c.sample_piece[s], b = c.sample_piece[u];
      if (a >= b || c.sample_level[s] == c.sample_level[u]) continue;
      if (c.clusters[static_cast<std::size_t>(a)].kind == ClusterKind::Static ||
          c.clusters[static_cast<std::size_t>(b)].kind == ClusterKind::Static)
        continue;
      c.adjacency.emplace_back(a, b);
    }
  std::sort(c.adjacency.begin(), c.adjacency.end());
  c.adjacency.erase(std::unique(c.adjacency.begin(), c.adjacency.end()), c.adjacency.end());

  // For interpolation: the nearest piece one level up (down) from each sample point, found by
  // a breadth-first search that starts at level boundaries and stays within a level.
  auto nearestAcross = [&](int dir, std::vector<int>& out) {
    out.assign(m, -1);
    std::deque<int> q;
    for (std::size_t s = 0; s < m; ++s) {
      if (c.clusters[static_cast<std::size_t>(c.sample_piece[s])].kind == ClusterKind::Static) continue;
      float best = INFINITY;
      for (const int* j = g.begin(s); j != g.end(s); ++j) {
        const auto u = static_cast<std::size_t>(*j);
        if (c.sample_level[u] - c.sample_level[s] != dir) continue;
        const float d = (sp[u].getVector3fMap() - sp[s].getVector3fMap()).squaredNorm();
        if (d < best) {
          best = d;
          out[s] = c.sample_piece[u];
        }
      }
      if (out[s] >= 0) q.push_back(static_cast<int>(s));
    }
    while (!q.empty()) {
      const auto v = static_cast<std::size_t>(q.front());
      q.pop_front();
      for (const int* j = g.begin(v); j != g.end(v); ++j) {
        const auto u = static_cast<std::size_t>(*j);
        if (out[u] < 0 && c.sample_piece[u] == c.sample_piece[v]) {
          out[u] = out[v];
          q.push_back(static_cast<int>(u));
        }
      }
    }
  };
  nearestAcross(+1, c.sample_up);
  nearestAcross(-1, c.sample_down);
  // A piece with no neighbour across a level boundary (possible only on a very sparse sample)
  // falls back to any adjacent cluster one level away, else to itself.
  for (std::size_t s = 0; s < m; ++s) {
    for (int dir : {+1, -1}) {
      int& slot = dir > 0 ? c.sample_up[s] : c.sample_down[s];
      if (slot >= 0) continue;
      const int self = c.sample_piece[s];
      const int want = c.clusters[static_cast<std::size_t>(self)].level + dir;
      for (const auto& e : c.adjacency) {
        const int other = e.first == self ? e.second : (e.second == self ? e.first : -1);
        if (other >= 0 && c.clusters[static_cast<std::size_t>(other)].level == want) {
          slot = other;
          break;
        }
      }
      if (slot < 0) slot = self;
    }
  }
  return c;
}

}  // namespace hgd
