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
  std::vector<int> lower = c.lower, upper = c.upper;
  std::vector<float> alpha = c.alpha;
  // Handle points take their handle's transform exactly.
  std::vector<int> fixed_cluster(handles.fixed.size(), -1);
  for (const auto& cl : c.clusters)
    if (cl.kind == ClusterKind::Fixed) fixed_cluster[static_cast<std::size_t>(cl.handle)] = cl.id;
  auto pin = [&](int i, int cluster) {
    lower[static_cast<std::size_t>(i)] = upper[static_cast<std::size_t>(i)] = cluster;
    alpha[static_cast<std::size_t>(i)] = 0.0f;
  };
  for (std::size_t k = 0; k < handles.fixed.size(); ++k)
    for (int i : handles.fixed[k]) pin(i, fixed_cluster[k]);
  for (int i : handles.manipulated) pin(i, c.manipulated);
  // Pairs: sorted unique (lower, upper), looked up by binary search.
  t.pairs.reserve(c.adjacency.size() * 2 + c.clusters.size());
  for (std::size_t i = 0; i < n; ++i)
    if (t.pairs.empty() || t.pairs.back() != std::make_pair(lower[i], upper[i]))
      t.pairs.emplace_back(lower[i], upper[i]);
  std::sort(t.pairs.begin(), t.pairs.end());
  t.pairs.erase(std::unique(t.pairs.begin(), t.pairs.end()), t.pairs.end());
  t.has_normals = normals != nullptr && normals->size() == n;
  t.points.resize(n);
  const long long nn = static_cast<long long>(n);
#pragma omp parallel for schedule(static) if (nn > kParallelMin)
  for (long long ii = 0; ii < nn; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    InterpolationTable::Point& r = t.points[i];
    for (int a = 0; a < 3; ++a) {
      r.p[a] = points[i].data[a];
      r.n[a] = t.has_normals ? (*normals)[i].normal[a] : 0.0f;
    }
    r.pair = static_cast<int>(
        std::lower_bound(t.pairs.begin(), t.pairs.end(), std::make_pair(lower[i], upper[i])) -
        t.pairs.begin());
    r.alpha = alpha[i];
  }
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

void interpolate(const InterpolationTable& table, const std::vector<LocalTransform>& transforms,
                 std::vector<Eigen::Vector3f>& out_points, std::vector<Eigen::Vector3f>* out_normals,
                 Blend blend) {
  const long long n = static_cast<long long>(table.size());
  const bool do_normals = table.has_normals && out_normals != nullptr;
  const InterpolationTable::Point* pts = table.points.data();
  Eigen::Vector3f* out_p = out_points.data();
  Eigen::Vector3f* out_n = do_normals ? out_normals->data() : nullptr;
  if (blend == Blend::Linear) {
#pragma omp parallel for schedule(static) if (n > kParallelMin)
    for (long long i = 0; i < n; ++i) {
      const InterpolationTable::Point& r = pts[i];
      const auto& pr = table.pairs[static_cast<std::size_t>(r.pair)];
      const LocalTransform& a = transforms[static_cast<std::size_t>(pr.first)];
      const LocalTransform& b = transforms[static_cast<std::size_t>(pr.second)];
      const float w = r.alpha;
      const Eigen::Matrix3f m = (1.0f - w) * a.A + w * b.A;
      out_p[i] = m * Eigen::Vector3f(r.p[0], r.p[1], r.p[2]) + (1.0f - w) * a.b + w * b.b;
      if (out_n) out_n[i] = transformNormal(m, Eigen::Vector3f(r.n[0], r.n[1], r.n[2]));
    }
    return;
  }
  // Rotation-aware: per pair, the images of its centre c under both rigid parts and the two
  // quaternions on the same hemisphere; per point, p' = R(w) (p - c) + lerp of the images.
  struct PairFrame {
    Eigen::Vector4f qa, qb;
    Eigen::Vector3f c, ta, tb;
    const LocalTransform* own;  // lower == hi: the cluster's own (full) transform applies
  };
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
  const PairFrame* fr = frames.data();
#pragma omp parallel for schedule(static) if (n > kParallelMin)
  for (long long i = 0; i < n; ++i) {
    const InterpolationTable::Point& r = pts[i];
    const PairFrame& f = fr[r.pair];
    const Eigen::Vector3f p(r.p[0], r.p[1], r.p[2]);
    if (f.own) {
      out_p[i] = f.own->A * p + f.own->b;
      if (out_n) out_n[i] = transformNormal(f.own->A, Eigen::Vector3f(r.n[0], r.n[1], r.n[2]));
      continue;
    }
    // The rotation of the quaternion (1 - w) qa + w qb without normalising it first: scaled
    // by s = 2 / |q|^2 (the same matrix, fewer operations in this per-point loop).
    const float w = r.alpha, v = 1.0f - w;
    const float qx = v * f.qa[0] + w * f.qb[0], qy = v * f.qa[1] + w * f.qb[1],
                qz = v * f.qa[2] + w * f.qb[2], qw = v * f.qa[3] + w * f.qb[3];
    const float s = 2.0f / (qx * qx + qy * qy + qz * qz + qw * qw);
    const float xx = s * qx * qx, yy = s * qy * qy, zz = s * qz * qz, xy = s * qx * qy, xz = s * qx * qz,
                yz = s * qy * qz, wx = s * qw * qx, wy = s * qw * qy, wz = s * qw * qz;
    Eigen::Matrix3f m;
    m << 1.0f - (yy + zz), xy - wz, xz + wy,  //
        xy + wz, 1.0f - (xx + zz), yz - wx,   //
        xz - wy, yz + wx, 1.0f - (xx + yy);
    out_p[i] = m * (p - f.c) + v * f.ta + w * f.tb;
    if (out_n) out_n[i] = m * Eigen::Vector3f(r.n[0], r.n[1], r.n[2]);  // a rotation: R^-T = R
  }
}

}  // namespace hgd
