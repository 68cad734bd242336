#include "hgdeform/field/harmonic_field.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include "field/laplacian.h"
#include "util/parallel.h"
#include "util/phases.h"
#include "util/timer.h"

namespace hgd {

void HarmonicField::setSurfaceGraph(std::shared_ptr<SurfaceGraph> graph) {
  if (!graph) throw std::invalid_argument("HarmonicField: no surface graph");
  graph_ = std::move(graph);
  graph_->setOptions(options_);
}

void HarmonicField::setInputCloud(const pcl::PointCloud<pcl::PointXYZ>::ConstPtr& cloud) {
  graph_->setInputCloud(cloud);
}

void HarmonicField::setInputNormals(const pcl::PointCloud<pcl::Normal>::ConstPtr& normals) {
  graph_->setInputNormals(normals);
}

void HarmonicField::setPolygons(const std::vector<pcl::Vertices>& polygons) {
  graph_->setPolygons(polygons);
}

void HarmonicField::setHandles(const std::vector<std::vector<int>>& fixed,
                               const std::vector<int>& manipulated) {
  fixed_ = fixed;
  manipulated_ = manipulated;
}

void HarmonicField::setOptions(const FieldOptions& options) {
  options_ = options;
  graph_->setOptions(options);
}

void HarmonicField::compute(std::vector<float>& phi) {
  const auto& cloud = graph_->inputCloud();
  if (!cloud || cloud->empty()) throw std::invalid_argument("HarmonicField: no input cloud");
  if (manipulated_.empty()) throw std::invalid_argument("HarmonicField: no manipulated handle");
  if (fixed_.empty()) throw std::invalid_argument("HarmonicField: no fixed handle");
  const std::size_t n = cloud->size();
  PhaseClock clock;
  std::vector<char> constrained(n, 0);
  std::vector<double> value(n, 0.0);
  auto mark = [&](const std::vector<int>& idx, double v) {
    for (int i : idx) {
      if (i < 0 || static_cast<std::size_t>(i) >= n)
        throw std::invalid_argument("HarmonicField: handle index " + std::to_string(i) + " out of range");
      constrained[static_cast<std::size_t>(i)] = 1;
      value[static_cast<std::size_t>(i)] = v;
    }
  };
  for (const auto& f : fixed_) mark(f, 0.0);
  mark(manipulated_, 1.0);  // a point in both keeps 1; resolveHandles rejects that earlier

  FieldTimings t = timings_;
  clock.lap("field.constraints");
  if (graph_->compute()) {
    const GraphTimings& g = graph_->timings();
    t.knn_ms = g.knn_ms, t.normals_ms = g.normals_ms, t.graph_ms = g.graph_ms;
  } else {
    t.knn_ms = t.normals_ms = t.graph_ms = 0;  // kept: this compute() did not pay for them
  }
  const std::vector<char>& outliers = graph_->outliers();
  // A stray inside a handle region is no constraint: as a leaf it would pass the handle's
  // value to the surface point it hangs from, maybe on another part (a stray between the
  // prongs of a fork, inside the dragged prong's handle box, hung from the other prong and
  // pulled it along). It takes its anchor's value; it still moves with its handle. A handle
  // of strays only keeps them.
  if (!outliers.empty()) {
    auto release = [&](const std::vector<int>& idx) {
      const bool any_inlier =
          std::any_of(idx.begin(), idx.end(), [&](int i) { return !outliers[static_cast<std::size_t>(i)]; });
      if (any_inlier)
        for (int i : idx)
          if (outliers[static_cast<std::size_t>(i)])
            constrained[static_cast<std::size_t>(i)] = 0, value[static_cast<std::size_t>(i)] = 0;
    };
    for (const auto& f : fixed_) release(f);
    release(manipulated_);
  }
  clock.skip();
  Stopwatch sw_join;
  graph_->joinPieces(constrained);
  t.graph_ms += sw_join.ms();
  clock.lap("field.join_pieces");
  solveDirichlet(graph_->graph(), constrained, value, options_, unreachable_, t, &piece_);
  timings_ = t;
  clock.skip();
  phi.resize(n);
  for (std::size_t i = 0; i < n; ++i) phi[i] = static_cast<float>(std::clamp(value[i], 0.0, 1.0));
  clock.lap("field.store");
}

}  // namespace hgd
