#include "hgdeform/interpolation.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>

#include "timer.h"

namespace hgd {

InterpolationTable buildInterpolation(const std::vector<float>& phi, const Handles& handles,
                                      const Clustering& c) {
  const std::size_t n = phi.size();
  InterpolationTable t;
  t.lo = c.down;
  t.hi = c.up;
  t.alpha = c.alpha;
  (void)n;
  // Handle points take their handle's transform exactly.
  std::vector<int> fixed_cluster(handles.fixed.size(), -1);
  for (const auto& cl : c.clusters)
    if (cl.kind == ClusterKind::Fixed) fixed_cluster[static_cast<std::size_t>(cl.handle)] = cl.id;
  auto pin = [&](int i, int cluster) {
    t.lo[static_cast<std::size_t>(i)] = t.hi[static_cast<std::size_t>(i)] = cluster;
    t.alpha[static_cast<std::size_t>(i)] = 0.0f;
  };
  for (std::size_t k = 0; k < handles.fixed.size(); ++k)
    for (int i : handles.fixed[k]) pin(i, fixed_cluster[k]);
  for (int i : handles.manipulated) pin(i, c.manipulated);
  // Pairs: sorted unique (lo, hi), looked up by binary search.
  t.pairs.reserve(c.adjacency.size() * 2 + c.clusters.size());
  for (std::size_t i = 0; i < t.lo.size(); ++i) t.pairs.emplace_back(t.lo[i], t.hi[i]);
  std::sort(t.pairs.begin(), t.pairs.end());
  t.pairs.erase(std::unique(t.pairs.begin(), t.pairs.end()), t.pairs.end());
  t.pair.resize(t.lo.size());
  for (std::size_t i = 0; i < t.lo.size(); ++i)
    t.pair[i] = static_cast<int>(
        std::lower_bound(t.pairs.begin(), t.pairs.end(), std::make_pair(t.lo[i], t.hi[i])) - t.pairs.begin());
  for (const auto& [a, b] : t.pairs)
    t.pair_centre.push_back((0.5 * (c.clusters[static_cast<std::size_t>(a)].barycenter +
                                    c.clusters[static_cast<std::size_t>(b)].barycenter))
                                .cast<float>());
  return t;
}

void LocalAffine::set(const Eigen::Matrix3f& a, const Eigen::Vector3f& translation,
                      const Eigen::Vector3f& barycenter) {
  A = a;
  b = translation;
  // Polar decomposition through the SVD: R = U V^T, a proper rotation.
  Eigen::JacobiSVD<Eigen::Matrix3f> svd(a, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3f u = svd.matrixU();
  const Eigen::Matrix3f v = svd.matrixV();
  if ((u * v.transpose()).determinant() < 0) u.col(2) *= -1.0f;
  R = u * v.transpose();
  q = Eigen::Quaternionf(R).normalized();
  rb = a * barycenter + b - R * barycenter;
  g = barycenter;
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

void interpolate(const InterpolationTable& table, const std::vector<LocalAffine>& transforms,
                 const pcl::PointCloud<pcl::PointXYZ>& points, const pcl::PointCloud<pcl::Normal>* normals,
                 std::vector<Eigen::Vector3f>& out_points, std::vector<Eigen::Vector3f>* out_normals,
                 Blend blend) {
  const long long n = static_cast<long long>(table.size());
  const bool do_normals = normals != nullptr && out_normals != nullptr && normals->size() == table.size();
  if (blend == Blend::Linear) {
#pragma omp parallel for schedule(static) if (n > kParallelMin)
    for (long long ii = 0; ii < n; ++ii) {
      const auto i = static_cast<std::size_t>(ii);
      const LocalAffine& a = transforms[static_cast<std::size_t>(table.lo[i])];
      const LocalAffine& b = transforms[static_cast<std::size_t>(table.hi[i])];
      const float w = table.alpha[i];
      const Eigen::Matrix3f m = (1.0f - w) * a.A + w * b.A;
      out_points[i] = m * points[i].getVector3fMap() + (1.0f - w) * a.b + w * b.b;
      if (do_normals) (*out_normals)[i] = transformNormal(m, (*normals)[i].getNormalVector3fMap());
    }
    return;
  }
  // Rotation-aware: per pair, the images of its centre c under both rigid parts and the two
  // quaternions on the same hemisphere; per point, p' = R(w) (p - c) + lerp of the images.
  struct PairFrame {
    Eigen::Vector4f qa, qb;
    Eigen::Vector3f c, ta, tb;
    bool rigid;  // lo == hi: the cluster's own (full) transform applies
  };
  std::vector<PairFrame> frames(table.pairs.size());
  for (std::size_t k = 0; k < table.pairs.size(); ++k) {
    const LocalAffine& a = transforms[static_cast<std::size_t>(table.pairs[k].first)];
    const LocalAffine& b = transforms[static_cast<std::size_t>(table.pairs[k].second)];
    PairFrame& f = frames[k];
    f.rigid = table.pairs[k].first == table.pairs[k].second;
    f.c = table.pair_centre[k];
    f.ta = a.R * f.c + a.rb;
    f.tb = b.R * f.c + b.rb;
    f.qa = a.q.coeffs();
    f.qb = a.q.dot(b.q) < 0 ? Eigen::Vector4f(-b.q.coeffs()) : Eigen::Vector4f(b.q.coeffs());
  }
#pragma omp parallel for schedule(static) if (n > kParallelMin)
  for (long long ii = 0; ii < n; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    const PairFrame& f = frames[static_cast<std::size_t>(table.pair[i])];
    const Eigen::Vector3f p = points[i].getVector3fMap();
    if (f.rigid) {
      const LocalAffine& a = transforms[static_cast<std::size_t>(table.lo[i])];
      out_points[i] = a.A * p + a.b;
      if (do_normals) (*out_normals)[i] = transformNormal(a.A, (*normals)[i].getNormalVector3fMap());
      continue;
    }
    const float w = table.alpha[i];
    const Eigen::Quaternionf q(Eigen::Vector4f((1.0f - w) * f.qa + w * f.qb).normalized());
    const Eigen::Matrix3f m = q.toRotationMatrix();
    out_points[i] = m * (p - f.c) + (1.0f - w) * f.ta + w * f.tb;
    if (do_normals) (*out_normals)[i] = m * (*normals)[i].getNormalVector3fMap();  // a rotation: R^-T = R
  }
}

}  // namespace hgd
