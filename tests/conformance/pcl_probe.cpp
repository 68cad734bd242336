// pcl_probe: PCL as a third-party writer and reader for the conformance suite (tests/conformance).
//
//   pcl_probe write TYPE ENCODING OUT   a deterministic cloud of TYPE written by PCL's own writer
//   pcl_probe read FILE                 FILE loaded by PCL into a PCLPointCloud2, printed as JSON
//
// TYPE: xyz (PointXYZ), xyzi (PointXYZI), xyzrgb (PointXYZRGB, colour packed the way PCL's
// tutorials do it, so alpha 0), xyzrgbnormal (PointXYZRGBNormal), pointnormal (PointNormal),
// organized (PointXYZRGBNormal, 80 x 25 grid with NaN points).
// ENCODING: ascii, binary, binary_compressed (pcl::io::savePCDFile*: OUT ends in .pcd) or ascii,
// binary (pcl::PLYWriter: OUT ends in .ply).
//
// The shape is a tube along x from 0 to 10 (radius 1; points in random order, radial noise), so
// that a test can fix one end (x < 1) and drag the other (x > 9).
//
// `read` loads .pcd with pcl::io::loadPCDFile, .ply with pcl::io::loadPLYFile and .obj with
// pcl::io::loadOBJFile (all into pcl::PCLPointCloud2) and prints
//   {"width", "height", "is_dense", "point_step", "row_step",
//    "fields": [{"name", "datatype", "count", "offset"}], "data": "<hex of every byte>"}
// so that the test sees every value exactly, NaN payloads included. Exit status 1 when PCL
// cannot load the file (its error on stderr).
#include <pcl/PCLPointCloud2.h>
#include <pcl/console/print.h>
#include <pcl/io/obj_io.h>
#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <limits>
#include <string>
#include <vector>

namespace {

// A small deterministic generator (splitmix64), the same on every platform and library.
struct Rng {
  std::uint64_t s;
  explicit Rng(std::uint64_t seed) : s(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (s += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  double uniform(double lo, double hi) { return lo + (hi - lo) * ((next() >> 11) * 0x1.0p-53); }
};

constexpr double kPi = 3.14159265358979323846;
constexpr double kLength = 10.0;
constexpr int kPoints = 2000;

struct Sample {
  float x, y, z, nx, ny, nz, curvature, intensity;
  std::uint8_t r, g, b;
};

// A point of the tube at (t along x, angle a), radius 1 + noise; its outward normal.
Sample sample(double t, double a, double noise) {
  Sample s{};
  const double radius = 1.0 + noise;
  s.x = static_cast<float>(t);
  s.y = static_cast<float>(radius * std::cos(a));
  s.z = static_cast<float>(radius * std::sin(a));
  s.nx = 0.0f;
  s.ny = static_cast<float>(std::cos(a));
  s.nz = static_cast<float>(std::sin(a));
  s.curvature = static_cast<float>(0.01 + 0.02 * std::fabs(std::sin(3 * a)));
  s.intensity = static_cast<float>(100.0 + 900.0 * t / kLength + 7.25 * std::sin(5 * a));
  s.r = static_cast<std::uint8_t>(std::lround(255.0 * t / kLength));
  s.g = static_cast<std::uint8_t>(std::lround(127.5 + 127.5 * std::cos(a)));
  s.b = static_cast<std::uint8_t>((static_cast<int>(t * 37) + 11) % 256);
  return s;
}

std::vector<Sample> unorganized() {
  Rng rng(20240611);
  std::vector<Sample> out;
  out.reserve(kPoints);
  for (int i = 0; i < kPoints; ++i) {
    const double t = rng.uniform(0.0, kLength);
    const double a = rng.uniform(0.0, 2 * kPi);
    out.push_back(sample(t, a, rng.uniform(-0.01, 0.01)));
  }
  return out;  // random order already: t and a are drawn per point
}

constexpr int kGridW = 80, kGridH = 25;

// An organized scan of the tube from above (+z): rows are angles over the upper half, columns x;
// cells that are "missed" by the scanner are NaN (every 7th by a hash, and the first column).
std::vector<Sample> organizedSamples(std::vector<bool>& valid) {
  Rng rng(77);
  std::vector<Sample> out;
  valid.assign(kGridW * kGridH, true);
  for (int row = 0; row < kGridH; ++row) {
    for (int col = 0; col < kGridW; ++col) {
      const double t = kLength * (col + 0.5) / kGridW;
      const double a = kPi * (row + 0.5) / kGridH;
      out.push_back(sample(t, a, rng.uniform(-0.01, 0.01)));
      const std::uint64_t h = rng.next();
      if (col == 0 || h % 7 == 0) valid[row * kGridW + col] = false;
    }
  }
  return out;
}

template <typename P>
void setXYZ(P& p, const Sample& s) {
  p.x = s.x;
  p.y = s.y;
  p.z = s.z;
}
template <typename P>
void setNormal(P& p, const Sample& s) {
  p.normal_x = s.nx;
  p.normal_y = s.ny;
  p.normal_z = s.nz;
  p.curvature = s.curvature;
}

template <typename P>
void makeNaN(P& p) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  p.x = p.y = p.z = nan;
}

template <typename P>
int save(const pcl::PointCloud<P>& cloud, const std::string& encoding, const std::string& out) {
  const bool ply = out.size() > 4 && out.compare(out.size() - 4, 4, ".ply") == 0;
  int rc = -1;
  if (ply) {
    pcl::PLYWriter w;
    if (encoding == "ascii")
      rc = w.write(out, cloud, false);
    else if (encoding == "binary")
      rc = w.write(out, cloud, true);
    else {
      std::cerr << "PLY encoding must be ascii or binary\n";
      return 2;
    }
  } else {
    if (encoding == "ascii")
      rc = pcl::io::savePCDFileASCII(out, cloud);
    else if (encoding == "binary")
      rc = pcl::io::savePCDFileBinary(out, cloud);
    else if (encoding == "binary_compressed")
      rc = pcl::io::savePCDFileBinaryCompressed(out, cloud);
    else {
      std::cerr << "PCD encoding must be ascii, binary or binary_compressed\n";
      return 2;
    }
  }
  if (rc != 0) {
    std::cerr << "PCL could not write " << out << "\n";
    return 1;
  }
  return 0;
}

int write(const std::string& type, const std::string& encoding, const std::string& out) {
  if (type == "organized") {
    std::vector<bool> valid;
    const auto samples = organizedSamples(valid);
    pcl::PointCloud<pcl::PointXYZRGBNormal> cloud(kGridW, kGridH);
    for (std::size_t i = 0; i < samples.size(); ++i) {
      auto& p = cloud[i];
      setXYZ(p, samples[i]);
      setNormal(p, samples[i]);
      p.r = samples[i].r;
      p.g = samples[i].g;
      p.b = samples[i].b;
      p.a = 255;
      if (!valid[i]) {
        makeNaN(p);
        p.normal_x = p.normal_y = p.normal_z = p.curvature = std::numeric_limits<float>::quiet_NaN();
      }
    }
    cloud.is_dense = false;
    cloud.sensor_origin_ = Eigen::Vector4f(5.0f, 0.0f, 20.0f, 0.0f);
    return save(cloud, encoding, out);
  }
  const auto samples = unorganized();
  const auto n = static_cast<std::uint32_t>(samples.size());
  if (type == "xyz") {
    pcl::PointCloud<pcl::PointXYZ> c;
    c.resize(n);
    for (std::uint32_t i = 0; i < n; ++i) setXYZ(c[i], samples[i]);
    return save(c, encoding, out);
  }
  if (type == "xyzi") {
    pcl::PointCloud<pcl::PointXYZI> c;
    c.resize(n);
    for (std::uint32_t i = 0; i < n; ++i) {
      setXYZ(c[i], samples[i]);
      c[i].intensity = samples[i].intensity;
    }
    return save(c, encoding, out);
  }
  if (type == "xyzrgb") {
    pcl::PointCloud<pcl::PointXYZRGB> c;
    c.resize(n);
    for (std::uint32_t i = 0; i < n; ++i) {
      setXYZ(c[i], samples[i]);
      // PCL's tutorials' idiom: the packed colour has alpha 0.
      const std::uint32_t rgb = (static_cast<std::uint32_t>(samples[i].r) << 16) |
                                (static_cast<std::uint32_t>(samples[i].g) << 8) | samples[i].b;
      std::memcpy(&c[i].rgb, &rgb, sizeof rgb);
    }
    return save(c, encoding, out);
  }
  if (type == "xyzrgbnormal") {
    pcl::PointCloud<pcl::PointXYZRGBNormal> c;
    c.resize(n);
    for (std::uint32_t i = 0; i < n; ++i) {
      setXYZ(c[i], samples[i]);
      setNormal(c[i], samples[i]);
      c[i].r = samples[i].r;
      c[i].g = samples[i].g;
      c[i].b = samples[i].b;
      c[i].a = 255;
    }
    return save(c, encoding, out);
  }
  if (type == "pointnormal") {
    pcl::PointCloud<pcl::PointNormal> c;
    c.resize(n);
    for (std::uint32_t i = 0; i < n; ++i) {
      setXYZ(c[i], samples[i]);
      setNormal(c[i], samples[i]);
    }
    return save(c, encoding, out);
  }
  std::cerr << "unknown type " << type << " (xyz, xyzi, xyzrgb, xyzrgbnormal, pointnormal, organized)\n";
  return 2;
}

bool endsWith(const std::string& s, const char* suffix) {
  const std::size_t n = std::strlen(suffix);
  if (s.size() < n) return false;
  std::string tail = s.substr(s.size() - n);
  std::transform(tail.begin(), tail.end(), tail.begin(), [](unsigned char c) { return std::tolower(c); });
  return tail == suffix;
}

std::string jsonString(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", static_cast<unsigned char>(c));
      out += buf;
    } else
      out += c;
  }
  return out + "\"";
}

int read(const std::string& path) {
  pcl::PCLPointCloud2 cloud;
  int rc = -1;
  if (endsWith(path, ".pcd"))
    rc = pcl::io::loadPCDFile(path, cloud);
  else if (endsWith(path, ".ply"))
    rc = pcl::io::loadPLYFile(path, cloud);
  else if (endsWith(path, ".obj"))
    rc = pcl::io::loadOBJFile(path, cloud);
  else {
    std::cerr << "pcl_probe read: PCL reads .pcd, .ply and .obj here, not " << path << "\n";
    return 2;
  }
  if (rc < 0) {
    std::cerr << "pcl_probe read: PCL could not load " << path << " (" << rc << ")\n";
    return 1;
  }
  std::string out;
  out.reserve(cloud.data.size() * 2 + 1024);
  out += "{\"width\": " + std::to_string(cloud.width) + ", \"height\": " + std::to_string(cloud.height);
  out += ", \"is_dense\": " + std::string(cloud.is_dense ? "true" : "false");
  out += ", \"point_step\": " + std::to_string(cloud.point_step);
  out += ", \"row_step\": " + std::to_string(cloud.row_step);
  out += ", \"fields\": [";
  for (std::size_t i = 0; i < cloud.fields.size(); ++i) {
    const auto& f = cloud.fields[i];
    if (i) out += ", ";
    out += "{\"name\": " + jsonString(f.name) + ", \"datatype\": " + std::to_string(f.datatype) +
           ", \"count\": " + std::to_string(f.count) + ", \"offset\": " + std::to_string(f.offset) + "}";
  }
  out += "], \"data\": \"";
  static const char* hex = "0123456789abcdef";
  for (const std::uint8_t b : cloud.data) {
    out += hex[b >> 4];
    out += hex[b & 15];
  }
  out += "\"}\n";
  std::fwrite(out.data(), 1, out.size(), stdout);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  // PCL prints its information on stdout: only warnings and errors (stderr), so that stdout is JSON.
  pcl::console::setVerbosityLevel(pcl::console::L_WARN);
  const std::vector<std::string> args(argv + 1, argv + argc);
  if (args.size() == 4 && args[0] == "write") return write(args[1], args[2], args[3]);
  if (args.size() == 2 && args[0] == "read") return read(args[1]);
  std::cerr << "usage: pcl_probe write TYPE ENCODING OUT.pcd|OUT.ply\n"
               "       pcl_probe read FILE.pcd|FILE.ply|FILE.obj\n";
  return 2;
}
