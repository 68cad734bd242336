#include "hgdeform/interpolation.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>

namespace hgd {

InterpolationTable buildInterpolation(const std::vector<float>& phi, const Handles& handles,
                                      const Clustering& c) {
  const std::size_t n = phi.size();
  InterpolationTable t;
  t.lo = c.down;
  t.hi = c.up;
  t.alpha.assign(n, 0.0f);
  const int top = static_cast<int>(c.levels.size()) - 1;
  for (std::size_t i = 0; i < n; ++i) {
    // Eq. (1): the position of phi_i between the isovalues of its slab.
    const double x = static_cast<double>(phi[i]) * top;
    const double slab = std::clamp(std::floor(x), 0.0, static_cast<double>(top - 1));
    t.alpha[i] = t.lo[i] == t.hi[i] ? 0.0f : static_cast<float>(std::clamp(x - slab, 0.0, 1.0));
  }
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
