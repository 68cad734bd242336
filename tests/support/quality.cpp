#include "support/quality.h"

#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_types.h>

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>

namespace hgd {
namespace quality {

double localDistortion(const std::vector<Eigen::Vector3d>& rest, const std::vector<Eigen::Vector3d>& deformed,
                       int k) {
  const std::vector<double> each = localDistortions(rest, deformed, k);
  double sum = 0;
  for (const double d : each) sum += d;
  return sum / static_cast<double>(each.size());
}

std::vector<double> localDistortions(const std::vector<Eigen::Vector3d>& rest,
                                     const std::vector<Eigen::Vector3d>& deformed, int k) {
  if (rest.size() != deformed.size()) throw std::invalid_argument("localDistortion: point counts differ");
  if (rest.size() < static_cast<std::size_t>(k) + 1)
    throw std::invalid_argument("localDistortion: too few points");
  // The k-d tree in offsets from the first point, so that float keeps the local detail.
  const Eigen::Vector3d o = rest[0];
  auto cloud = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  cloud->resize(rest.size());
  for (std::size_t i = 0; i < rest.size(); ++i) {
    const Eigen::Vector3f q = (rest[i] - o).cast<float>();
    (*cloud)[i] = pcl::PointXYZ(q.x(), q.y(), q.z());
  }
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
  tree.setInputCloud(cloud);
  std::vector<double> out(rest.size(), 0.0);
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t ii = 0; ii < static_cast<std::ptrdiff_t>(rest.size()); ++ii) {
    const std::size_t i = static_cast<std::size_t>(ii);
    std::vector<int> nb;
    std::vector<float> d2;
    tree.nearestKSearch((*cloud)[i], k + 1, nb, d2);
    std::vector<Eigen::Vector3d> q, r;
    for (const int j : nb) {
      if (static_cast<std::size_t>(j) == i) continue;
      if (q.size() == static_cast<std::size_t>(k)) break;
      q.push_back(rest[static_cast<std::size_t>(j)] - rest[i]);
      r.push_back(deformed[static_cast<std::size_t>(j)] - deformed[i]);
    }
    Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
    double length = 0;
    for (std::size_t j = 0; j < q.size(); ++j) {
      h += q[j] * r[j].transpose();
      length += q[j].norm();
    }
    if (length <= 0) continue;
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
    d(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1 : 1;
    const Eigen::Matrix3d rot = svd.matrixV() * d * svd.matrixU().transpose();
    double residual = 0;
    for (std::size_t j = 0; j < q.size(); ++j) residual += (rot * q[j] - r[j]).norm();
    out[i] = residual / length;
  }
  return out;
}

std::function<bool(const std::vector<Eigen::Vector3d>&, int)> distortionSettles(
    const std::vector<Eigen::Vector3d>& rest, double relative, double* last) {
  auto history = std::make_shared<std::vector<double>>();
  return [&rest, relative, last, history](const std::vector<Eigen::Vector3d>& now, int) {
    history->push_back(localDistortion(rest, now));
    if (last) *last = history->back();
    const std::size_t k = history->size();
    return k >= 3 && std::abs((*history)[k - 3] - (*history)[k - 1]) <= relative * (*history)[k - 1];
  };
}

double meanDisplacement(const std::vector<Eigen::Vector3d>& rest,
                        const std::vector<Eigen::Vector3d>& deformed, const std::vector<int>& points) {
  if (points.empty()) return 0;
  double sum = 0;
  for (const int i : points)
    sum += (deformed[static_cast<std::size_t>(i)] - rest[static_cast<std::size_t>(i)]).norm();
  return sum / static_cast<double>(points.size());
}

double lengthChange(const std::vector<Eigen::Vector3d>& rest, const std::vector<Eigen::Vector3d>& deformed,
                    const std::vector<int>& a, const std::vector<int>& b) {
  if (a.empty() || b.empty()) return 0;
  const auto centroid = [](const std::vector<Eigen::Vector3d>& at, const std::vector<int>& set) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (const int i : set) c += at[static_cast<std::size_t>(i)];
    return Eigen::Vector3d(c / static_cast<double>(set.size()));
  };
  const double before = (centroid(rest, a) - centroid(rest, b)).norm();
  if (!(before > 0)) return 0;
  return (centroid(deformed, a) - centroid(deformed, b)).norm() / before - 1;
}

double largestLengthChange(const std::vector<Eigen::Vector3d>& rest,
                           const std::vector<Eigen::Vector3d>& deformed, const std::vector<Part>& parts) {
  double worst = 0;
  for (const Part& p : parts) worst = std::max(worst, std::abs(lengthChange(rest, deformed, p.a, p.b)));
  return worst;
}

}  // namespace quality
}  // namespace hgd
