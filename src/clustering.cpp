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

Clustering buildClusters(const pcl::PointCloud<pcl::PointXYZ>& points, const NeighborGraph& graph,
                         const std::vector<float>& phi, const Handles& handles,
                         const std::vector<int>& unreachable, const std::vector<int>& sample,
                         const ClusterOptions& options) {
  Clustering c;
  c.sample = sample;
  const std::size_t n = points.size();
  const int top = std::max(0, options.isoclusters) + 1;
  c.levels.resize(static_cast<std::size_t>(top) + 1);
  for (int l = 0; l <= top; ++l) c.levels[static_cast<std::size_t>(l)] = static_cast<double>(l) / top;
  auto slabOf = [&](std::size_t i) {
    return std::clamp(static_cast<int>(std::floor(phi[i] * top)), 0, top - 1);
  };

  // Roles: -1 free, -2 manipulated, -3 unreachable, k >= 0 fixed handle k.
  std::vector<int> role(n, -1);
  for (int i : unreachable) role[static_cast<std::size_t>(i)] = -3;
  for (std::size_t k = 0; k < handles.fixed.size(); ++k)
    for (int i : handles.fixed[k]) role[static_cast<std::size_t>(i)] = static_cast<int>(k);
  for (int i : handles.manipulated) role[static_cast<std::size_t>(i)] = -2;
  std::vector<char> in_sample(n, 0);
  for (int s : sample) in_sample[static_cast<std::size_t>(s)] = 1;

  auto newCluster = [&](ClusterKind kind, int lvl, int handle) {
    Cluster cl;
    cl.id = static_cast<int>(c.clusters.size());
    cl.kind = kind;
    cl.level = lvl;
    cl.phi = c.levels[static_cast<std::size_t>(lvl)];
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
    fixed_id[k] = newCluster(ClusterKind::Fixed, 0, static_cast<int>(k));
    handleMembers(handles.fixed[k], c.clusters.back());
  }
  c.manipulated = newCluster(ClusterKind::Manipulated, top, -1);
  handleMembers(handles.manipulated, c.clusters.back());

  // Isolines: the points on either side of an edge that crosses v_l, per level.
  std::vector<std::vector<int>> on_line(static_cast<std::size_t>(top));
  for (std::size_t i = 0; i < n; ++i) {
    if (role[i] == -3) continue;
    for (const int* j = graph.begin(i); j != graph.end(i); ++j) {
      const auto u = static_cast<std::size_t>(*j);
      if (!(phi[i] < phi[u])) continue;
      // Levels l with phi_i < v_l <= phi_u.
      const int lo = std::max(1, static_cast<int>(std::floor(phi[i] * top)) + 1);
      const int hi = std::min(top - 1, static_cast<int>(std::floor(phi[u] * top)));
      for (int l = lo; l <= hi; ++l) {
        if (!(phi[i] < c.levels[static_cast<std::size_t>(l)] &&
              c.levels[static_cast<std::size_t>(l)] <= phi[u]))
          continue;
        on_line[static_cast<std::size_t>(l)].push_back(static_cast<int>(i));
        on_line[static_cast<std::size_t>(l)].push_back(static_cast<int>(u));
      }
    }
  }
  // Contours: connected pieces of each isoline; every piece of enough points is an isocluster.
  std::vector<int> down(n, -1), up(n, -1);
  std::vector<int> mark(n, -1), comp(n, -1), stack, members;
  std::deque<int> down_queue, up_queue;
  for (int l = 1; l < top; ++l) {
    auto& line = on_line[static_cast<std::size_t>(l)];
    std::sort(line.begin(), line.end());
    line.erase(std::unique(line.begin(), line.end()), line.end());
    for (int i : line) mark[static_cast<std::size_t>(i)] = l;
    const double v = c.levels[static_cast<std::size_t>(l)];
    for (int seed : line) {
      if (comp[static_cast<std::size_t>(seed)] == l) continue;  // comp doubles as "visited at level l"
      members.clear();
      comp[static_cast<std::size_t>(seed)] = l;
      stack.assign(1, seed);
      while (!stack.empty()) {
        const auto x = static_cast<std::size_t>(stack.back());
        stack.pop_back();
        members.push_back(static_cast<int>(x));
        for (const int* j = graph.begin(x); j != graph.end(x); ++j) {
          const auto u = static_cast<std::size_t>(*j);
          if (mark[u] == l && comp[u] != l) {
            comp[u] = l;
            stack.push_back(static_cast<int>(u));
          }
        }
      }
      if (static_cast<int>(members.size()) < options.min_contour) continue;
      const int id = newCluster(ClusterKind::Iso, l, -1);
      Cluster& cl = c.clusters.back();
      for (int m : members)
        if (in_sample[static_cast<std::size_t>(m)]) cl.members.push_back(m);
      if (cl.members.size() < 3) {  // a short contour: its points nearest the isovalue
        std::sort(members.begin(), members.end(), [&](int a, int b) {
          return std::abs(phi[static_cast<std::size_t>(a)] - v) <
                 std::abs(phi[static_cast<std::size_t>(b)] - v);
        });
        for (std::size_t k = 0; k < members.size() && cl.members.size() < 3; ++k)
          if (!in_sample[static_cast<std::size_t>(members[k])]) cl.members.push_back(members[k]);
      }
      // The contour seeds the searches of the slabs on either side of it.
      for (int m : members) {
        const auto x = static_cast<std::size_t>(m);
        if (slabOf(x) == l && down[x] < 0) {
          down[x] = id;
          down_queue.push_back(m);
        } else if (slabOf(x) == l - 1 && up[x] < 0) {
          up[x] = id;
          up_queue.push_back(m);
        }
      }
    }
  }
  // Handles seed the outermost slabs.
  for (std::size_t i = 0; i < n; ++i) {
    if (role[i] >= 0 && slabOf(i) == 0) {
      down[i] = fixed_id[static_cast<std::size_t>(role[i])];
      down_queue.push_front(static_cast<int>(i));
    }
    if (role[i] == -2 && slabOf(i) == top - 1) {
      up[i] = c.manipulated;
      up_queue.push_front(static_cast<int>(i));
    }
  }
  // Nearest contour along the surface within each slab.
  auto spread = [&](std::deque<int>& q, std::vector<int>& label, int offset) {
    while (!q.empty()) {
      const auto x = static_cast<std::size_t>(q.front());
      q.pop_front();
      const int slab = c.clusters[static_cast<std::size_t>(label[x])].level - offset;
      for (const int* j = graph.begin(x); j != graph.end(x); ++j) {
        const auto u = static_cast<std::size_t>(*j);
        if (label[u] < 0 && role[u] != -3 && slabOf(u) == slab) {
          label[u] = label[x];
          q.push_back(static_cast<int>(u));
        }
      }
    }
  };
  spread(down_queue, down, 0);
  spread(up_queue, up, 1);
  // A slab region that meets only one side (a part touching one kind of handle only) takes
  // that side for both; parts touching no handle become static clusters.
  for (std::size_t i = 0; i < n; ++i) {
    if (down[i] < 0) down[i] = up[i];
    if (up[i] < 0) up[i] = down[i];
  }
  for (std::size_t s = 0; s < n; ++s) {
    if (down[s] >= 0) continue;
    const int id = newCluster(ClusterKind::Static, 0, -1);
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
  // Adjacent clusters: the two sides of some slab region.
  c.piece.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const int a = std::min(down[i], up[i]), b = std::max(down[i], up[i]);
    if (a != b) c.adjacency.emplace_back(a, b);
    c.piece[i] = phi[i] * top - slabOf(i) < 0.5 ? down[i] : up[i];
  }
  std::sort(c.adjacency.begin(), c.adjacency.end());
  c.adjacency.erase(std::unique(c.adjacency.begin(), c.adjacency.end()), c.adjacency.end());
  c.down = std::move(down);
  c.up = std::move(up);
  return c;
}

}  // namespace hgd
