#include "hgdeform/io/geometry.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <map>
#include <type_traits>

#include "hgdeform/io/fields.h"
#include "hgdeform/io/io.h"
#include "io/frame.h"
#include "util/parallel.h"
#include "util/phases.h"
#include "util/radix_sort.h"

namespace hgd {

using namespace frame;

namespace {

/// The forBlocks() blocks of `v` (one a count) each kept their first counts[b] items in place at
/// their block's start; moves them together at the front of `v`, in block order, and resizes it.
template <typename T>
void joinBlocks(std::vector<T>& v, const std::vector<std::size_t>& counts) {
  const auto n = static_cast<long long>(v.size());
  const int blocks = static_cast<int>(counts.size());
  std::size_t total = 0;
  for (std::size_t b = 0; b < counts.size(); ++b) {
    const auto from = static_cast<std::size_t>(blockStart(n, blocks, static_cast<int>(b)));
    if (from != total)
      std::copy(v.begin() + static_cast<std::ptrdiff_t>(from),
                v.begin() + static_cast<std::ptrdiff_t>(from + counts[b]),
                v.begin() + static_cast<std::ptrdiff_t>(total));
    total += counts[b];
  }
  v.resize(total);
}

}  // namespace

Geometry extractGeometry(const Shape& shape) {
  const pcl::PCLPointCloud2& c = shape.cloud;
  const XyzFields f = findXyzFields(c);
  if (!f.hasXyz()) throw IoError(shape.path + ": no x/y/z fields");
  const std::size_t n = shape.size();
  if (n == 0) throw IoError(shape.path + ": no points");

  PhaseClock clock;
  Geometry g;
  g.finite_index.assign(n, -1);  // set below for every point kept
  // The finite points, in file order: each block of points keeps its own at its start, then the
  // blocks join up.
  std::vector<Eigen::Vector3d> world(n);
  g.raw_index.resize(n);
  const int blocks = blockCount(static_cast<long long>(n));
  std::vector<std::size_t> kept_in(static_cast<std::size_t>(blocks));
  // x, y and z as the file stores them: float and double read inline (the common case, a tenth
  // of the generic per-value decoder's time), any other type through it.
  const auto& fx = c.fields[static_cast<std::size_t>(f.x)];
  const auto& fy = c.fields[static_cast<std::size_t>(f.y)];
  const auto& fz = c.fields[static_cast<std::size_t>(f.z)];
  const std::uint8_t type = fx.datatype == fy.datatype && fx.datatype == fz.datatype ? fx.datatype : 0;
  const auto readXyz = [&](auto tag, int begin, int end, std::size_t& k) {
    using T = decltype(tag);
    const std::uint8_t* data = c.data.data();
    for (auto i = static_cast<std::size_t>(begin); i < static_cast<std::size_t>(end); ++i) {
      const std::uint8_t* r = data + i * c.point_step;
      Eigen::Vector3d p;
      if constexpr (std::is_same_v<T, void*>) {
        p = Eigen::Vector3d(readValue(c, i, fx), readValue(c, i, fy), readValue(c, i, fz));
      } else {
        T v[3];
        std::memcpy(&v[0], r + fx.offset, sizeof(T));
        std::memcpy(&v[1], r + fy.offset, sizeof(T));
        std::memcpy(&v[2], r + fz.offset, sizeof(T));
        p = Eigen::Vector3d(static_cast<double>(v[0]), static_cast<double>(v[1]), static_cast<double>(v[2]));
      }
      if (!p.allFinite()) continue;
      g.raw_index[k] = static_cast<int>(i);
      world[k++] = p;
    }
  };
  forBlocks(static_cast<long long>(n), blocks, [&](int begin, int end, int b) {
    auto k = static_cast<std::size_t>(begin);
    if (type == pcl::PCLPointField::FLOAT32)
      readXyz(float{}, begin, end, k);
    else if (type == pcl::PCLPointField::FLOAT64)
      readXyz(double{}, begin, end, k);
    else
      readXyz(static_cast<void*>(nullptr), begin, end, k);
    kept_in[static_cast<std::size_t>(b)] = k - static_cast<std::size_t>(begin);
  });
  joinBlocks(world, kept_in);
  joinBlocks(g.raw_index, kept_in);
  if (world.empty())
    throw IoError(shape.path + ": no finite points (all " + std::to_string(n) + " are NaN/inf)");
  clock.lap("geometry.read_xyz");

  // The local frame: its origin is the centre of the shape's body, not of the bounding box of
  // every point, so that one far point (a bad return at 1e5 or 1e10) neither moves the frame nor
  // spends the float's bits on empty space. Points absurdly far from the shape (over a million times its
  // size, or beyond 1e12 units: a corrupt block decoded to 1e22) cannot be deformed with it in any precision
  // that means something (and their squared distances would overflow): they are set apart like NaN points,
  // written back untouched, with a warning.
  // A scanner's "no return": points at exactly (0, 0, 0) while the shape lies far from the origin
  // (over a thousand times its size). However many they are (60% of a georeferenced patch),
  // they are no part of it, yet they would set the frame's origin and size (the median and the
  // spread) and cost the deformation its precision. Set apart like far points: untouched, said.
  std::size_t no_return = 0;
  const std::size_t frame_step = frameSampleStep(n);
  {
    const auto isZero = [](const Eigen::Vector3d& w) { return w.x() == 0 && w.y() == 0 && w.z() == 0; };
    const std::size_t zeros = static_cast<std::size_t>(std::count_if(world.begin(), world.end(), isZero));
    if (zeros > 0 && zeros < world.size()) {
      std::vector<Eigen::Vector3d> rest;
      std::vector<int> rest_index;
      rest.reserve(world.size() - zeros);
      rest_index.reserve(world.size() - zeros);
      for (std::size_t j = 0; j < world.size(); ++j)
        if (!isZero(world[j])) {
          rest.push_back(world[j]);
          rest_index.push_back(g.raw_index[j]);
        }
      const RobustFrame nz = robustFrame(rest, rest_index, frame_step);
      const double distance = nz.centre.cwiseAbs().maxCoeff();
      if (distance > 1000 * nz.extent) {
        std::size_t k = 0;
        for (std::size_t j = 0; j < world.size(); ++j) {
          if (isZero(world[j])) continue;  // finite_index stays -1: written back as it is
          g.raw_index[k] = g.raw_index[j];
          world[k++] = world[j];
        }
        world.resize(k);
        g.raw_index.resize(k);
        no_return = zeros;
        g.warnings.push_back(noReturnWarning(shape.path, zeros, distance, nz.extent));
      }
    }
  }
  const RobustFrame frame = robustFrame(world, g.raw_index, frame_step);
  refuseExtent(shape.path, frame);
  const FrameLimits limits = frameLimits(frame);
  const double far = limits.far;
  // Strays: points more than 16 times the shape's size from its centre, each alone there (no
  // other such point within one shape size: a part that reaches out, a rod, a second object,
  // has its points together), are no part of the shape when they are few (at most 1% of the
  // points). Deformed, such a point turns with its nearest cluster about a pivot many sizes
  // away: one at 100 sizes was flung 66 units by a unit drag, one at 1e5 sizes 6.5e5, and it
  // pulled the clustering (the other points shifted by up to 0.8% of the move). Set apart like
  // the absurdly far: left where they are, untouched, with the same warning.
  const double stray = limits.stray;
  std::vector<std::size_t> strays;  // positions in `world`, ascending
  if (frame.extent > 0) {
    const std::size_t m = world.size();
    const int mb = blockCount(static_cast<long long>(m));
    std::vector<std::vector<std::size_t>> beyond_in(static_cast<std::size_t>(mb));
    forBlocks(static_cast<long long>(m), mb, [&](int begin, int end, int b) {
      for (auto j = static_cast<std::size_t>(begin); j < static_cast<std::size_t>(end); ++j) {
        const double d = (world[j] - frame.centre).cwiseAbs().maxCoeff();
        if (d > stray && d <= far) beyond_in[static_cast<std::size_t>(b)].push_back(j);
      }
    });
    std::vector<std::size_t> beyond;
    for (const auto& v : beyond_in) beyond.insert(beyond.end(), v.begin(), v.end());
    if (!beyond.empty() && static_cast<double>(beyond.size()) <= kStrayShare * static_cast<double>(m)) {
      // Alone: no other candidate within one size (the body is 12 sizes away).
      std::vector<Eigen::Vector3d> at;
      at.reserve(beyond.size());
      for (const std::size_t j : beyond) at.push_back(world[j]);
      for (const std::size_t k : aloneAmong(at, frame.centre, frame.extent)) strays.push_back(beyond[k]);
    }
  }
  // The frame's origin: the centre of the bounding box of the shape's body, the points within
  // four times its size of the median (every point of a shape without strays), rounded.
  const double body = limits.body;
  Eigen::Vector3d body_lo = Eigen::Vector3d::Constant(INFINITY), body_hi = -body_lo;
  {
    // In blocks as above: each keeps its near points at its start, counts its far ones and
    // bounds its body (a box, the same whatever the blocks).
    const std::size_t m = world.size();
    const int mb = blockCount(static_cast<long long>(m));
    std::vector<std::size_t> kept(static_cast<std::size_t>(mb)), far_in(static_cast<std::size_t>(mb));
    std::vector<double> farthest_in(static_cast<std::size_t>(mb), 0.0);
    std::vector<Eigen::Vector3d> lo_in(static_cast<std::size_t>(mb), body_lo),
        hi_in(static_cast<std::size_t>(mb), body_hi);
    forBlocks(static_cast<long long>(m), mb, [&](int begin, int end, int b) {
      const auto bb = static_cast<std::size_t>(b);
      auto k = static_cast<std::size_t>(begin);
      std::size_t far_here = 0;
      double farthest_here = 0;
      Eigen::Vector3d lo = lo_in[bb], hi = hi_in[bb];  // (locals: the blocks share cache lines)
      for (auto j = static_cast<std::size_t>(begin); j < static_cast<std::size_t>(end); ++j) {
        const Eigen::Vector3d w = world[j];
        const double d = (w - frame.centre).cwiseAbs().maxCoeff();
        if (d > far || (d > stray && std::binary_search(strays.begin(), strays.end(), j))) {
          ++far_here;
          farthest_here = std::max(farthest_here, d);
          g.finite_index[static_cast<std::size_t>(g.raw_index[j])] = -1;
          continue;
        }
        g.raw_index[k] = g.raw_index[j];
        world[k++] = w;
        if (d <= body) {
          lo = lo.cwiseMin(w);
          hi = hi.cwiseMax(w);
        }
      }
      kept[bb] = k - static_cast<std::size_t>(begin);
      far_in[bb] = far_here;
      farthest_in[bb] = farthest_here;
      lo_in[bb] = lo;
      hi_in[bb] = hi;
    });
    joinBlocks(world, kept);
    joinBlocks(g.raw_index, kept);
    std::size_t far_count = 0;
    double farthest = 0;
    for (std::size_t b = 0; b < static_cast<std::size_t>(mb); ++b) {
      far_count += far_in[b];
      farthest = std::max(farthest, farthest_in[b]);
      body_lo = body_lo.cwiseMin(lo_in[b]);
      body_hi = body_hi.cwiseMax(hi_in[b]);
    }
    g.far_points = far_count + no_return;
    if (far_count > 0) {
      g.warnings.push_back(
          farWarning(shape.path, far_count, strays.empty() ? far : stray, frame.extent, farthest));
    }
  }
  if (world.empty()) throw IoError(shape.path + ": no finite points");
  clock.lap("geometry.frame");

  // Points in space-filling-curve order (Morton, 10 bits per axis of the bounding cube; file
  // order among points of one cell): neighbours then lie near each other in memory, so kNN,
  // normals, the graph, the field solve and clustering stay in cache whatever order the file
  // has (a resampled or merged scan comes shuffled: 1.7x faster at 1M points). raw_index and
  // finite_index map to and from the file's order.
  std::vector<std::uint32_t> perm(world.size());  // geometry point -> position in `world`
  {
    const std::size_t m = world.size();
    // Over the shape's body (strays beyond it take the edge cells): a far stray would leave the
    // body a single cell.
    const double extent = (body_hi - body_lo).maxCoeff();
    const double scale = extent > 0 ? 1023.0 / extent : 0.0;
    std::vector<std::uint32_t> key(m);
    const long long mm = static_cast<long long>(m);
#pragma omp parallel for schedule(static) if (mm > kParallelMin)
    for (long long kk = 0; kk < mm; ++kk) {
      const auto k = static_cast<std::size_t>(kk);
      key[k] = mortonKey(world[k], body_lo, scale);
      perm[k] = static_cast<std::uint32_t>(k);
    }
    clock.lap("geometry.morton_keys");
    radixSort(key, perm, (std::uint32_t{1} << 30) - 1, 10);  // stable: file order within a cell
    clock.lap("geometry.morton_sort");
    std::vector<int> raw(m);
#pragma omp parallel for schedule(static) if (mm > kParallelMin)
    for (long long kk = 0; kk < mm; ++kk) {
      const auto k = static_cast<std::size_t>(kk);
      raw[k] = g.raw_index[perm[k]];
      g.finite_index[static_cast<std::size_t>(raw[k])] = static_cast<int>(k);
    }
    g.raw_index.swap(raw);
  }

  // Rounded so that the local coordinates of a regular sampling stay exact offsets (equal
  // distances stay equal, whatever the shape's position).
  g.origin = (0.5 * (body_lo + body_hi)).array().round().matrix();
  g.body = Eigen::AlignedBox3f((body_lo - g.origin).cast<float>(), (body_hi - g.origin).cast<float>());
  g.points->resize(world.size());
  const long long wn = static_cast<long long>(world.size());
#pragma omp parallel for schedule(static) if (wn > kParallelMin)
  for (long long ii = 0; ii < wn; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    (*g.points)[i].getVector3fMap() = (world[perm[i]] - g.origin).cast<float>();
  }
  g.points->width = static_cast<std::uint32_t>(world.size());
  g.points->height = 1;
  g.points->is_dense = true;
  clock.lap("geometry.points");

  if (f.hasNormals()) {
    bool usable = true;
    g.file_normals->resize(world.size());
    for (std::size_t i = 0; i < n && usable; ++i) {  // in file order: sequential reads
      const int fk = g.finite_index[i];
      if (fk < 0) continue;
      const auto k = static_cast<std::size_t>(fk);
      Eigen::Vector3f nv(static_cast<float>(readValue(c, i, c.fields[f.nx])),
                         static_cast<float>(readValue(c, i, c.fields[f.ny])),
                         static_cast<float>(readValue(c, i, c.fields[f.nz])));
      const float len = nv.norm();
      if (!std::isfinite(len) || len < 1e-12f) {
        usable = false;  // a file with missing normals is treated as one without normals
        break;
      }
      (*g.file_normals)[k].getNormalVector3fMap() = nv / len;
    }
    if (!usable) g.file_normals->clear();
  }

  g.faces.reserve(shape.polygons.size());
  for (const auto& poly : shape.polygons) {
    pcl::Vertices v;
    bool ok = poly.vertices.size() >= 3;
    for (auto idx : poly.vertices) {
      const int fi =
          idx >= 0 && static_cast<std::size_t>(idx) < n ? g.finite_index[static_cast<std::size_t>(idx)] : -1;
      if (fi < 0) ok = false;
      v.vertices.push_back(static_cast<std::uint32_t>(fi));
    }
    if (ok) g.faces.push_back(std::move(v));
  }
  clock.lap("geometry.normals_faces");
  return g;
}

void storePositions(Shape& shape, const Geometry& geometry, const std::vector<Eigen::Vector3f>& positions,
                    const std::vector<Eigen::Vector3f>* normals) {
  pcl::PCLPointCloud2& c = shape.cloud;
  const XyzFields f = findXyzFields(c);
  const bool write_normals = normals != nullptr && f.hasNormals();
  const long long m = static_cast<long long>(positions.size());
#pragma omp parallel for schedule(static) if (m > kParallelMin)
  for (long long kk = 0; kk < m; ++kk) {  // each point's own bytes
    const auto k = static_cast<std::size_t>(kk);
    const std::size_t i = static_cast<std::size_t>(geometry.raw_index[k]);
    const Eigen::Vector3d p = positions[k].cast<double>() + geometry.origin;
    writeValue(c, i, c.fields[f.x], p.x());
    writeValue(c, i, c.fields[f.y], p.y());
    writeValue(c, i, c.fields[f.z], p.z());
    if (write_normals) {
      const Eigen::Vector3f& nv = (*normals)[k];
      writeValue(c, i, c.fields[f.nx], nv.x());
      writeValue(c, i, c.fields[f.ny], nv.y());
      writeValue(c, i, c.fields[f.nz], nv.z());
    }
  }
}

Eigen::AlignedBox3f boundingBox(const pcl::PointCloud<pcl::PointXYZ>& points) {
  // One box a block of points, then their union (the same box whatever the blocks).
  const auto n = static_cast<long long>(points.size());
  const int blocks = blockCount(n);
  std::vector<Eigen::AlignedBox3f> part(static_cast<std::size_t>(blocks));  // empty
  forBlocks(n, blocks, [&](int begin, int end, int b) {
    Eigen::AlignedBox3f box;
    for (int i = begin; i < end; ++i) box.extend(points[static_cast<std::size_t>(i)].getVector3fMap());
    part[static_cast<std::size_t>(b)] = box;
  });
  Eigen::AlignedBox3f box;  // empty
  for (const auto& p : part) box.extend(p);
  return box;
}

Eigen::AlignedBox3f bodyBox(const Geometry& geometry) {
  return geometry.body.isEmpty() ? boundingBox(*geometry.points) : geometry.body;
}

double boundingBoxDiagonal(const Geometry& geometry) {
  if (geometry.points->empty()) return 0;
  const Eigen::AlignedBox3f box = bodyBox(geometry);
  return static_cast<double>((box.max() - box.min()).norm());
}

}  // namespace hgd
