#include "bench_references.h"

#include <omp.h>
#include <pcl/features/normal_3d_omp.h>
#include <pcl/search/kdtree.h>

#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <random>
#include <vector>

namespace hgdbench {

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n == 0 ? 0 : n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double pclNormalEstimationMs(const pcl::PointCloud<pcl::PointXYZ>::ConstPtr& cloud, int k, int repeat) {
  std::vector<double> ms;
  for (int r = 0; r < repeat; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    pcl::NormalEstimationOMP<pcl::PointXYZ, pcl::Normal> ne(static_cast<unsigned>(omp_get_max_threads()));
    ne.setInputCloud(cloud);
    ne.setSearchMethod(pcl::search::KdTree<pcl::PointXYZ>::Ptr(new pcl::search::KdTree<pcl::PointXYZ>));
    ne.setKSearch(k);
    pcl::PointCloud<pcl::Normal> normals;
    ne.compute(normals);
    ms.push_back(msSince(t0));
  }
  return median(ms);
}

struct StreamingReference::Buffers {
  struct Record {
    std::uint16_t a, b;
    float w;
  };
  static_assert(sizeof(Record) == 8, "an 8-byte record");
  std::vector<float> in, out;
  std::vector<Record> rec;
  std::vector<Eigen::Matrix<float, 3, 4>> t;
};

StreamingReference::StreamingReference(std::size_t n) : b_(new Buffers) {
  b_->in.resize(3 * n);
  b_->out.resize(3 * n);
  b_->rec.resize(n);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1, 1);
  for (auto& x : b_->in) x = u(rng);
  for (auto& r : b_->rec)
    r = {static_cast<std::uint16_t>(rng() % 32), static_cast<std::uint16_t>(rng() % 32), 0.5f * (u(rng) + 1)};
  b_->t.resize(32);
  for (auto& m : b_->t) m = Eigen::Matrix<float, 3, 4>::Random();
}

StreamingReference::~StreamingReference() {
  delete b_;
}

double StreamingReference::runMs() {
  const long long nn = static_cast<long long>(b_->rec.size());
  const Buffers::Record* rec = b_->rec.data();
  const Eigen::Matrix<float, 3, 4>* t = b_->t.data();
  const float* in = b_->in.data();
  float* out = b_->out.data();
  const auto t0 = std::chrono::steady_clock::now();
#pragma omp parallel for schedule(static)
  for (long long i = 0; i < nn; ++i) {
    const Buffers::Record& q = rec[i];
    const Eigen::Matrix<float, 3, 4> m = (1 - q.w) * t[q.a] + q.w * t[q.b];
    const Eigen::Map<const Eigen::Vector3f> p(in + 3 * i);
    Eigen::Map<Eigen::Vector3f> o(out + 3 * i);
    o = m.leftCols<3>() * p + m.col(3);
  }
  const double ms = msSince(t0);
  volatile float sink = nn > 0 ? out[3 * (nn / 2)] : 0.0f;  // the writes are used
  (void)sink;
  return ms;
}

double streamingReferenceMs(std::size_t n, int repeat) {
  StreamingReference ref(n);
  std::vector<double> ms;
  for (int r = 0; r < repeat; ++r) ms.push_back(ref.runMs());
  return median(ms);
}

}  // namespace hgdbench
