// Test fixtures of the streamed runs (test_stream, test_stream_cli): a temporary folder, a scan
// shaped like users' files, a file's bytes.
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <unistd.h>

#include <Eigen/Core>
#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "hgdeform/io/fields.h"
#include "hgdeform/io/geometry.h"
#include "hgdeform/io/shape.h"
#include "hgdeform/multires/streamed.h"
#include "support/shapes.h"

namespace hgd_test {

struct TempDir {
  std::filesystem::path dir;
  TempDir() {
    dir = std::filesystem::temp_directory_path() /
          ("hgd_stream_" + std::to_string(::getpid()) + "_" + std::to_string(std::random_device{}()));
    std::filesystem::create_directories(dir);
  }
  ~TempDir() { std::filesystem::remove_all(dir); }
  std::string operator/(const std::string& name) const { return (dir / name).string(); }
};

/// A scan as users' files hold it: a bumpy sphere's points with noise, 1% strays about it,
/// dense pieces, repeated points (merged scans), NaN records, a few points far away (a bad return
/// at 10^4 sizes) and, when `zeros`, 'no return' records at (0, 0, 0) while the shape lies at
/// `offset`; normals of random signs; shuffled. x, y, z in double (offset: georeferenced), an
/// intensity, normals in float.
inline hgd::Shape userScan(std::size_t n, unsigned seed, const Eigen::Vector3d& offset, bool zeros) {
  std::mt19937 rng(seed);
  std::vector<Eigen::Vector3f> p, none;
  {
    const hgd::Geometry s = hgd::extractGeometry(hgd::shapes::bumpySphere(n));
    for (std::size_t i = 0; i < s.size(); ++i) p.push_back(s.world(i).cast<float>());
  }
  std::uniform_real_distribution<float> u(-1.4f, 1.4f), noise(-0.004f, 0.004f);
  for (std::size_t k = 0; k < p.size() / 100; ++k) p.emplace_back(u(rng), u(rng), u(rng));
  p = hgd::shapes::withDensePieces(std::move(p), 12, 800, 0.01f, 5);
  for (auto& x : p) x += Eigen::Vector3f(noise(rng), noise(rng), noise(rng));
  std::uniform_int_distribution<std::size_t> any(0, p.size() - 1);
  for (std::size_t k = 0; k < p.size() / 20; ++k) p.push_back(p[any(rng)]);
  std::vector<Eigen::Vector3d> w;
  for (const auto& x : p) w.push_back(x.cast<double>() + offset);
  w.push_back(offset + Eigen::Vector3d(3e4, 0, 0));
  w.push_back(offset + Eigen::Vector3d(0, -5e4, 2e4));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (int k = 0; k < 500; ++k) w.emplace_back(nan, nan, nan);
  if (zeros)
    for (int k = 0; k < 700; ++k) w.emplace_back(0, 0, 0);
  std::shuffle(w.begin(), w.end(), rng);

  hgd::Shape shape;
  pcl::PCLPointCloud2& c = shape.cloud;
  const auto field = [&](const char* name, std::uint32_t offset_bytes, std::uint8_t type) {
    pcl::PCLPointField f;
    f.name = name;
    f.offset = offset_bytes;
    f.datatype = type;
    f.count = 1;
    c.fields.push_back(f);
  };
  field("x", 0, pcl::PCLPointField::FLOAT64);
  field("y", 8, pcl::PCLPointField::FLOAT64);
  field("z", 16, pcl::PCLPointField::FLOAT64);
  field("nx", 24, pcl::PCLPointField::FLOAT32);
  field("ny", 28, pcl::PCLPointField::FLOAT32);
  field("nz", 32, pcl::PCLPointField::FLOAT32);
  field("intensity", 36, pcl::PCLPointField::UINT16);
  c.point_step = 38;
  c.width = static_cast<std::uint32_t>(w.size());
  c.height = 1;
  c.row_step = c.point_step * c.width;
  c.data.resize(c.row_step);
  std::uniform_real_distribution<float> dir(-1, 1);
  std::uniform_int_distribution<int> level(0, 65535);
  for (std::size_t i = 0; i < w.size(); ++i) {
    std::uint8_t* r = c.data.data() + i * c.point_step;
    std::memcpy(r, w[i].data(), 24);
    Eigen::Vector3f nv(dir(rng), dir(rng), dir(rng));
    nv = nv.normalized() * (rng() % 2 ? 1.0f : -1.0f);
    std::memcpy(r + 24, nv.data(), 12);
    const auto v = static_cast<std::uint16_t>(level(rng));
    std::memcpy(r + 36, &v, 2);
  }
  return shape;
}

/// The handles of a file's records: below z -0.75 fixed, beyond x 0.8 the manipulated handle
/// (of the shape's own coordinates: less its offset), in record indices.
inline hgd::RecordHandles recordHandles(const hgd::Shape& shape, const Eigen::Vector3d& offset) {
  hgd::RecordHandles h;
  h.fixed.resize(1);
  const hgd::XyzFields f = hgd::findXyzFields(shape.cloud);
  for (std::size_t i = 0; i < shape.size(); ++i) {
    const Eigen::Vector3d x =
        Eigen::Vector3d(hgd::readValue(shape.cloud, i, shape.cloud.fields[static_cast<std::size_t>(f.x)]),
                        hgd::readValue(shape.cloud, i, shape.cloud.fields[static_cast<std::size_t>(f.y)]),
                        hgd::readValue(shape.cloud, i, shape.cloud.fields[static_cast<std::size_t>(f.z)])) -
        offset;
    if (!x.allFinite() || x.norm() > 10) continue;
    if (x.z() < -0.75) h.fixed[0].push_back(i);
    if (x.x() > 0.8) h.manipulated.push_back(i);
  }
  return h;
}

inline std::string fileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

/// Two outputs of one input (the same size) compared byte for byte: how many bytes differ
/// between them, and how many of the first differ from the input (that it did deform).
struct ByteDiff {
  std::size_t differ = 0, moved = 0;
};
inline ByteDiff diffBytes(const std::string& a, const std::string& b, const std::string& input) {
  ByteDiff d;
  for (std::size_t k = 0; k < a.size() && k < b.size(); ++k) {
    d.differ += a[k] != b[k];
    d.moved += k < input.size() && a[k] != input[k];
  }
  return d;
}

/// A scan's x, y, z and normals as PCL's PointNormal cloud (as a PCL program would save it;
/// not dense: its NaN points), with `curvature` set to each point's index modulo `curvature_mod`
/// (0: zero).
inline pcl::PointCloud<pcl::PointNormal> asPointNormals(const hgd::Shape& scan, int curvature_mod = 0) {
  pcl::PointCloud<pcl::PointNormal> pn;
  const hgd::XyzFields f = hgd::findXyzFields(scan.cloud);
  const auto value = [&](std::size_t i, int field) {
    return static_cast<float>(
        hgd::readValue(scan.cloud, i, scan.cloud.fields[static_cast<std::size_t>(field)]));
  };
  for (std::size_t i = 0; i < scan.size(); ++i) {
    pcl::PointNormal q;
    q.x = value(i, f.x);
    q.y = value(i, f.y);
    q.z = value(i, f.z);
    q.normal_x = value(i, f.nx);
    q.normal_y = value(i, f.ny);
    q.normal_z = value(i, f.nz);
    q.curvature = curvature_mod > 0
                      ? static_cast<float>(static_cast<int>(i % static_cast<std::size_t>(curvature_mod)))
                      : 0.0f;
    pn.push_back(q);
  }
  pn.is_dense = false;
  return pn;
}

}  // namespace hgd_test
