#include "hgdeform/cluster/pieces.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <flann/flann.hpp>
#include <memory>

namespace hgd {

std::vector<std::string> PieceReport::warnings() const {
  std::vector<std::string> out;
  char buf[400];
  if (followed_points > 0) {
    std::snprintf(buf, sizeof buf,
                  "%zu points in %zu piece%s that touch no handle lie against the surface the handles "
                  "reach: they follow the deformation of the nearest reached points",
                  followed_points, followed_pieces, followed_pieces == 1 ? "" : "s");
    out.emplace_back(buf);
  }
  if (stayed_points > 0) {
    std::snprintf(buf, sizeof buf,
                  "%zu points in %zu piece%s that touch no handle lie apart from the surface the handles "
                  "reach (farther than %.4g): they stay where they are",
                  stayed_points, stayed_pieces, stayed_pieces == 1 ? "" : "s", reach);
    out.emplace_back(buf);
  }
  if (rigid_points > 0) {
    std::snprintf(buf, sizeof buf,
                  "%zu points in %zu piece%s that hold%s the manipulated handle but no fixed handle move "
                  "rigidly with the handle",
                  rigid_points, rigid_pieces, rigid_pieces == 1 ? "" : "s", rigid_pieces == 1 ? "s" : "");
    out.emplace_back(buf);
  }
  return out;
}

PieceAnalysis analysePieces(const pcl::PointCloud<pcl::PointXYZ>& points, const NeighborGraph& graph,
                            const std::vector<int>& piece_label, const Handles& handles,
                            const std::vector<int>& sample, double reach_spacings,
                            const std::vector<std::uint32_t>* weight) {
  PieceAnalysis out;
  const std::size_t n = points.size();
  if (weight && weight->size() != n) weight = nullptr;
  auto points_of = [&](std::size_t i) -> std::size_t { return weight ? (*weight)[i] : 1; };
  out.follow.assign(n, -1);
  if (n == 0 || piece_label.size() != n) return out;
  const std::size_t pieces =
      static_cast<std::size_t>(*std::max_element(piece_label.begin(), piece_label.end())) + 1;
  std::vector<char> fixed(pieces, 0), manipulated(pieces, 0);
  std::vector<std::size_t> size(pieces, 0);
  for (const auto& f : handles.fixed)
    for (int i : f) fixed[static_cast<std::size_t>(piece_label[static_cast<std::size_t>(i)])] = 1;
  for (int i : handles.manipulated)
    manipulated[static_cast<std::size_t>(piece_label[static_cast<std::size_t>(i)])] = 1;
  for (std::size_t i = 0; i < n; ++i) size[static_cast<std::size_t>(piece_label[i])] += points_of(i);
  bool any_unreached = false;
  for (std::size_t p = 0; p < pieces; ++p) {
    if (manipulated[p] && !fixed[p]) {
      ++out.report.rigid_pieces;
      out.report.rigid_points += size[p];
    }
    any_unreached = any_unreached || (!manipulated[p] && !fixed[p]);
  }
  if (!any_unreached) return out;
  auto reached = [&](std::size_t i) {
    const auto p = static_cast<std::size_t>(piece_label[i]);
    return fixed[p] || manipulated[p];
  };

  // The reached part of the surface sample, in a k-d tree (a few thousand points).
  std::vector<int> anchors;
  for (int s : sample)
    if (reached(static_cast<std::size_t>(s))) anchors.push_back(s);
  if (anchors.empty())  // a sample that missed every reached point: take the handles
    for (int i : handles.manipulated) anchors.push_back(i);
  const std::size_t na = anchors.size();
  std::unique_ptr<float[]> xyz(new float[na * 3]);
  for (std::size_t a = 0; a < na; ++a)
    for (int c = 0; c < 3; ++c)
      xyz[3 * a + static_cast<std::size_t>(c)] = points[static_cast<std::size_t>(anchors[a])].data[c];
  const flann::Matrix<float> data(xyz.get(), na, 3);
  flann::Index<flann::L2_Simple<float>> index(data, flann::KDTreeSingleIndexParams(15));
  index.buildIndex();
  flann::SearchParams params(flann::FLANN_CHECKS_UNLIMITED, 0.0f, true);

  // The sample's spacing: the median distance from a sample point to its nearest other one.
  double spacing = 0;
  if (na > 1) {
    std::vector<int> idx(na * 2);
    std::vector<float> d2(na * 2);
    flann::Matrix<int> mi(idx.data(), na, 2);
    flann::Matrix<float> md(d2.data(), na, 2);
    index.knnSearch(data, mi, md, 2, params);
    std::vector<float> nearest(na);
    for (std::size_t a = 0; a < na; ++a) nearest[a] = std::sqrt(d2[2 * a + 1]);
    std::nth_element(nearest.begin(), nearest.begin() + static_cast<long>(na / 2), nearest.end());
    spacing = nearest[na / 2];
  }
  out.report.reach = reach_spacings * spacing;
  const double reach2 = out.report.reach * out.report.reach;

  // Each unreached point: its nearest reached sample point, then downhill along the graph of
  // reached points to a nearest reached point (a local minimum of the distance).
  std::vector<int> unreached;
  for (std::size_t i = 0; i < n; ++i)
    if (!reached(i)) unreached.push_back(static_cast<int>(i));
  const std::size_t nu = unreached.size();
  std::vector<float> q(nu * 3);
  for (std::size_t u = 0; u < nu; ++u)
    for (int c = 0; c < 3; ++c)
      q[3 * u + static_cast<std::size_t>(c)] = points[static_cast<std::size_t>(unreached[u])].data[c];
  std::vector<int> qi(nu);
  std::vector<float> qd(nu);
  flann::Matrix<float> mq(q.data(), nu, 3);
  flann::Matrix<int> mqi(qi.data(), nu, 1);
  flann::Matrix<float> mqd(qd.data(), nu, 1);
  index.knnSearch(mq, mqi, mqd, 1, params);
  std::vector<int> target(nu, -1);
  std::vector<float> dist2(nu, INFINITY);
  for (std::size_t u = 0; u < nu; ++u) {
    if (qi[u] < 0) continue;
    const Eigen::Vector3f p = points[static_cast<std::size_t>(unreached[u])].getVector3fMap();
    int at = anchors[static_cast<std::size_t>(qi[u])];
    float best = (points[static_cast<std::size_t>(at)].getVector3fMap() - p).squaredNorm();
    for (int from = -1; from != at;) {
      from = at;
      for (const int* j = graph.begin(static_cast<std::size_t>(from));
           j != graph.end(static_cast<std::size_t>(from)); ++j) {
        const float d = (points[static_cast<std::size_t>(*j)].getVector3fMap() - p).squaredNorm();
        if (d < best) {  // a neighbour of a reached point is reached (same piece)
          best = d;
          at = *j;
        }
      }
    }
    target[u] = at;
    dist2[u] = best;
  }
  // A piece follows when any of its points lies within the reach.
  std::vector<char> near(pieces, 0);
  std::vector<std::size_t> count(pieces, 0);
  for (std::size_t u = 0; u < nu; ++u) {
    const auto p = static_cast<std::size_t>(piece_label[static_cast<std::size_t>(unreached[u])]);
    if (dist2[u] <= reach2) near[p] = 1;
  }
  std::vector<char> counted(pieces, 0);
  for (std::size_t u = 0; u < nu; ++u) {
    const auto p = static_cast<std::size_t>(piece_label[static_cast<std::size_t>(unreached[u])]);
    const bool first = !counted[p];
    counted[p] = 1;
    if (near[p] && target[u] >= 0) {
      out.follow[static_cast<std::size_t>(unreached[u])] = target[u];
      out.report.followed_points += points_of(static_cast<std::size_t>(unreached[u]));
      out.report.followed_pieces += first;
    } else {
      out.report.stayed_points += points_of(static_cast<std::size_t>(unreached[u]));
      out.report.stayed_pieces += first;
    }
  }
  return out;
}

}  // namespace hgd
