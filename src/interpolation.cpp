#include "hgdeform/interpolation.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>

#include "hgdeform/geometry.h"
#include "timer.h"

namespace hgd {

InterpolationTable buildInterpolation(const std::vector<float>& phi, const Handles& handles,
                                      const Clustering& c, const pcl::PointCloud<pcl::PointXYZ>& points,
                                      const pcl::PointCloud<pcl::Normal>* normals) {
  const std::size_t n = phi.size();
  InterpolationTable t;
  // Handle points take their handle's transform exactly (pinned below, after the pass over
  // every point: no per-point copy of the labels).
  std::vector<int> fixed_cluster(handles.fixed.size(), -1);
  for (const auto& cl : c.clusters)
    if (cl.kind == ClusterKind::Fixed) fixed_cluster[static_cast<std::size_t>(cl.handle)] = cl.id;
  // Pairs: sorted unique (lower, upper), looked up by binary search.
  t.pairs.reserve(c.adjacency.size() * 2 + c.clusters.size());
  for (std::size_t i = 0; i < n; ++i)
    if (t.pairs.empty() || t.pairs.back() != std::make_pair(c.lower[i], c.upper[i]))
      t.pairs.emplace_back(c.lower[i], c.upper[i]);
  for (std::size_t k = 0; k < handles.fixed.size(); ++k)
    if (!handles.fixed[k].empty()) t.pairs.emplace_back(fixed_cluster[k], fixed_cluster[k]);
  if (!handles.manipulated.empty()) t.pairs.emplace_back(c.manipulated, c.manipulated);
  std::sort(t.pairs.begin(), t.pairs.end());
  t.pairs.erase(std::unique(t.pairs.begin(), t.pairs.end()), t.pairs.end());
  auto pairOf = [&](int lo, int hi) {
    return static_cast<std::uint32_t>(
        std::lower_bound(t.pairs.begin(), t.pairs.end(), std::make_pair(lo, hi)) - t.pairs.begin());
  };
  t.has_normals = normals != nullptr && normals->size() == n;
  t.points.resize(n);
  if (t.has_normals) t.normals.resize(n);
  const long long nn = static_cast<long long>(n);
#pragma omp parallel for schedule(static) if (nn > kParallelMin)
  for (long long ii = 0; ii < nn; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    InterpolationTable::Point& r = t.points[i];
    for (int a = 0; a < 3; ++a) r.p[a] = points[i].data[a];
    if (t.has_normals) t.normals[i] = (*normals)[i].getNormalVector3fMap();
    r.pair = pairOf(c.lower[i], c.upper[i]);
    r.alpha = c.alpha[i];
  }
  auto pin = [&](const std::vector<int>& idx, int cluster) {
    const std::uint32_t pair = pairOf(cluster, cluster);
    for (const int i : idx) {
      t.points[static_cast<std::size_t>(i)].pair = pair;
      t.points[static_cast<std::size_t>(i)].alpha = 0.0f;
    }
  };
  for (std::size_t k = 0; k < handles.fixed.size(); ++k) pin(handles.fixed[k], fixed_cluster[k]);
  pin(handles.manipulated, c.manipulated);  // last: a point in both keeps the manipulated one
  for (const auto& [a, b] : t.pairs)
    t.pair_centre.push_back((0.5 * (c.clusters[static_cast<std::size_t>(a)].barycentre +
                                    c.clusters[static_cast<std::size_t>(b)].barycentre))
                                .cast<float>());
  return t;
}

void LocalTransform::set(const Eigen::Matrix3f& a, const Eigen::Vector3f& translation,
                         const Eigen::Vector3f& barycentre) {
  A = a;
  b = translation;
  // Polar decomposition through the SVD: R = U V^T, a proper rotation.
  R = nearestRotation(a);
  q = Eigen::Quaternionf(R).normalized();
  rb = a * barycentre + b - R * barycentre;
  g = barycentre;
}

namespace {
// A^-T n up to scale: the cofactor matrix, which keeps the normal's side even where the
// blended matrix is nearly singular.
Eigen::Vector3f transformNormal(const Eigen::Matrix3f& m, const Eigen::Vector3f& n) {
  Eigen::Matrix3f cof;
  cof.col(0) = m.col(1).cross(m.col(2));
  cof.col(1) = m.col(2).cross(m.col(0));
  cof.col(2) = m.col(0).cross(m.col(1));
  const Eigen::Vector3f out = cof * n;
  const float len = out.norm();
  return len > 0 ? Eigen::Vector3f(out / len) : n;
}
}  // namespace

namespace {

// The rotation-aware blend, per pair: the images of its centre c under both rigid parts and the
// two quaternions on the same hemisphere; per point, p' = R(w) (p - c) + lerp of the images.
struct PairFrame {
  Eigen::Vector4f qa, qb;
  Eigen::Vector3f c, ta, tb;
  const LocalTransform* own;  // lower == upper: the cluster's own (full) transform applies
};

std::vector<PairFrame> pairFrames(const InterpolationTable& table,
                                  const std::vector<LocalTransform>& transforms) {
  std::vector<PairFrame> frames(table.pairs.size());
  for (std::size_t k = 0; k < table.pairs.size(); ++k) {
    const LocalTransform& a = transforms[static_cast<std::size_t>(table.pairs[k].first)];
    const LocalTransform& b = transforms[static_cast<std::size_t>(table.pairs[k].second)];
    PairFrame& f = frames[k];
    f.own = table.pairs[k].first == table.pairs[k].second ? &a : nullptr;
    f.c = table.pair_centre[k];
    f.ta = a.R * f.c + a.rb;
    f.tb = b.R * f.c + b.rb;
    f.qa = a.q.coeffs();
    f.qb = a.q.dot(b.q) < 0 ? Eigen::Vector4f(-b.q.coeffs()) : Eigen::Vector4f(b.q.coeffs());
  }
  return frames;
}

// x turned by the rotation of the quaternion q = (1 - w) qa + w qb, not normalised first: for a
// unit quaternion (u, qw), R x = x + 2 (qw (u x x) + u x (u x x)); for q, the 2 becomes 2 / |q|^2.
// Two cross products a point: fewer operations than building the matrix.
inline Eigen::Vector3f blendedRotate(const PairFrame& f, float w, const Eigen::Vector3f& x) {
  const float v = 1.0f - w;
  const Eigen::Vector4f q = v * f.qa + w * f.qb;  // (x, y, z, w), Eigen's order
  const float s = 2.0f / q.squaredNorm();
  const Eigen::Vector3f u = q.head<3>();
  const Eigen::Vector3f a = u.cross(x);
  return x + s * (q[3] * a + u.cross(a));
}

// Every point of the table, in parallel: `linear(i, record, lower, upper)` with the two
// clusters' transforms, or for the rotation-aware blend `rotation(i, record, pair frame)`.
template <typename Linear, typename Rotation>
void forEachPoint(const InterpolationTable& table, const std::vector<LocalTransform>& transforms, Blend blend,
                  Linear&& linear, Rotation&& rotation) {
  const long long n = static_cast<long long>(table.size());
  const InterpolationTable::Point* pts = table.points.data();
  if (blend == Blend::Linear) {
    const std::pair<int, int>* pairs = table.pairs.data();
    const LocalTransform* tr = transforms.data();
#pragma omp parallel for schedule(static) if (n > kParallelMin)
    for (long long i = 0; i < n; ++i) {
      const std::pair<int, int>& pr = pairs[pts[i].pair];
      linear(i, pts[i], tr[pr.first], tr[pr.second]);
    }
    return;
  }
  const std::vector<PairFrame> frames = pairFrames(table, transforms);
  const PairFrame* fr = frames.data();
#pragma omp parallel for schedule(static) if (n > kParallelMin)
  for (long long i = 0; i < n; ++i) rotation(i, pts[i], fr[pts[i].pair]);
}

}  // namespace

void interpolatePositions(const InterpolationTable& table, const std::vector<LocalTransform>& transforms,
                          std::vector<Eigen::Vector3f>& out_points, Blend blend) {
  using Point = InterpolationTable::Point;
  Eigen::Vector3f* out = out_points.data();
  forEachPoint(
      table, transforms, blend,
      [out](long long i, const Point& r, const LocalTransform& a, const LocalTransform& b) {
        const float w = r.alpha;
        const Eigen::Matrix3f m = (1.0f - w) * a.A + w * b.A;
        out[i] = m * Eigen::Vector3f(r.p[0], r.p[1], r.p[2]) + (1.0f - w) * a.b + w * b.b;
      },
      [out](long long i, const Point& r, const PairFrame& f) {
        const Eigen::Vector3f p(r.p[0], r.p[1], r.p[2]);
        const float w = r.alpha, v = 1.0f - w;
        out[i] = f.own ? Eigen::Vector3f(f.own->A * p + f.own->b)
                       : Eigen::Vector3f(blendedRotate(f, w, p - f.c) + v * f.ta + w * f.tb);
      });
}

void interpolateNormals(const InterpolationTable& table, const std::vector<LocalTransform>& transforms,
                        std::vector<Eigen::Vector3f>& out_normals, Blend blend) {
  if (!table.has_normals) return;
  using Point = InterpolationTable::Point;
  const Eigen::Vector3f* rest = table.normals.data();
  Eigen::Vector3f* out = out_normals.data();
  forEachPoint(
      table, transforms, blend,
      [out, rest](long long i, const Point& r, const LocalTransform& a, const LocalTransform& b) {
        const float w = r.alpha;
        out[i] = transformNormal((1.0f - w) * a.A + w * b.A, rest[i]);
      },
      [out, rest](long long i, const Point& r, const PairFrame& f) {
        // A rotation: R^-T = R.
        out[i] = f.own ? transformNormal(f.own->A, rest[i]) : blendedRotate(f, r.alpha, rest[i]);
      });
}

void interpolate(const InterpolationTable& table, const std::vector<LocalTransform>& transforms,
                 std::vector<Eigen::Vector3f>& out_points, std::vector<Eigen::Vector3f>* out_normals,
                 Blend blend) {
  interpolatePositions(table, transforms, out_points, blend);
  if (out_normals != nullptr) interpolateNormals(table, transforms, *out_normals, blend);
}

}  // namespace hgd
