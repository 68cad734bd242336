// Prolongation from the coarse level to the shape: the field (each coarse point's linear model),
// the clusters and the interpolation table.
#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "hgdeform/multires/multires.h"
#include "interp/table_build.h"
#include "multires/prolong_labels.h"
#include "util/parallel.h"

namespace hgd {

std::vector<CoarseLinear> coarseLinearModels(const pcl::PointCloud<pcl::PointXYZ>& coarse,
                                             const NeighborGraph& graph, const std::vector<float>& coarse_phi,
                                             const std::vector<char>& constrained) {
  const std::size_t m = coarse.size();
  std::vector<CoarseLinear> model(m);
  const long long mm = static_cast<long long>(m);
#pragma omp parallel for schedule(dynamic, kDynamicChunkCostly) if (mm > kParallelMinCostly)
  for (long long aa = 0; aa < mm; ++aa) {
    const auto a = static_cast<std::size_t>(aa);
    CoarseLinear& l = model[a];
    const float va = coarse_phi[a];
    l.lo = l.hi = va;
    if (constrained[a]) continue;  // a handle's cell keeps the handle's value
    const Eigen::Vector3d xa = coarse[a].getVector3fMap().cast<double>();
    Eigen::Matrix3d mat = Eigen::Matrix3d::Zero();
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    int count = 0;
    for (const int* j = graph.begin(a); j != graph.end(a); ++j) {
      const auto u = static_cast<std::size_t>(*j);
      const Eigen::Vector3d d = coarse[u].getVector3fMap().cast<double>() - xa;
      mat += d * d.transpose();
      rhs += d * static_cast<double>(coarse_phi[u] - va);
      l.lo = std::min(l.lo, coarse_phi[u]);
      l.hi = std::max(l.hi, coarse_phi[u]);
      ++count;
    }
    const double trace = mat.trace();
    if (count < 2 || !(trace > 0)) continue;
    // Neighbours on a surface leave the normal direction undetermined: a small ridge keeps the
    // gradient in the tangent plane.
    l.grad = (mat + 1e-3 * trace / 3 * Eigen::Matrix3d::Identity()).ldlt().solve(rhs).cast<float>();
    if (!l.grad.allFinite()) l.grad.setZero();
  }
  return model;
}

std::vector<float> prolongField(const pcl::PointCloud<pcl::PointXYZ>& points, const CoarseLevel& level,
                                const NeighborGraph& graph, const std::vector<float>& coarse_phi,
                                const std::vector<char>& constrained) {
  // Each coarse point's linear model: its value, its gradient and the range of values around it.
  pcl::PointCloud<pcl::PointXYZ> coarse;
  coarse.resize(level.points.size());
  for (std::size_t a = 0; a < level.points.size(); ++a)
    coarse[a] = points[static_cast<std::size_t>(level.points[a])];
  const std::vector<CoarseLinear> model = coarseLinearModels(coarse, graph, coarse_phi, constrained);
  const std::size_t n = level.anchor.size();
  std::vector<float> phi(n);
  const long long nn = static_cast<long long>(n);
#pragma omp parallel for schedule(dynamic, dynamicChunk(nn)) if (nn > kParallelMin)
  for (long long ii = 0; ii < nn; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    const std::uint32_t a = level.anchor[i];
    phi[i] = model[a].at(coarse_phi[a], points[i].getVector3fMap() - coarse[a].getVector3fMap());
  }
  for (const int i : level.strays)
    phi[static_cast<std::size_t>(i)] = coarse_phi[level.anchor[static_cast<std::size_t>(i)]];
  return phi;
}

namespace {

// The blend factor a shape point takes from the coarse level: a coarse point between two bands
// whose factor is its place in the gap hands that rule on (the point's own φ placed in the same
// gap); one that copied its factor from elsewhere (see buildClusters) hands on the factor.
class AlphaRule {
 public:
  AlphaRule(const Clustering& c, const std::vector<float>& coarse_phi)
      : c_(c), own_gap_(coarse_phi.size(), -1) {
    const auto& bands = c.bands;
    for (std::size_t a = 0; a < own_gap_.size(); ++a) {
      const int lower = c.lower[a], upper = c.upper[a];
      if (lower < 0 || upper < 0 || lower == upper) continue;
      const int g = c.clusters[static_cast<std::size_t>(lower)].level;
      if (g < 0 || static_cast<std::size_t>(g) + 1 >= bands.size() ||
          c.clusters[static_cast<std::size_t>(upper)].level != g + 1)
        continue;
      // Inside its gap, not clamped at an end (an α of 0 or 1 copied from elsewhere would match a
      // clamped one by chance).
      const double v = coarse_phi[a];
      const auto gs = static_cast<std::size_t>(g);
      if (v > bands[gs].hi && v < bands[gs + 1].lo && std::abs(gapAlpha(gs, v) - c.alpha[a]) <= 1e-6f)
        own_gap_[a] = g;
    }
  }
  /// The factor of a point anchored at coarse point a with field value v.
  float operator()(std::uint32_t a, float v) const {
    return own_gap_[a] >= 0 ? gapAlpha(static_cast<std::size_t>(own_gap_[a]), v) : c_.alpha[a];
  }

 private:
  float gapAlpha(std::size_t g, double v) const {
    const double a = c_.bands[g].hi, b = c_.bands[g + 1].lo;
    return b > a ? static_cast<float>(std::clamp((v - a) / (b - a), 0.0, 1.0)) : 0.0f;
  }
  const Clustering& c_;
  std::vector<int> own_gap_;
};

void checkCoarseLabels(const Clustering& c, const CoarseLevel& level, const std::vector<float>& coarse_phi,
                       const std::vector<float>& phi) {
  const std::size_t m = level.points.size();
  if (c.lower.size() != m || c.upper.size() != m || c.alpha.size() != m || coarse_phi.size() != m ||
      phi.size() != level.anchor.size())
    throw std::invalid_argument(
        "prolong: the coarse clustering, the fields and the coarse level differ in size");
}

}  // namespace

Clustering prolongClusters(Clustering c, const CoarseLevel& level) {
  const auto& to_shape = level.points;
  auto map = [&](std::vector<int>& idx) {
    for (int& i : idx) i = to_shape[static_cast<std::size_t>(i)];
    std::sort(idx.begin(), idx.end());
  };
  map(c.sample);
  for (auto& cl : c.clusters) map(cl.members);
  return withoutPointLabels(std::move(c));
}

Clustering prolongClustering(Clustering c, const CoarseLevel& level, const std::vector<float>& coarse_phi,
                             const std::vector<float>& phi) {
  checkCoarseLabels(c, level, coarse_phi, phi);
  const std::size_t n = level.anchor.size();
  std::vector<int> lower(n), upper(n), nearest(n);
  std::vector<float> alpha(n);
  {
    const AlphaRule rule(c, coarse_phi);
    const long long nn = static_cast<long long>(n);
#pragma omp parallel for schedule(dynamic, dynamicChunk(nn)) if (nn > kParallelMin)
    for (long long ii = 0; ii < nn; ++ii) {
      const auto i = static_cast<std::size_t>(ii);
      const std::uint32_t a = level.anchor[i];
      lower[i] = c.lower[a];
      upper[i] = c.upper[a];
      alpha[i] = rule(a, phi[i]);
    }
    for (const int i : level.strays) {  // a stray moves as the point it hangs from
      const auto x = static_cast<std::size_t>(i);
      alpha[x] = c.alpha[level.anchor[x]];
    }
#pragma omp parallel for schedule(dynamic, dynamicChunk(nn)) if (nn > kParallelMin)
    for (long long ii = 0; ii < nn; ++ii) {
      const auto i = static_cast<std::size_t>(ii);
      nearest[i] = alpha[i] < 0.5f ? lower[i] : upper[i];
    }
  }
  c = prolongClusters(std::move(c), level);
  c.lower = std::move(lower);
  c.upper = std::move(upper);
  c.alpha = std::move(alpha);
  c.nearest = std::move(nearest);
  return c;
}

InterpolationTable prolongInterpolation(const Clustering& c, const CoarseLevel& level,
                                        const std::vector<float>& coarse_phi, const std::vector<float>& phi,
                                        const Handles& handles,
                                        const pcl::PointCloud<pcl::PointXYZ>& points) {
  checkCoarseLabels(c, level, coarse_phi, phi);
  if (points.size() != phi.size())
    throw std::invalid_argument("prolongInterpolation: the points and the field differ in size");
  const AlphaRule rule(c, coarse_phi);
  InterpolationTable t = detail::buildTable(
      handles, c, points, detail::labelPairs(c),
      [&](std::size_t i, int& lo, int& hi, float& alpha) {
        const std::uint32_t a = level.anchor[i];
        lo = c.lower[a];
        hi = c.upper[a];
        alpha = rule(a, phi[i]);
      },
      [&](InterpolationTable& table) {  // a stray moves as the point it hangs from
        for (const int x : level.strays)
          table.points[static_cast<std::size_t>(x)].alpha =
              c.alpha[level.anchor[static_cast<std::size_t>(x)]];
      });
  return t;
}

struct BlockProlongation::Rule {
  Rule(const Clustering& c, const std::vector<float>& coarse_phi) : alpha(c, coarse_phi) {}
  AlphaRule alpha;
};

BlockProlongation::BlockProlongation(const Clustering& coarse, pcl::PointCloud<pcl::PointXYZ> points,
                                     std::vector<float> coarse_phi, std::vector<CoarseLinear> models,
                                     std::size_t fixed_handles)
    : labels_(coarse),
      points_(std::move(points)),
      phi_(std::move(coarse_phi)),
      models_(std::move(models)),
      fixed_handles_(fixed_handles) {
  const std::size_t m = points_.size();
  if (labels_.lower.size() != m || labels_.upper.size() != m || labels_.alpha.size() != m ||
      phi_.size() != m || models_.size() != m)
    throw std::invalid_argument("BlockProlongation: the coarse clustering, field and points differ in size");
  rule_ = std::make_unique<Rule>(labels_, phi_);
}

BlockProlongation::~BlockProlongation() = default;

float BlockProlongation::phi(std::uint32_t a, const Eigen::Vector3f& p, bool stray) const {
  if (stray) return phi_[a];
  return models_[a].at(phi_[a], p - points_[a].getVector3fMap());
}

InterpolationTable BlockProlongation::table(const pcl::PointCloud<pcl::PointXYZ>& points,
                                            const std::vector<std::uint32_t>& anchor,
                                            const std::vector<char>& stray,
                                            const std::vector<int>& cls) const {
  // prolongInterpolation's table (buildTable with its bracket, stray and pin rules), for these
  // points: the pins of the shape's handles by class (a point in two lists has the class that
  // pins last: the manipulated handle, else the last fixed one).
  Handles handles;
  handles.fixed.resize(fixed_handles_);
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (cls[i] == 1) handles.manipulated.push_back(static_cast<int>(i));
    if (cls[i] >= 2 && static_cast<std::size_t>(cls[i] - 2) < fixed_handles_)
      handles.fixed[static_cast<std::size_t>(cls[i] - 2)].push_back(static_cast<int>(i));
  }
  // Every fixed handle and the manipulated one have points in the shape: their pairs are in the
  // table whether or not this block holds any.
  const int none = -1;
  for (auto& f : handles.fixed)
    if (f.empty()) f.push_back(none);
  if (handles.manipulated.empty()) handles.manipulated.push_back(none);
  std::vector<std::vector<int>> pins_fixed(handles.fixed.size());
  std::vector<int> pins_manipulated;
  for (std::size_t k = 0; k < handles.fixed.size(); ++k)
    for (const int i : handles.fixed[k])
      if (i != none) pins_fixed[k].push_back(i);
  for (const int i : handles.manipulated)
    if (i != none) pins_manipulated.push_back(i);
  const Clustering& c = labels_;
  const AlphaRule& rule = rule_->alpha;
  InterpolationTable t = detail::buildTable(
      handles, c, points, detail::labelPairs(c),
      [&](std::size_t i, int& lo, int& hi, float& alpha) {
        const std::uint32_t a = anchor[i];
        lo = c.lower[a];
        hi = c.upper[a];
        alpha = rule(a, phi(a, points[i].getVector3fMap(), false));
      },
      [&](InterpolationTable& table) {  // a stray moves as the point it hangs from
        for (std::size_t i = 0; i < points.size(); ++i)
          if (stray[i]) table.points[i].alpha = c.alpha[anchor[i]];
      },
      &pins_fixed, &pins_manipulated);
  return t;
}

}  // namespace hgd
