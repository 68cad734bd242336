#include <omp.h>

#include <algorithm>
#include <cstring>
#include <stdexcept>

#include "deformer/deformer_impl.h"
#include "deformer/xyz_access.h"
#include "hgdeform/io/fields.h"
#include "hgdeform/io/io.h"
#include "util/parallel.h"

namespace hgd {

ExactInterpolation Deformer::Impl::exactInterpolation(const InterpolationTable& table) const {
  std::vector<Eigen::Vector3d> barycentres;
  barycentres.reserve(data_.clustering.clusters.size());
  for (const Cluster& cl : data_.clustering.clusters) barycentres.push_back(cl.barycentre);
  return ExactInterpolation(table, exact_, barycentres, options_.blend);
}

std::vector<Eigen::Affine3d> Deformer::Impl::worldTransforms() const {
  std::vector<Eigen::Affine3d> out;
  const Eigen::Vector3d o = geometry_->origin;
  for (const ExactTransform& e : exact_) {
    Eigen::Affine3d t = Eigen::Affine3d::Identity();
    t.linear() = e.A;
    t.translation() = e.b + o - e.A * o;
    out.push_back(t);
  }
  return out;
}

std::vector<std::string> Deformer::Impl::writeDeformed(Shape& shape) const {
  std::vector<std::string> warnings;
  pcl::PCLPointCloud2& c = shape.cloud;
  XyzFields f = findXyzFields(c);
  const Geometry& g = *geometry_;
  const std::size_t n = static_cast<std::size_t>(c.width) * c.height;
  if (!f.hasXyz() || g.raw_index.size() != data_.table.size() || g.finite_index.size() != n)
    throw std::logic_error("Deformer::writeDeformed: the shape is not the one the deformer was built on");
  // Nothing moves: every point as the file had it, to the bit (nothing read, nothing written).
  if (std::all_of(exact_.begin(), exact_.end(), [](const ExactTransform& e) { return e.identity; }))
    return warnings;
  const ExactInterpolation exact = exactInterpolation();
  const long long nn = static_cast<long long>(n);
  // In the file's order: the cloud's records are read and written in sequence. The table's
  // records are in the deformer's spatial order, so a file in any other order (a resampled or
  // merged scan) reads them at random: each is fetched a few dozen points ahead, so that the
  // cache misses overlap (at 4M shuffled points, one miss per point per pass).
  constexpr long long kAhead = 32;
  const InterpolationTable::Point* records = data_.table.points.data();
  auto forEachPoint = [&](auto&& body) {
#pragma omp parallel for schedule(static) if (nn > kParallelMin)
    for (long long ii = 0; ii < nn; ++ii) {
      const auto i = static_cast<std::size_t>(ii);
      if (ii + kAhead < nn) {
        const int ahead = g.finite_index[i + kAhead];
        if (ahead >= 0) __builtin_prefetch(records + ahead);
      }
      const int k = g.finite_index[i];
      if (k >= 0) body(i, static_cast<std::size_t>(k));
    }
  };
  // The shape must hold the rest positions (a second call on the same shape would move it twice):
  // its values give the table's float rest positions exactly, as extractGeometry made them.
  {
    std::vector<char> bad(static_cast<std::size_t>(omp_get_max_threads()), 0);
    const XyzAccess xyz(c, f);
    forEachPoint([&](std::size_t i, std::size_t k) {
      const Eigen::Vector3f p = (xyz.get(i) - g.origin).cast<float>();
      const float* r = data_.table.points[k].p;
      if (!(p.x() == r[0] && p.y() == r[1] && p.z() == r[2]))
        bad[static_cast<std::size_t>(omp_get_thread_num())] = 1;
    });
    if (std::find(bad.begin(), bad.end(), 1) != bad.end())
      throw std::logic_error(
          "Deformer::writeDeformed: the shape does not hold the rest positions (written to already?)");
  }
  // Integer coordinates cannot hold a deformed position: each is widened (8 and 16 bits to float,
  // 32 to double), said, never rounded or clipped.
  {
    std::vector<int> to_float, to_double;
    for (const int idx : {f.x, f.y, f.z}) {
      const std::uint8_t t = c.fields[static_cast<std::size_t>(idx)].datatype;
      if (t == pcl::PCLPointField::FLOAT32 || t == pcl::PCLPointField::FLOAT64) continue;
      (t == pcl::PCLPointField::INT32 || t == pcl::PCLPointField::UINT32 ? to_double : to_float)
          .push_back(idx);
    }
    if (!to_float.empty()) retypeFields(c, to_float, pcl::PCLPointField::FLOAT32);
    if (!to_double.empty()) retypeFields(c, to_double, pcl::PCLPointField::FLOAT64);
    if (!to_float.empty() || !to_double.empty()) {
      f = findXyzFields(c);
      warnings.push_back(
          (shape.path.empty() ? std::string("the shape") : shape.path) +
          ": x/y/z are stored as integers, which cannot hold the deformed positions: written as " +
          (to_double.empty()  ? "float"
           : to_float.empty() ? "double"
                              : "float and double"));
    }
  }
  // Normals are turned where the file's own were used (all finite and non-zero): else they are
  // left as the file had them, and that is said.
  const bool write_normals = f.hasNormals() && g.hasFileNormals() && data_.table.has_normals;
  if (f.hasNormals() && !write_normals)
    warnings.push_back((shape.path.empty() ? std::string("the shape") : shape.path) +
                       ": its normals were not usable (some are zero or not finite): they are written back "
                       "as they were, not turned with the shape");
  XyzAccess xyz(c, f);
  forEachPoint([&](std::size_t i, std::size_t k) {
    if (!exact.moves(k)) return;  // left as the file had it
    xyz.set(i, exact.apply(k, xyz.get(i) - g.origin) + g.origin);
    if (write_normals) {
      const Eigen::Vector3d nv = exact.applyNormal(k, data_.table.restNormal(k).cast<double>());
      writeValue(c, i, c.fields[f.nx], nv.x());
      writeValue(c, i, c.fields[f.ny], nv.y());
      writeValue(c, i, c.fields[f.nz], nv.z());
    }
  });
  // An OBJ's own normals turn as the normal of the vertex a face pairs them with turns.
  const auto turn = [&](int v, Eigen::Quaterniond& q) {
    if (v < 0 || static_cast<std::size_t>(v) >= g.finite_index.size()) return false;
    const int fi = g.finite_index[static_cast<std::size_t>(v)];
    if (fi < 0 || !exact.moves(static_cast<std::size_t>(fi))) return false;
    const auto i = static_cast<std::size_t>(fi);
    const Eigen::Vector3d n0 = data_.table.restNormal(i).cast<double>();  // the rest normal that turns
    const Eigen::Vector3d n1 = exact.applyNormal(i, n0);
    if (!(n0.squaredNorm() > 0) || !(n1.squaredNorm() > 0) || !n0.allFinite() || !n1.allFinite())
      return false;
    q = Eigen::Quaterniond::FromTwoVectors(n0, n1);
    return true;
  };
  turnObjNormals(shape.extras,
                 data_.table.has_normals ? std::function<bool(int, Eigen::Quaterniond&)>(turn) : nullptr);
  return warnings;
}

}  // namespace hgd
