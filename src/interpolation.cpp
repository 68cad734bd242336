#include "hgdeform/interpolation.h"

#include <pcl/kdtree/kdtree_flann.h>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>

namespace hgd {

InterpolationTable buildInterpolation(const pcl::PointCloud<pcl::PointXYZ>& points,
                                      const pcl::PointCloud<pcl::Normal>& normals,
                                      const std::vector<float>& phi, const Handles& handles,
                                      const Clustering& c) {
  const std::size_t n = points.size();
  InterpolationTable t;
  t.lo.assign(n, -1);
  t.hi.assign(n, -1);
  t.alpha.assign(n, 0.0f);
  // Handle points take their handle's transform exactly.
  std::vector<int> fixed_cluster(handles.fixed.size(), -1);
  for (const auto& cl : c.clusters)
    if (cl.kind == ClusterKind::Fixed) fixed_cluster[static_cast<std::size_t>(cl.handle)] = cl.id;
  for (std::size_t k = 0; k < handles.fixed.size(); ++k)
    for (int i : handles.fixed[k])
      t.lo[static_cast<std::size_t>(i)] = t.hi[static_cast<std::size_t>(i)] = fixed_cluster[k];
  for (int i : handles.manipulated)
    t.lo[static_cast<std::size_t>(i)] = t.hi[static_cast<std::size_t>(i)] = c.manipulated;

  pcl::PointCloud<pcl::PointXYZ>::Ptr sp(new pcl::PointCloud<pcl::PointXYZ>);
  sp->resize(c.sample.size());
  for (std::size_t s = 0; s < c.sample.size(); ++s) (*sp)[s] = points[static_cast<std::size_t>(c.sample[s])];
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
  tree.setInputCloud(sp);
  const int k = std::min<int>(6, static_cast<int>(sp->size()));
  const long long nn = static_cast<long long>(n);
  const int top = static_cast<int>(c.levels.size()) - 1;
#pragma omp parallel
  {
    pcl::Indices idx;
    std::vector<float> d2;
#pragma omp for schedule(dynamic, 2048)
    for (long long ii = 0; ii < nn; ++ii) {
      const auto i = static_cast<std::size_t>(ii);
      if (t.lo[i] >= 0) continue;
      tree.nearestKSearch(points[i], k, idx, d2);
      // The nearest sample point on the same side of the surface stands for the point's branch.
      std::size_t s = static_cast<std::size_t>(idx[0]);
      for (int m = 0; m < static_cast<int>(idx.size()); ++m) {
        const int si = c.sample[static_cast<std::size_t>(idx[static_cast<std::size_t>(m)])];
        if (normals[i].getNormalVector3fMap().dot(
                normals[static_cast<std::size_t>(si)].getNormalVector3fMap()) >= 0) {
          s = static_cast<std::size_t>(idx[static_cast<std::size_t>(m)]);
          break;
        }
      }
      const int piece = c.sample_piece[s];
      const Cluster& own = c.clusters[static_cast<std::size_t>(piece)];
      if (own.kind == ClusterKind::Static) {
        t.lo[i] = t.hi[i] = piece;
        continue;
      }
      const double v = phi[i];
      const int level = own.level;
      if (v >= own.phi && level < top) {
        const int up = c.sample_up[s];
        const double span = c.clusters[static_cast<std::size_t>(up)].phi - own.phi;
        t.lo[i] = piece;
        t.hi[i] = up;
        t.alpha[i] = span > 0 ? static_cast<float>(std::clamp((v - own.phi) / span, 0.0, 1.0)) : 0.0f;
      } else if (v < own.phi && level > 0) {
        const int down = c.sample_down[s];
        const double span = own.phi - c.clusters[static_cast<std::size_t>(down)].phi;
        t.lo[i] = down;
        t.hi[i] = piece;
        t.alpha[i] = span > 0 ? static_cast<float>(std::clamp(1.0 - (own.phi - v) / span, 0.0, 1.0)) : 1.0f;
      } else {
        t.lo[i] = t.hi[i] = piece;
      }
    }
  }
  return t;
}

void interpolate(const InterpolationTable& table, const std::vector<LocalAffine>& transforms,
                 const pcl::PointCloud<pcl::PointXYZ>& points, const pcl::PointCloud<pcl::Normal>* normals,
                 std::vector<Eigen::Vector3f>& out_points, std::vector<Eigen::Vector3f>* out_normals) {
  const long long n = static_cast<long long>(table.size());
  const bool do_normals = normals != nullptr && out_normals != nullptr && normals->size() == table.size();
#pragma omp parallel for schedule(static)
  for (long long ii = 0; ii < n; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    const LocalAffine& a = transforms[static_cast<std::size_t>(table.lo[i])];
    const LocalAffine& b = transforms[static_cast<std::size_t>(table.hi[i])];
    const float w = table.alpha[i];
    const Eigen::Matrix3f m = (1.0f - w) * a.A + w * b.A;
    const Eigen::Vector3f tr = (1.0f - w) * a.b + w * b.b;
    out_points[i] = m * points[i].getVector3fMap() + tr;
    if (do_normals) {
      // A^-T n = cofactor(A) n / det(A): the cofactor matrix avoids the division's sign trap.
      Eigen::Matrix3f cof;
      cof.col(0) = m.col(1).cross(m.col(2));
      cof.col(1) = m.col(2).cross(m.col(0));
      cof.col(2) = m.col(0).cross(m.col(1));
      Eigen::Vector3f nv = cof * (*normals)[i].getNormalVector3fMap();
      const float len = nv.norm();
      (*out_normals)[i] =
          len > 0 ? Eigen::Vector3f(nv / len) : Eigen::Vector3f((*normals)[i].getNormalVector3fMap());
    }
  }
}

}  // namespace hgd
