// hgdeform-scan-figures: the real-scan figures of docs/scans.md, measured on files so that any
// build of `hgdeform deform` (this one, or an older one) can be compared on the same inputs.
//
//   hgdeform-scan-figures gen DIR [ARMADILLO_MESH]
//       writes scan-shaped inputs, a scenario for each, and DIR/cases.txt (one line per case:
//       name input scenario drag-distance surface-points)
//   hgdeform-scan-figures measure REST DEFORMED DRAG [SURFACE]
//       prints "torn N split N stretch X" for a deformed output against its input, over its
//       first SURFACE points (all by default: the stray points a case adds come last):
//       - torn: a point whose displacement differs from the median displacement of its 10
//         nearest rest neighbours by more than 0.25x the drag distance;
//       - split: a point whose distance to one of its 10 nearest rest neighbours more than
//         triples and grows by more than 2% of the drag distance; stretch: the largest ratio of
//         deformed to rest distance over those pairs.
//
// scripts/scan_figures.sh runs both over one or two builds and prints the table.
#include <pcl/kdtree/kdtree_flann.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "hgdeform/io/geometry.h"
#include "hgdeform/io/io.h"
#include "support/shapes.h"

namespace {

using V3 = Eigen::Vector3f;

// Positions in file order (NaN points kept as NaN).
std::vector<V3> positions(const hgd::Shape& shape) {
  const hgd::Geometry g = hgd::extractGeometry(shape);
  std::vector<V3> out(shape.size(), V3::Constant(NAN));
  for (std::size_t i = 0; i < g.size(); ++i)
    out[static_cast<std::size_t>(g.raw_index[i])] = g.world(i).cast<float>();
  return out;
}

void writeScenario(const std::filesystem::path& file, const std::string& fixed,
                   const std::string& manipulated, const V3& from, const V3& to) {
  std::ofstream out(file);
  char move[256];
  std::snprintf(move, sizeof move, R"({"drag": {"from": [%.6g, %.6g, %.6g], "to": [%.6g, %.6g, %.6g]}})",
                static_cast<double>(from.x()), static_cast<double>(from.y()), static_cast<double>(from.z()),
                static_cast<double>(to.x()), static_cast<double>(to.y()), static_cast<double>(to.z()));
  out << R"({"format": "hgdeform-scenario/1", "clusters": 16, "fixed": [)" << fixed << R"(], "manipulated": )"
      << manipulated << R"(, "move": )" << move << "}\n";
}

std::string box(const V3& lo, const V3& hi) {
  char s[256];
  std::snprintf(s, sizeof s, R"({"box": {"min": [%.6g, %.6g, %.6g], "max": [%.6g, %.6g, %.6g]}})",
                static_cast<double>(lo.x()), static_cast<double>(lo.y()), static_cast<double>(lo.z()),
                static_cast<double>(hi.x()), static_cast<double>(hi.y()), static_cast<double>(hi.z()));
  return s;
}

int gen(const std::filesystem::path& dir, const std::string& armadillo) {
  std::filesystem::create_directories(dir);
  std::ofstream cases(dir / "cases.txt");
  // The fork: base fixed, one prong's tip dragged up and out.
  const V3 from(1.2f, 0.05f, 0), to(1.2f, 0.15f, 0.3f);
  writeScenario(dir / "fork.json", box({-1, -1, -1}, {0.4f, 1, 1}), box({1.15f, 0, -1}, {2, 0.1f, 1}), from,
                to);
  struct Fork {
    const char* name;
    std::size_t n;
    double noise, outliers;
  };
  for (const Fork& f :
       {Fork{"fork_50k", 50000, 0, 0}, Fork{"fork_200k", 200000, 0, 0}, Fork{"fork_1M", 1000000, 0, 0},
        Fork{"fork_4M", 4000000, 0, 0}, Fork{"fork_200k_noise", 200000, 0.003, 0},
        Fork{"fork_200k_outliers", 200000, 0, 0.01}, Fork{"fork_200k_noise_outliers", 200000, 0.003, 0.01}}) {
    const hgd::shapes::PointsAndNormals s = hgd::shapes::sampledFork(f.n, 11, f.noise, f.outliers);
    const std::string file = std::string(f.name) + ".ply";
    hgd::writeShape((dir / file).string(), hgd::shapes::cloudShape(s.p, s.n));
    cases << f.name << ' ' << file << " fork.json " << (to - from).norm() << ' ' << f.n << '\n';
  }
  if (armadillo.empty() || !std::filesystem::exists(armadillo)) return 0;
  // The Armadillo: the feet fixed (lowest 12% of its height), the top of the head dragged by
  // 15% of the diagonal, as the mesh, and resampled with face normals in random signs.
  const hgd::Shape mesh = hgd::readShape(armadillo);
  const std::vector<V3> mp = positions(mesh);
  V3 lo = V3::Constant(INFINITY), hi = -lo;
  for (const V3& x : mp) lo = lo.cwiseMin(x), hi = hi.cwiseMax(x);
  const float diag = (hi - lo).norm();
  V3 top = mp.front();
  for (const V3& x : mp)
    if (x.y() > top.y()) top = x;
  const V3 dto = top + V3(0.15f * diag, 0, 0);
  char sphere[160];
  std::snprintf(sphere, sizeof sphere, R"({"sphere": {"center": [%.6g, %.6g, %.6g], "radius": %.6g}})",
                static_cast<double>(top.x()), static_cast<double>(top.y()), static_cast<double>(top.z()),
                static_cast<double>(0.06f * diag));
  writeScenario(
      dir / "armadillo.json",
      box(lo - V3::Constant(diag), V3(hi.x() + diag, lo.y() + 0.12f * (hi.y() - lo.y()), hi.z() + diag)),
      sphere, top, dto);
  const double drag = (dto - top).norm();
  std::filesystem::copy_file(armadillo, dir / "armadillo_mesh.ply",
                             std::filesystem::copy_options::overwrite_existing);
  cases << "armadillo_mesh armadillo_mesh.ply armadillo.json " << drag << ' ' << mp.size() << '\n';
  std::mt19937 rng(5);
  for (const auto& [name, n] : {std::pair<const char*, std::size_t>{"armadillo_200k_random_signs", 200000},
                                {"armadillo_1M_random_signs", 1000000}}) {
    const hgd::Shape sampled = hgd::shapes::sampleMesh(mesh, n, 7);
    const hgd::Geometry g = hgd::extractGeometry(sampled);
    std::vector<V3> p = positions(sampled), nrm(p.size());
    for (std::size_t i = 0; i < g.size(); ++i) {
      const auto r = static_cast<std::size_t>(g.raw_index[i]);
      nrm[r] = (*g.file_normals)[i].getNormalVector3fMap() * (rng() % 2 ? 1.0f : -1.0f);
    }
    const std::string file = std::string(name) + ".ply";
    hgd::writeShape((dir / file).string(), hgd::shapes::cloudShape(p, nrm));
    cases << name << ' ' << file << " armadillo.json " << drag << ' ' << n << '\n';
  }
  return 0;
}

int measure(const std::string& rest_file, const std::string& out_file, double drag, std::size_t surface) {
  const std::vector<V3> rest = positions(hgd::readShape(rest_file)),
                        out = positions(hgd::readShape(out_file));
  if (rest.size() != out.size()) throw std::runtime_error("the two files differ in point count");
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  std::vector<int> at;
  for (std::size_t i = 0; i < std::min(rest.size(), surface); ++i)
    if (rest[i].allFinite()) {
      cloud->push_back(pcl::PointXYZ(rest[i].x(), rest[i].y(), rest[i].z()));
      at.push_back(static_cast<int>(i));
    }
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
  tree.setInputCloud(cloud);
  std::size_t torn = 0, split = 0;
  double stretch = 1;
  pcl::Indices nb;
  std::vector<float> d2;
  for (std::size_t c = 0; c < cloud->size(); ++c) {
    const auto i = static_cast<std::size_t>(at[c]);
    tree.nearestKSearch((*cloud)[c], 11, nb, d2);
    V3 med;
    for (int a = 0; a < 3; ++a) {
      std::vector<float> v;
      for (const auto j : nb)
        if (static_cast<std::size_t>(j) != c) {
          const auto q = static_cast<std::size_t>(at[static_cast<std::size_t>(j)]);
          v.push_back(out[q][a] - rest[q][a]);
        }
      std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
      med[a] = v[v.size() / 2];
    }
    if ((out[i] - rest[i] - med).norm() > 0.25 * drag) ++torn;
    bool is_split = false;
    for (const auto j : nb) {
      if (static_cast<std::size_t>(j) == c) continue;
      const auto q = static_cast<std::size_t>(at[static_cast<std::size_t>(j)]);
      const double r = (rest[q] - rest[i]).norm(), d = (out[q] - out[i]).norm();
      if (r > 0) stretch = std::max(stretch, d / r);
      if (d > 3 * r && d - r > 0.02 * drag) is_split = true;
    }
    split += is_split;
  }
  std::printf("torn %zu split %zu stretch %.2f\n", torn, split, stretch);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const std::string mode = argc > 1 ? argv[1] : "";
    if (mode == "gen" && (argc == 3 || argc == 4)) return gen(argv[2], argc == 4 ? argv[3] : "");
    if (mode == "measure" && (argc == 5 || argc == 6))
      return measure(argv[2], argv[3], std::stod(argv[4]), argc == 6 ? std::stoul(argv[5]) : SIZE_MAX);
    std::fprintf(stderr,
                 "usage: hgdeform-scan-figures gen DIR [ARMADILLO_MESH]\n"
                 "       hgdeform-scan-figures measure REST DEFORMED DRAG [SURFACE]\n");
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "hgdeform-scan-figures: %s\n", e.what());
    return 1;
  }
}
