// Helpers shared by the test suites.
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "hgdeform/app/regions.h"
#include "hgdeform/io/geometry.h"
#include "hgdeform/io/shape.h"

// Built with AddressSanitizer: `ulimit -v` cannot apply (its shadow memory needs terabytes of
// address space), so tests that set one skip that part.
#if defined(__SANITIZE_ADDRESS__)
#define HGD_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define HGD_TEST_ASAN 1
#endif
#endif

namespace hgdtest {

/// A fresh directory under the system temp dir, removed when the object dies.
class TempDir {
 public:
  TempDir() {
    std::random_device rd;
    path_ = std::filesystem::temp_directory_path() /
            ("hgdeform-test-" + std::to_string(rd()) + std::to_string(rd()));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  const std::filesystem::path& path() const { return path_; }
  /// Names of the files in the directory (to check that nothing was left behind).
  std::vector<std::string> list() const {
    std::vector<std::string> out;
    for (const auto& e : std::filesystem::directory_iterator(path_))
      out.push_back(e.path().filename().string());
    return out;
  }

 private:
  std::filesystem::path path_;
};

/// Appends the bytes of `v` (in this machine's order, or reversed for the other endianness).
template <typename T>
void put(std::string& s, T v, bool big_endian = false) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof v);
  if (big_endian) std::reverse(b, b + sizeof b);
  s.append(b, sizeof b);
}

/// `s` as one single-quoted shell word.
inline std::string quote(const std::string& s) {
  std::string q = "'";
  for (const char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

/// A whole file's bytes ("" when it cannot be read).
inline std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

inline bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

struct CommandResult {
  int code = -1;  ///< exit status; -1 when killed by a signal
  std::string out, err;
};

/// Runs a shell command line with stdout and stderr captured separately.
inline CommandResult shell(const std::string& command) {
  static TempDir err_dir;  // stderr goes here, never into a directory a test inspects
  const std::string err_file = err_dir.file("stderr.txt");
  CommandResult r;
  FILE* pipe = popen((command + " 2>" + quote(err_file)).c_str(), "r");
  if (!pipe) return r;
  char buf[4096];
  std::size_t got;
  while ((got = fread(buf, 1, sizeof buf, pipe)) > 0) r.out.append(buf, got);
  const int status = pclose(pipe);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.err = slurp(err_file);
  return r;
}

inline void writeText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

/// Runs a shell command, returns its exit status; stdout+stderr in `output`.
inline int run(const std::string& command, std::string& output) {
  const std::string full = command + " 2>&1";
  FILE* pipe = popen(full.c_str(), "r");
  if (!pipe) return -1;
  char buf[4096];
  output.clear();
  std::size_t got;
  while ((got = fread(buf, 1, sizeof buf, pipe)) > 0) output.append(buf, got);
  const int status = pclose(pipe);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/// Indices of finite points whose world coordinate along `axis` is <= hi / >= lo.
inline std::vector<int> pointsWhere(const hgd::Geometry& g, int axis, double lo, double hi) {
  std::vector<int> out;
  for (std::size_t i = 0; i < g.size(); ++i) {
    const double v = g.world(i)[axis];
    if (v >= lo && v <= hi) out.push_back(static_cast<int>(i));
  }
  return out;
}

/// The set-up of most bar and fork tests: fixed where x <= `fixed_below`, manipulated where
/// x >= `manipulated_from` (pointsWhere along x).
inline hgd::Handles endHandles(const hgd::Geometry& g, double fixed_below, double manipulated_from) {
  hgd::Handles h;
  h.fixed.push_back(pointsWhere(g, 0, -1, fixed_below));
  h.manipulated = pointsWhere(g, 0, manipulated_from, 2);
  return h;
}

// Best rigid fit (Kabsch) of `after` to `before`; RMS residual.
inline double rigidResidual(const std::vector<Eigen::Vector3d>& before,
                            const std::vector<Eigen::Vector3d>& after) {
  const std::size_t n = before.size();
  Eigen::Vector3d cb = Eigen::Vector3d::Zero(), ca = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    cb += before[i];
    ca += after[i];
  }
  cb /= static_cast<double>(n);
  ca /= static_cast<double>(n);
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < n; ++i) cov += (after[i] - ca) * (before[i] - cb).transpose();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d r = svd.matrixU() * svd.matrixV().transpose();
  if (r.determinant() < 0) {
    Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
    d(2, 2) = -1;
    r = svd.matrixU() * d * svd.matrixV().transpose();
  }
  double s = 0;
  for (std::size_t i = 0; i < n; ++i) s += (r * (before[i] - cb) + ca - after[i]).squaredNorm();
  return std::sqrt(s / static_cast<double>(n));
}

inline std::string datasetsDir() {
  return HGD_DATA_DIR;
}
inline std::string sharedDatasetsDir() {
  return HGD_SHARED_DATA_DIR;
}
inline bool exists(const std::string& p) {
  return std::filesystem::exists(p);
}

}  // namespace hgdtest
