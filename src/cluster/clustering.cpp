#include "hgdeform/cluster/clustering.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <memory>
#include <numeric>
#include <unordered_map>

#include "util/parallel.h"
#include "util/timer.h"

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
  // Each block of points (in order) keeps its cells' nearest on its own thread; the blocks are
  // then merged in order, a later block's point winning only when strictly nearer, so that the
  // first of equally near points wins as in one pass.
  using Map = std::unordered_map<CellKey, std::pair<float, int>, CellHash>;
  const long long n = static_cast<long long>(points.size());
  const int blocks = blockCount(n);
  std::vector<Map> part(static_cast<std::size_t>(blocks));
  for (auto& m : part) m.reserve(points.size() / 4 / static_cast<std::size_t>(blocks) + 16);
  forBlocks(n, blocks, [&](int begin, int end, int b) {
    Map& best = part[static_cast<std::size_t>(b)];
    for (auto i = static_cast<std::size_t>(begin); i < static_cast<std::size_t>(end); ++i) {
      if (cls[i] < 0) continue;
      const Eigen::Vector3f q = (points[i].getVector3fMap() - lo) / h;
      const Eigen::Vector3f f = q.array().floor();
      const CellKey key{static_cast<int>(f.x()), static_cast<int>(f.y()), static_cast<int>(f.z()), cls[i]};
      const float d = (q - f - Eigen::Vector3f::Constant(0.5f)).squaredNorm();
      auto [it, inserted] = best.try_emplace(key, d, static_cast<int>(i));
      if (!inserted && d < it->second.first) it->second = {d, static_cast<int>(i)};
    }
  });
  Map& best = part[0];
  for (std::size_t b = 1; b < part.size(); ++b)
    for (const auto& [key, value] : part[b]) {
      auto [it, inserted] = best.try_emplace(key, value);
      if (!inserted && value.first < it->second.first) it->second = value;
    }
  std::vector<int> out;
  out.reserve(best.size());
  for (const auto& kv : best) out.push_back(kv.second.second);
  std::sort(out.begin(), out.end());
  return out;
}

// The surface sample's own graph: each site (a sample point that the field reached and that is
// no outlier) owns the points nearest it along the neighbour graph (breadth first from all
// sites at once), and two sites are adjacent when an edge joins their cells.
}  // namespace

std::vector<int> sampleSurface(const pcl::PointCloud<pcl::PointXYZ>& points, const Handles& handles,
                               int target, const std::vector<char>* exclude) {
  const std::size_t n = points.size();
  if (target <= 0 || static_cast<std::size_t>(target) >= n) {  // every point but the excluded
    std::vector<int> all;
    all.reserve(n);
    for (std::size_t i = 0; i < n; ++i)
      if (!exclude || exclude->size() != n || !(*exclude)[i]) all.push_back(static_cast<int>(i));
    return all;
  }
  std::vector<int> cls(n, 0);
  if (exclude && exclude->size() == n)
    for (std::size_t i = 0; i < n; ++i)
      if ((*exclude)[i]) cls[i] = -1;  // never picked
  for (std::size_t k = 0; k < handles.fixed.size(); ++k)
    for (int i : handles.fixed[k]) cls[static_cast<std::size_t>(i)] = 2 + static_cast<int>(k);
  for (int i : handles.manipulated) cls[static_cast<std::size_t>(i)] = 1;
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(INFINITY), hi = -lo;
  for (std::size_t i = 0; i < n; ++i) {
    if (cls[i] < 0) continue;
    lo = lo.cwiseMin(points[i].getVector3fMap());
    hi = hi.cwiseMax(points[i].getVector3fMap());
  }
  if (!(lo.array() <= hi.array()).all()) return {};
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
    const int n = std::max(0, options.isovalues);
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
    const int per_joint = std::max(1, options.joint_isovalues);
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

Clustering withoutPointLabels(Clustering clustering) {
  clustering.lower = {};
  clustering.upper = {};
  clustering.alpha = {};
  clustering.nearest = {};
  return clustering;
}

}  // namespace hgd
