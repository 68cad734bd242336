// The references hgdeform-bench measures in the same run, on the same cloud, so that its targets
// are ratios (issue: "targets are ratios printed by the benchmark against references measured
// in the same run"): PCL's own normal estimation, and a streaming pass as cheap as a blend can be.
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <chrono>
#include <cstddef>
#include <vector>

namespace hgdbench {

/// The median of `v` (0 when empty): what hgdeform-bench reports of repeated runs.
double median(std::vector<double> v);

/// Milliseconds since `t0` (a steady_clock reading): how every time of the bench is taken.
double msSince(std::chrono::steady_clock::time_point t0);

/// Median ms of pcl::NormalEstimationOMP (k nearest neighbours, a k-d tree, every OpenMP
/// thread) over `repeat` runs on `cloud`.
double pclNormalEstimationMs(const pcl::PointCloud<pcl::PointXYZ>::ConstPtr& cloud, int k, int repeat);

/// Median ms of the streaming reference over `repeat` runs on n points: each point reads its
/// 12-byte position and an 8-byte record (two 16-bit transform ids and a float weight), blends
/// the two 3x4 transforms it names (of 32) by the weight, applies the blend and writes 12 bytes;
/// OpenMP over every thread. What an interpolation costs when it does nothing else.
double streamingReferenceMs(std::size_t n, int repeat);

/// The streaming reference as an object, its buffers (32 bytes a point) made once: runMs() is
/// one pass, so that passes can alternate with the interpolation they are compared with.
class StreamingReference {
 public:
  explicit StreamingReference(std::size_t n);
  ~StreamingReference();
  StreamingReference(const StreamingReference&) = delete;
  StreamingReference& operator=(const StreamingReference&) = delete;
  double runMs();

 private:
  struct Buffers;
  Buffers* b_;
};

}  // namespace hgdbench
