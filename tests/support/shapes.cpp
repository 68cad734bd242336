#include "support/shapes.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <map>
#include <random>
#include <tuple>

#include "hgdeform/io/geometry.h"
#include "hgdeform/io/io.h"
#include "hgdeform/io/records.h"

namespace hgd {
namespace shapes {

Shape cloudShape(const std::vector<Eigen::Vector3f>& points, const std::vector<Eigen::Vector3f>& normals) {
  Shape s;
  auto& c = s.cloud;
  const char* names[6] = {"x", "y", "z", "nx", "ny", "nz"};
  const int nf = normals.empty() ? 3 : 6;
  for (int f = 0; f < nf; ++f) {
    pcl::PCLPointField pf;
    pf.name = names[f];
    pf.offset = static_cast<std::uint32_t>(4 * f);
    pf.datatype = pcl::PCLPointField::FLOAT32;
    pf.count = 1;
    c.fields.push_back(pf);
  }
  c.point_step = static_cast<std::uint32_t>(4 * nf);
  c.width = static_cast<std::uint32_t>(points.size());
  c.height = 1;
  c.row_step = c.point_step * c.width;
  c.is_dense = true;
  c.data.resize(static_cast<std::size_t>(c.row_step));
  for (std::size_t i = 0; i < points.size(); ++i) {
    float v[6];
    for (int k = 0; k < 3; ++k) v[k] = points[i][k];
    if (nf == 6)
      for (int k = 0; k < 3; ++k) v[3 + k] = normals[i][k];
    std::memcpy(c.data.data() + i * c.point_step, v, c.point_step);
  }
  s.path = "<procedural>";
  return s;
}

namespace {
// Samples the surface of an axis-aligned box [lo, hi] on a grid of spacing ~h, without
// duplicating edge points; normals outward (edges take the first face's normal).
void boxSurface(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, float h,
                std::vector<Eigen::Vector3f>& p, std::vector<Eigen::Vector3f>& n) {
  int cells[3];
  for (int a = 0; a < 3; ++a) cells[a] = std::max(1, static_cast<int>(std::lround((hi[a] - lo[a]) / h)));
  std::map<std::tuple<int, int, int>, bool> seen;
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      for (int i = 0; i <= cells[u]; ++i)
        for (int j = 0; j <= cells[v]; ++j) {
          int g[3];
          g[axis] = side ? cells[axis] : 0;
          g[u] = i;
          g[v] = j;
          if (!seen.emplace(std::make_tuple(g[0], g[1], g[2]), true).second) continue;
          Eigen::Vector3f x;
          for (int a = 0; a < 3; ++a) x[a] = lo[a] + (hi[a] - lo[a]) * static_cast<float>(g[a]) / cells[a];
          Eigen::Vector3f nv = Eigen::Vector3f::Zero();
          for (int a = 0; a < 3; ++a) {
            if (g[a] == 0) nv[a] -= 1;
            if (g[a] == cells[a]) nv[a] += 1;
          }
          p.push_back(x);
          n.push_back(nv.normalized());
        }
    }
}
}  // namespace

Shape bar(float length, float width, float h) {
  std::vector<Eigen::Vector3f> p, n;
  boxSurface({0, -width / 2, -width / 2}, {length, width / 2, width / 2}, h, p, n);
  return cloudShape(p, n);
}

Shape barBesideABox(float h) {
  std::vector<Eigen::Vector3f> p, n;
  boxSurface({0, -0.05f, -0.05f}, {1, 0.05f, 0.05f}, h, p, n);
  boxSurface({0.3f, 0.55f, -0.05f}, {0.6f, 0.75f, 0.05f}, h, p, n);
  return cloudShape(p, n);
}

Shape cylinder(float length, float radius, float h) {
  std::vector<Eigen::Vector3f> p, n;
  const int around = std::max(8, static_cast<int>(std::lround(2 * M_PI * radius / h)));
  const int along = std::max(1, static_cast<int>(std::lround(length / h)));
  for (int i = 0; i <= along; ++i)
    for (int k = 0; k < around; ++k) {
      const float a = static_cast<float>(2 * M_PI * k / around);
      p.emplace_back(length * static_cast<float>(i) / along, radius * std::cos(a), radius * std::sin(a));
      n.emplace_back(0, std::cos(a), std::sin(a));
    }
  for (int side = 0; side < 2; ++side) {
    const float x = side ? length : 0;
    const int rings = std::max(1, static_cast<int>(std::lround(radius / h)));
    for (int r = 0; r < rings; ++r) {
      const float rr = radius * static_cast<float>(r) / rings;
      const int m = std::max(1, static_cast<int>(std::lround(2 * M_PI * rr / h)));
      for (int k = 0; k < m; ++k) {
        const float a = static_cast<float>(2 * M_PI * k / m);
        p.emplace_back(x, rr * std::cos(a), rr * std::sin(a));
        n.emplace_back(side ? 1.0f : -1.0f, 0, 0);
      }
    }
  }
  return cloudShape(p, n);
}

namespace {

/// bumpyPlane's point (i, j) of a grid of `cells`: x, y, z and the normal.
void bumpyPlanePoint(int i, int j, int cells, int bumps, float height, float out[6]) {
  const float sigma = 0.25f / bumps;
  const float x = static_cast<float>(i) / cells, y = static_cast<float>(j) / cells;
  float z = 0;
  Eigen::Vector2f grad = Eigen::Vector2f::Zero();
  for (int a = 0; a < bumps; ++a)
    for (int b = 0; b < bumps; ++b) {
      const float cx = (a + 0.5f) / bumps, cy = (b + 0.5f) / bumps;
      const float dx = x - cx, dy = y - cy;
      const float e = height * std::exp(-(dx * dx + dy * dy) / (2 * sigma * sigma));
      z += e;
      grad += Eigen::Vector2f(-dx, -dy) * e / (sigma * sigma);
    }
  const Eigen::Vector3f n = Eigen::Vector3f(-grad.x(), -grad.y(), 1).normalized();
  const float v[6] = {x, y, z, n.x(), n.y(), n.z()};
  std::memcpy(out, v, sizeof v);
}

int bumpyPlaneCells(float h) {
  return std::max(2, static_cast<int>(std::lround(1.0f / h)));
}

}  // namespace

Shape bumpyPlane(int bumps, float height, float h) {
  std::vector<Eigen::Vector3f> p, n;
  const int cells = bumpyPlaneCells(h);
  for (int i = 0; i <= cells; ++i)
    for (int j = 0; j <= cells; ++j) {
      float v[6];
      bumpyPlanePoint(i, j, cells, bumps, height, v);
      p.emplace_back(v[0], v[1], v[2]);
      n.emplace_back(v[3], v[4], v[5]);
    }
  return cloudShape(p, n);
}

void writeBumpyPlane(const std::string& path, int bumps, float height, float h) {
  const int cells = bumpyPlaneCells(h);
  RecordLayout layout;
  layout.shape = cloudShape({}, {Eigen::Vector3f::Zero()});  // the fields of x, y, z and normals
  layout.shape.format = formatFromPath(path);
  if (layout.shape.format == FileFormat::Pcd)  // writeShape's PCD names them as PCL does
    for (auto& f : layout.shape.cloud.fields)
      if (f.name.size() == 2 && f.name[0] == 'n') f.name = std::string("normal_") + f.name[1];
  layout.count = static_cast<std::uint64_t>(cells + 1) * static_cast<std::uint64_t>(cells + 1);
  if (layout.count > 0xFFFFFFFFull) throw IoError(path + ": more points than a file's width holds");
  layout.shape.cloud.width = static_cast<std::uint32_t>(layout.count);
  layout.shape.cloud.row_step = 0;
  layout.bytes = layout.shape.cloud.point_step;
  writeRecords(path, layout, [&](RecordSink& sink) {
    std::vector<float> row(static_cast<std::size_t>(cells + 1) * 6);
    for (int i = 0; i <= cells; ++i) {
      // A row's points on every thread (a 200M-point plane's Gaussians are minutes on one).
#pragma omp parallel for schedule(static)
      for (int j = 0; j <= cells; ++j)
        bumpyPlanePoint(i, j, cells, bumps, height, &row[static_cast<std::size_t>(j) * 6]);
      sink.write(reinterpret_cast<const std::uint8_t*>(row.data()), row.size() * sizeof(float));
    }
  });
}

Shape fork(float gap, float w, float h) {
  std::vector<Eigen::Vector3f> p, n;
  const float half = gap / 2 + w;  // the base spans both prongs
  boxSurface({0, -half, -w / 2}, {0.4f, half, w / 2}, h, p, n);
  std::vector<Eigen::Vector3f> q, m;
  boxSurface({0.4f + h, gap / 2, -w / 2}, {1.2f, gap / 2 + w, w / 2}, h, q, m);
  boxSurface({0.4f + h, -gap / 2 - w, -w / 2}, {1.2f, -gap / 2, w / 2}, h, q, m);
  // Drop the prongs' inner end caps (they sit against the base).
  for (std::size_t i = 0; i < q.size(); ++i)
    if (!(q[i].x() < 0.4f + 1.5f * h && m[i].x() < -0.5f)) {
      p.push_back(q[i]);
      n.push_back(m[i]);
    }
  return cloudShape(p, n);
}

Shape bumpySphere(std::size_t count, float amp) {
  std::vector<Eigen::Vector3f> p(count), n(count);
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (std::size_t i = 0; i < count; ++i) {
    const double z = 1.0 - 2.0 * (static_cast<double>(i) + 0.5) / static_cast<double>(count);
    const double r = std::sqrt(1.0 - z * z), th = golden * static_cast<double>(i);
    const Eigen::Vector3d d(r * std::cos(th), r * std::sin(th), z);
    const double bump = 1.0 + amp * std::sin(6 * d.x()) * std::sin(6 * d.y()) * std::sin(6 * d.z());
    p[i] = (d * bump).cast<float>();
    n[i] = d.cast<float>();  // close enough for a benchmark shape; the field needs only orientation
  }
  return cloudShape(p, n);
}

std::vector<Eigen::Vector3f> withDensePieces(std::vector<Eigen::Vector3f> body, int pieces,
                                             std::size_t per_piece, float radius, unsigned seed) {
  if (body.empty()) return body;
  std::mt19937 rng(seed);
  std::normal_distribution<float> gauss(0, 1);
  const std::size_t n = body.size();
  for (int k = 0; k < pieces; ++k) {
    const Eigen::Vector3f centre = body[rng() % n];
    for (std::size_t i = 0; i < per_piece; ++i) {
      Eigen::Vector3f d(gauss(rng), gauss(rng), gauss(rng));
      d /= std::max(d.norm(), 1e-6f);
      body.push_back(centre + radius * d);
    }
  }
  return body;
}

Shape sampleMesh(const Shape& mesh, std::size_t n, unsigned seed) {
  const Geometry g = extractGeometry(mesh);
  struct Tri {
    int a, b, c;
  };
  std::vector<Tri> tris;
  std::vector<double> cumulative;
  double total = 0;
  for (const auto& f : g.faces)
    for (std::size_t t = 1; t + 1 < f.vertices.size(); ++t) {
      const Tri tri{f.vertices[0], f.vertices[t], f.vertices[t + 1]};
      const Eigen::Vector3f a = (*g.points)[static_cast<std::size_t>(tri.a)].getVector3fMap(),
                            b = (*g.points)[static_cast<std::size_t>(tri.b)].getVector3fMap(),
                            c = (*g.points)[static_cast<std::size_t>(tri.c)].getVector3fMap();
      const double area = 0.5 * static_cast<double>((b - a).cross(c - a).norm());
      if (!(area > 0)) continue;
      tris.push_back(tri);
      total += area;
      cumulative.push_back(total);
    }
  std::vector<Eigen::Vector3f> p(n), nrm(n);
  if (tris.empty()) return cloudShape({}, {});
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (std::size_t i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(
        std::lower_bound(cumulative.begin(), cumulative.end(), u(rng) * total) - cumulative.begin());
    const Tri& t = tris[std::min(k, tris.size() - 1)];
    double r1 = u(rng), r2 = u(rng);
    if (r1 + r2 > 1) {
      r1 = 1 - r1;
      r2 = 1 - r2;
    }
    const Eigen::Vector3f a = (*g.points)[static_cast<std::size_t>(t.a)].getVector3fMap(),
                          b = (*g.points)[static_cast<std::size_t>(t.b)].getVector3fMap(),
                          c = (*g.points)[static_cast<std::size_t>(t.c)].getVector3fMap();
    p[i] = a + static_cast<float>(r1) * (b - a) + static_cast<float>(r2) * (c - a) + g.origin.cast<float>();
    nrm[i] = (b - a).cross(c - a).normalized();
  }
  return cloudShape(p, nrm);
}

Shape barMesh(float length, float width, float h) {
  // A box mesh: each face gridded, vertices shared along edges through a map.
  const Eigen::Vector3f lo(0, -width / 2, -width / 2), hi(length, width / 2, width / 2);
  int cells[3];
  for (int a = 0; a < 3; ++a) cells[a] = std::max(1, static_cast<int>(std::lround((hi[a] - lo[a]) / h)));
  std::map<std::tuple<int, int, int>, int> index;
  std::vector<Eigen::Vector3f> p;
  auto vertex = [&](int g0, int g1, int g2) {
    auto [it, added] = index.emplace(std::make_tuple(g0, g1, g2), static_cast<int>(p.size()));
    if (added) {
      const int g[3] = {g0, g1, g2};
      Eigen::Vector3f x;
      for (int a = 0; a < 3; ++a) x[a] = lo[a] + (hi[a] - lo[a]) * static_cast<float>(g[a]) / cells[a];
      p.push_back(x);
    }
    return it->second;
  };
  std::vector<pcl::Vertices> faces;
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      for (int i = 0; i < cells[u]; ++i)
        for (int j = 0; j < cells[v]; ++j) {
          int q[4];
          const int du[4] = {0, 1, 1, 0}, dv[4] = {0, 0, 1, 1};
          for (int c = 0; c < 4; ++c) {
            int g[3];
            g[axis] = side ? cells[axis] : 0;
            g[u] = i + du[c];
            g[v] = j + dv[c];
            q[c] = vertex(g[0], g[1], g[2]);
          }
          // (u, v, axis) is right-handed: counter-clockwise seen from +axis on the far side.
          auto tri = [&](int a, int b, int c) {
            pcl::Vertices t;
            t.vertices.resize(3);
            t.vertices[0] = a;
            t.vertices[1] = b;
            t.vertices[2] = c;
            faces.push_back(std::move(t));
          };
          if (side) {
            tri(q[0], q[1], q[2]);
            tri(q[0], q[2], q[3]);
          } else {
            tri(q[0], q[2], q[1]);
            tri(q[0], q[3], q[2]);
          }
        }
    }
  Shape s = cloudShape(p, {});
  s.polygons = std::move(faces);
  return s;
}

PointsAndNormals sampledFork(std::size_t n, unsigned seed, double noise, double outliers) {
  using V3 = Eigen::Vector3f;
  struct Box {
    V3 lo, hi;
  };
  const Box boxes[] = {{{0, -0.1f, -0.03f}, {0.45f, 0.1f, 0.03f}},
                       {{0.4f, 0.02f, -0.03f}, {1.2f, 0.08f, 0.03f}},
                       {{0.4f, -0.08f, -0.03f}, {1.2f, -0.02f, 0.03f}}};
  struct Face {
    int box, axis, side;
    double area;
  };
  std::vector<Face> faces;
  double total = 0;
  for (int b = 0; b < 3; ++b)
    for (int axis = 0; axis < 3; ++axis)
      for (int side = 0; side < 2; ++side) {
        const V3 e = boxes[b].hi - boxes[b].lo;
        const double area = static_cast<double>(e[(axis + 1) % 3] * e[(axis + 2) % 3]);
        faces.push_back({b, axis, side, area});
        total += area;
      }
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<float> gauss(0, 1);
  const float diag = V3(1.2f, 0.2f, 0.06f).norm();
  PointsAndNormals s;
  auto inside = [&](const V3& x, int except) {
    for (int b = 0; b < 3; ++b)
      if (b != except && (x.array() > boxes[b].lo.array() + 1e-6f).all() &&
          (x.array() < boxes[b].hi.array() - 1e-6f).all())
        return true;
    return false;
  };
  while (s.p.size() < n) {
    double t = u(rng) * total;
    std::size_t f = 0;
    while (f + 1 < faces.size() && t > faces[f].area) t -= faces[f++].area;
    const Box& b = boxes[faces[f].box];
    V3 x;
    for (int a = 0; a < 3; ++a) x[a] = b.lo[a] + static_cast<float>(u(rng)) * (b.hi[a] - b.lo[a]);
    const int axis = faces[f].axis;
    x[axis] = faces[f].side ? b.hi[axis] : b.lo[axis];
    if (inside(x, faces[f].box)) continue;
    V3 nrm = V3::Zero();
    nrm[axis] = faces[f].side ? 1.0f : -1.0f;
    if (rng() % 2) nrm = -nrm;
    if (noise > 0) x += V3(gauss(rng), gauss(rng), gauss(rng)) * static_cast<float>(noise) * diag;
    s.p.push_back(x);
    s.n.push_back(nrm);
  }
  const auto extra = static_cast<std::size_t>(outliers * static_cast<double>(n));
  for (std::size_t i = 0; i < extra; ++i) {
    const V3 x(static_cast<float>(u(rng) * 1.4 - 0.1), static_cast<float>(u(rng) * 0.4 - 0.2),
               static_cast<float>(u(rng) * 0.26 - 0.13));
    s.p.push_back(x);
    s.n.push_back(V3(gauss(rng), gauss(rng), gauss(rng)).normalized());
  }
  return s;
}

namespace {

/// Signed distance (negative inside) to a smooth union of capsules: the quadruped's body.
struct Capsule {
  Eigen::Vector3d a, b;
  double r;
};

double capsuleDistance(const Capsule& c, const Eigen::Vector3d& p) {
  const Eigen::Vector3d ab = c.b - c.a;
  const double t = std::clamp((p - c.a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (p - (c.a + t * ab)).norm() - c.r;
}

double quadrupedDistance(const Eigen::Vector3d& p) {
  static const Capsule parts[] = {{{-0.5, 0, 0}, {0.5, 0, 0}, 0.22},                // body
                                  {{0.38, -0.05, 0.14}, {0.4, -0.75, 0.14}, 0.07},  // front right leg
                                  {{0.38, -0.05, -0.14}, {0.4, -0.75, -0.14}, 0.07},
                                  {{-0.38, -0.05, 0.14}, {-0.4, -0.75, 0.14}, 0.07},  // hind right leg
                                  {{-0.38, -0.05, -0.14}, {-0.4, -0.75, -0.14}, 0.07},
                                  {{0.5, 0.05, 0}, {0.75, 0.4, 0}, 0.09},        // neck
                                  {{0.72, 0.42, 0}, {0.95, 0.35, 0}, 0.1},       // head
                                  {{-0.55, 0.05, 0}, {-0.85, -0.15, 0}, 0.04}};  // tail
  const double k = 0.05;                                                         // smooth-union radius
  double d = capsuleDistance(parts[0], p);
  for (std::size_t i = 1; i < sizeof(parts) / sizeof(parts[0]); ++i) {
    const double e = capsuleDistance(parts[i], p);
    const double h = std::max(k - std::abs(d - e), 0.0) / k;
    d = std::min(d, e) - h * h * k / 4;
  }
  return d;
}

}  // namespace

Shape quadruped(float h_in) {
  // Marching tetrahedra (each grid cube cut into the six tetrahedra around its main diagonal,
  // so that neighbouring cubes agree), one vertex per crossed grid edge, then three rounds of
  // neighbour averaging projected back onto the surface so that triangles are well shaped.
  const double h = h_in;
  const Eigen::Vector3d lo(-1.0 + 0.0137 * h, -0.9 + 0.0291 * h, -0.32 + 0.0173 * h);
  const Eigen::Vector3d hi(1.1, 0.65, 0.32);
  int n[3];
  for (int a = 0; a < 3; ++a) n[a] = static_cast<int>(std::ceil((hi[a] - lo[a]) / h)) + 1;
  const auto id = [&](int i, int j, int k) {
    return static_cast<std::int64_t>(i) +
           static_cast<std::int64_t>(n[0]) * (j + static_cast<std::int64_t>(n[1]) * k);
  };
  const auto at = [&](std::int64_t g) {
    const std::int64_t i = g % n[0], j = (g / n[0]) % n[1], k = g / (static_cast<std::int64_t>(n[0]) * n[1]);
    return Eigen::Vector3d(lo.x() + h * static_cast<double>(i), lo.y() + h * static_cast<double>(j),
                           lo.z() + h * static_cast<double>(k));
  };
  std::vector<double> f(static_cast<std::size_t>(n[0]) * n[1] * n[2]);
  for (int k = 0; k < n[2]; ++k)
    for (int j = 0; j < n[1]; ++j)
      for (int i = 0; i < n[0]; ++i)
        f[static_cast<std::size_t>(id(i, j, k))] = quadrupedDistance(at(id(i, j, k)));

  std::map<std::pair<std::int64_t, std::int64_t>, int> edge_vertex;
  std::vector<Eigen::Vector3d> p;
  const auto vertex = [&](std::int64_t a, std::int64_t b) {
    if (a > b) std::swap(a, b);
    auto [it, added] = edge_vertex.emplace(std::make_pair(a, b), static_cast<int>(p.size()));
    if (added) {
      const double fa = f[static_cast<std::size_t>(a)], fb = f[static_cast<std::size_t>(b)];
      const double t = std::clamp(fa / (fa - fb), 0.05, 0.95);
      p.push_back(at(a) + t * (at(b) - at(a)));
    }
    return it->second;
  };
  std::vector<std::array<int, 3>> tris;
  const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int k = 0; k + 1 < n[2]; ++k)
    for (int j = 0; j + 1 < n[1]; ++j)
      for (int i = 0; i + 1 < n[0]; ++i)
        for (const auto& perm : perms) {
          std::int64_t t[4];
          int c[3] = {i, j, k};
          t[0] = id(c[0], c[1], c[2]);
          for (int s = 0; s < 3; ++s) {
            ++c[perm[s]];
            t[s + 1] = id(c[0], c[1], c[2]);
          }
          std::vector<std::int64_t> in, out;
          for (const std::int64_t g : t) (f[static_cast<std::size_t>(g)] < 0 ? in : out).push_back(g);
          if (in.empty() || out.empty()) continue;
          Eigen::Vector3d outward = Eigen::Vector3d::Zero();
          for (const auto g : out) outward += at(g) / static_cast<double>(out.size());
          for (const auto g : in) outward -= at(g) / static_cast<double>(in.size());
          const auto emit = [&](int a, int b, int c2) {
            const Eigen::Vector3d nrm = (p[b] - p[a]).cross(p[c2] - p[a]);
            if (nrm.dot(outward) < 0) std::swap(b, c2);
            tris.push_back({a, b, c2});
          };
          if (in.size() == 1 || out.size() == 1) {
            const bool one_in = in.size() == 1;
            const std::int64_t apex = one_in ? in[0] : out[0];
            const auto& rest = one_in ? out : in;
            emit(vertex(apex, rest[0]), vertex(apex, rest[1]), vertex(apex, rest[2]));
          } else {
            const int a = vertex(in[0], out[0]), b = vertex(in[0], out[1]), c2 = vertex(in[1], out[1]),
                      d = vertex(in[1], out[0]);
            emit(a, b, c2);
            emit(a, c2, d);
          }
        }

  std::vector<std::vector<int>> nb(p.size());
  for (const auto& t : tris)
    for (int e = 0; e < 3; ++e) {
      nb[static_cast<std::size_t>(t[e])].push_back(t[(e + 1) % 3]);
      nb[static_cast<std::size_t>(t[e])].push_back(t[(e + 2) % 3]);
    }
  const auto project = [&](Eigen::Vector3d x) {
    for (int it = 0; it < 3; ++it) {
      const double d = quadrupedDistance(x), e = 1e-5;
      Eigen::Vector3d g;
      for (int a = 0; a < 3; ++a) {
        Eigen::Vector3d y = x;
        y[a] += e;
        g[a] = (quadrupedDistance(y) - d) / e;
      }
      x -= d * g / std::max(1e-12, g.squaredNorm());
    }
    return x;
  };
  for (int round = 0; round < 3; ++round) {
    std::vector<Eigen::Vector3d> q(p.size());
    for (std::size_t v = 0; v < p.size(); ++v) {
      Eigen::Vector3d mean = Eigen::Vector3d::Zero();
      for (const int w : nb[v]) mean += p[static_cast<std::size_t>(w)];
      q[v] = project(nb[v].empty() ? p[v] : Eigen::Vector3d(mean / static_cast<double>(nb[v].size())));
    }
    p.swap(q);
  }
  std::vector<Eigen::Vector3f> pf(p.size());
  for (std::size_t v = 0; v < p.size(); ++v) pf[v] = p[v].cast<float>();
  Shape s = cloudShape(pf, {});
  s.polygons.reserve(tris.size());
  for (const auto& t : tris) {
    pcl::Vertices v;
    v.vertices.assign(t.begin(), t.end());
    s.polygons.push_back(std::move(v));
  }
  return s;
}

namespace {

std::vector<int> legPart(const Shape& s, int leg, float y_lo, float y_hi) {
  const float sx = leg < 2 ? 1.0f : -1.0f, sz = leg % 2 == 0 ? 1.0f : -1.0f;
  std::vector<int> out;
  const auto& c = s.cloud;
  for (std::size_t i = 0; i < c.width * c.height; ++i) {
    float x[3];
    std::memcpy(x, &c.data[i * c.point_step], sizeof(x));  // cloudShape: x, y, z first
    if (x[1] >= y_lo && x[1] < y_hi && x[0] * sx > 0.2f && x[2] * sz > 0.02f)
      out.push_back(static_cast<int>(i));
  }
  return out;
}

}  // namespace

std::vector<int> quadrupedFoot(const Shape& quadruped, int leg) {
  return legPart(quadruped, leg, -1.0f, -0.68f);
}

std::vector<int> quadrupedShin(const Shape& quadruped, int leg) {
  return legPart(quadruped, leg, -0.6f, -0.3f);
}

std::vector<int> quadrupedLegTop(const Shape& quadruped, int leg) {
  return legPart(quadruped, leg, -0.34f, -0.3f);
}

}  // namespace shapes
}  // namespace hgd
