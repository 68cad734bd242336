#include "hgdeform/interp/interpolation.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "hgdeform/io/geometry.h"
#include "interp/table_build.h"
#include "util/parallel.h"
#include "util/timer.h"

namespace hgd {

namespace {
InterpolationTable tableOf(const std::vector<float>& phi, const Handles& handles, const Clustering& c,
                           const pcl::PointCloud<pcl::PointXYZ>& points) {
  const std::size_t n = phi.size();
  if (points.size() != n || c.lower.size() != n || c.upper.size() != n || c.alpha.size() != n)
    throw std::invalid_argument(
        "buildInterpolation: the field, the points and the clustering's per-point labels differ in size");
  return detail::buildTable(
      handles, c, points, detail::labelPairs(c),
      [&](std::size_t i, int& lo, int& hi, float& alpha) {
        lo = c.lower[i];
        hi = c.upper[i];
        alpha = c.alpha[i];
      },
      [](InterpolationTable&) {});
}
}  // namespace

InterpolationTable buildInterpolation(const std::vector<float>& phi, const Handles& handles,
                                      const Clustering& c, const pcl::PointCloud<pcl::PointXYZ>& points,
                                      pcl::PointCloud<pcl::Normal>::ConstPtr normals) {
  InterpolationTable t = tableOf(phi, handles, c, points);
  t.has_normals = normals && normals->size() == t.size();
  if (t.has_normals) t.normal_cloud = std::move(normals);
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
template <typename S>
Eigen::Matrix<S, 3, 1> transformNormal(const Eigen::Matrix<S, 3, 3>& m, const Eigen::Matrix<S, 3, 1>& n) {
  Eigen::Matrix<S, 3, 3> cof;
  cof.col(0) = m.col(1).cross(m.col(2));
  cof.col(1) = m.col(2).cross(m.col(0));
  cof.col(2) = m.col(0).cross(m.col(1));
  const Eigen::Matrix<S, 3, 1> out = cof * n;
  const S len = out.norm();
  return len > 0 ? Eigen::Matrix<S, 3, 1>(out / len) : n;
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

namespace {
// The normals pass with the rest normals read by `rest(i)` (the table's own, or a shared cloud's).
template <typename Rest>
void turnNormals(const InterpolationTable& table, const std::vector<LocalTransform>& transforms,
                 Eigen::Vector3f* out, Blend blend, Rest rest) {
  using Point = InterpolationTable::Point;
  forEachPoint(
      table, transforms, blend,
      [out, rest](long long i, const Point& r, const LocalTransform& a, const LocalTransform& b) {
        const float w = r.alpha;
        out[i] = transformNormal<float>((1.0f - w) * a.A + w * b.A, rest(i));
      },
      [out, rest](long long i, const Point& r, const PairFrame& f) {
        // A rotation: R^-T = R.
        out[i] = f.own ? transformNormal(f.own->A, rest(i)) : blendedRotate(f, r.alpha, rest(i));
      });
}
}  // namespace

void interpolateNormals(const InterpolationTable& table, const std::vector<LocalTransform>& transforms,
                        std::vector<Eigen::Vector3f>& out_normals, Blend blend) {
  if (!table.has_normals) return;
  if (table.normal_cloud) {
    const pcl::Normal* rest = table.normal_cloud->data();
    turnNormals(table, transforms, out_normals.data(), blend, [rest](long long i) {
      return Eigen::Vector3f(rest[i].normal_x, rest[i].normal_y, rest[i].normal_z);
    });
  } else {
    const Eigen::Vector3f* rest = table.normals.data();
    turnNormals(table, transforms, out_normals.data(), blend, [rest](long long i) { return rest[i]; });
  }
}

void interpolate(const InterpolationTable& table, const std::vector<LocalTransform>& transforms,
                 std::vector<Eigen::Vector3f>& out_points, std::vector<Eigen::Vector3f>* out_normals,
                 Blend blend) {
  interpolatePositions(table, transforms, out_points, blend);
  if (out_normals != nullptr) interpolateNormals(table, transforms, *out_normals, blend);
}

ExactInterpolation::ExactInterpolation(const InterpolationTable& table,
                                       std::vector<ExactTransform> transforms,
                                       const std::vector<Eigen::Vector3d>& barycentres, Blend blend)
    : table_(&table), transforms_(std::move(transforms)), blend_(blend) {
  pairs_.resize(table.pairs.size());
  std::vector<Eigen::Quaterniond> q(transforms_.size());
  std::vector<Eigen::Matrix3d> r(transforms_.size());
  for (std::size_t c = 0; c < transforms_.size(); ++c) {
    r[c] = transforms_[c].identity ? Eigen::Matrix3d::Identity() : nearestRotation(transforms_[c].A);
    q[c] = Eigen::Quaterniond(r[c]).normalized();
  }
  for (std::size_t k = 0; k < table.pairs.size(); ++k) {
    Pair& p = pairs_[k];
    p.lower = table.pairs[k].first;
    p.upper = table.pairs[k].second;
    const auto a = static_cast<std::size_t>(p.lower), b = static_cast<std::size_t>(p.upper);
    p.c = 0.5 * (barycentres[a] + barycentres[b]);
    // The rigid part x -> R x + rb maps the cluster's barycentre g where A maps it.
    auto rigidImage = [&](std::size_t t, const Eigen::Vector3d& x) {
      const ExactTransform& e = transforms_[t];
      const Eigen::Vector3d& g = barycentres[t];
      return Eigen::Vector3d(r[t] * (x - g) + e.A * g + e.b);
    };
    p.ta = rigidImage(a, p.c);
    p.tb = rigidImage(b, p.c);
    p.qa = q[a].coeffs();
    p.qb = q[a].dot(q[b]) < 0 ? Eigen::Vector4d(-q[b].coeffs()) : Eigen::Vector4d(q[b].coeffs());
  }
}

bool ExactInterpolation::moves(std::size_t i) const {
  const InterpolationTable::Point& rec = table_->points[i];
  const Pair& p = pairs_[rec.pair];
  const bool lower_moves = rec.alpha != 1.0f && !transforms_[static_cast<std::size_t>(p.lower)].identity;
  const bool upper_moves = rec.alpha != 0.0f && !transforms_[static_cast<std::size_t>(p.upper)].identity;
  return lower_moves || upper_moves;
}

namespace {
// x turned by the rotation of the quaternion (1 - w) qa + w qb (normalised), as blendedRotate.
Eigen::Vector3d blendedRotateExact(const Eigen::Vector4d& qa, const Eigen::Vector4d& qb, double w,
                                   const Eigen::Vector3d& x) {
  const Eigen::Vector4d q = (1.0 - w) * qa + w * qb;
  const double s = 2.0 / q.squaredNorm();
  const Eigen::Vector3d u = q.head<3>();
  const Eigen::Vector3d a = u.cross(x);
  return x + s * (q[3] * a + u.cross(a));
}
}  // namespace

Eigen::Vector3d ExactInterpolation::apply(std::size_t i, const Eigen::Vector3d& x) const {
  const InterpolationTable::Point& rec = table_->points[i];
  const Pair& p = pairs_[rec.pair];
  const double w = rec.alpha;
  const ExactTransform& a = transforms_[static_cast<std::size_t>(p.lower)];
  const ExactTransform& b = transforms_[static_cast<std::size_t>(p.upper)];
  if (p.lower == p.upper) return a.identity ? x : Eigen::Vector3d(a.A * x + a.b);
  if (blend_ == Blend::Linear) return ((1.0 - w) * a.A + w * b.A) * x + (1.0 - w) * a.b + w * b.b;
  return blendedRotateExact(p.qa, p.qb, w, x - p.c) + (1.0 - w) * p.ta + w * p.tb;
}

Eigen::Vector3d ExactInterpolation::applyNormal(std::size_t i, const Eigen::Vector3d& n) const {
  const InterpolationTable::Point& rec = table_->points[i];
  const Pair& p = pairs_[rec.pair];
  const double w = rec.alpha;
  const ExactTransform& a = transforms_[static_cast<std::size_t>(p.lower)];
  const ExactTransform& b = transforms_[static_cast<std::size_t>(p.upper)];
  auto cofactor = [&](const Eigen::Matrix3d& m) { return transformNormal(m, n); };
  if (p.lower == p.upper) return a.identity ? n : cofactor(a.A);
  if (blend_ == Blend::Linear) return cofactor((1.0 - w) * a.A + w * b.A);
  return blendedRotateExact(p.qa, p.qb, w, n);
}

}  // namespace hgd
