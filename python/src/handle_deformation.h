// PyHandleDeformation: the C++ side of hgdeform.HandleDeformation (its binding:
// handle_deformation.cpp). Internal to the module.
#pragma once

#include <cmath>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "common.h"
#include "hgdeform/deformer/deformer.h"
#include "hgdeform/io/geometry.h"

namespace hgd_py {

/// Interactive deformation of one shape: handles by index (or a scenario), frames one at a time,
/// the deformed positions as a read-only view of the deformer's own buffer.
class PyHandleDeformation {
 public:
  PyHandleDeformation(hgd::Shape shape, hgd::RunOptions options)
      : shape_((checkThreadStacks(), std::move(shape))),
        // extractGeometry's own geometry (Morton order, its origin), as ScenarioRunner builds it
        // for `hgdeform deform`: the library's sampling depends on the points' order, so any
        // other order gives another (equally valid, not bit-equal) result.
        geometry_(std::make_shared<const hgd::Geometry>(hgd::extractGeometry(shape_))),
        options_(std::move(options)) {}

  void setFixed(const std::vector<std::vector<long long>>& handles) {
    std::lock_guard<std::mutex> lock(mutex_);
    indexHandles();
    scenario_.fixed.clear();
    for (const auto& h : handles) scenario_.fix(hgd::Region::fromIndices(h));
  }
  void setManipulated(std::vector<long long> handle) {
    std::lock_guard<std::mutex> lock(mutex_);
    indexHandles();
    scenario_.manipulate(hgd::Region::fromIndices(std::move(handle)));
  }
  void setJoints(const std::vector<std::vector<long long>>& joints) {
    std::lock_guard<std::mutex> lock(mutex_);
    indexHandles();
    scenario_.joints.clear();
    for (const auto& j : joints) scenario_.joint(hgd::Region::fromIndices(j));
  }
  void setScenario(const hgd::Scenario& scenario) {
    std::lock_guard<std::mutex> lock(mutex_);
    scenario_ = scenario;
    have_scenario_ = true;
    built_ = false;
  }

  hgd::SolveStats drag(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    return deformer_->drag(from, to);
  }
  hgd::DragResult dragTo(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    return deformer_->dragTo(from, to);
  }
  hgd::SolveStats setHandleTransform(const Eigen::Affine3d& t) {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    return deformer_->setHandleTransform(t);
  }
  void reset() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (deformer_) deformer_->reset();  // also after a handle change not built yet
  }
  void build() {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
  }

  /// The deformer (built first if due), whose positions are the buffer `points` views: no frame
  /// or handle change moves it (Deformer sizes it once); a rebuild for other options (clusters,
  /// samples, full resolution) makes a new deformer, and the old one lives on as long as a view
  /// of it does.
  std::shared_ptr<const hgd::Deformer> deformer() {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    // The build's first shape is made when first read: here, under the lock, so that a view's
    // later read only reads (another thread's move or rebuild waits for this lock).
    (void)deformer_->deformedPoints();
    return deformer_;
  }
  std::vector<Eigen::Vector3f> normals() {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    return deformer_->deformedNormals();
  }
  std::vector<float> field() {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    return deformer_->field();
  }
  /// The deformed shape written as `hgdeform deform` writes it (in double from the input's values).
  hgd::Shape deformedShape() {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    hgd::Shape out = shape_;
    deformer_->writeDeformed(out);
    return out;
  }
  double lastInterpolationMs() {
    std::lock_guard<std::mutex> lock(mutex_);
    return deformer_ ? deformer_->lastInterpolationMs() : 0.0;
  }
  hgd::Energies energies() {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    return deformer_->energies();
  }

  const hgd::Geometry& geometry() const { return *geometry_; }
  const hgd::Shape& shape() const { return shape_; }

 private:
  void indexHandles() {
    // Handles by index replace a scenario given before (its regions and moves) whole.
    if (have_scenario_) scenario_ = hgd::Scenario{};
    have_scenario_ = false;
    built_ = false;
  }

  void ensureBuilt() {
    if (built_) return;
    if (scenario_.fixed.empty())
      throw hgd::ScenarioError("HandleDeformation: no fixed handle (set_fixed or set_scenario)");
    if (!have_scenario_ && scenario_.manipulated.indices.empty())
      throw hgd::ScenarioError("HandleDeformation: no manipulated handle (set_manipulated or set_scenario)");
    const hgd::Handles handles = hgd::resolveHandles(scenario_, *geometry_, shape_);
    const hgd::DeformOptions opt = hgd::mergedOptions(options_, scenario_, shape_, *geometry_);
    // The deformer is kept (and the buffer `points` views with it) while only the handles or the
    // blend change. The options mergedOptions() takes from a scenario besides the blend (the
    // rest come from the constructor and the shape) are built into it: clusters and full
    // resolution need a new one.
    if (!deformer_ || opt.clusters.isovalues != built_options_.clusters.isovalues ||
        opt.multires_above != built_options_.multires_above) {
      deformer_ = std::make_shared<hgd::Deformer>(geometry_, handles, opt);
    } else {
      deformer_->setHandles(handles);  // normals, kNN and the graph kept
      deformer_->setBlend(opt.blend);
    }
    built_options_ = opt;
    built_ = true;
    for (const hgd::Move& m : scenario_.moves) applyMove(m);
  }

  /// A scenario's move, as `hgdeform deform` applies it (ScenarioRunner::apply).
  void applyMove(const hgd::Move& move) {
    hgd::Deformer& d = *deformer_;
    if (move.kind == hgd::Move::Kind::Drag) {
      if (move.drag.keep_orientation)
        d.translateHandle(move.drag.from, move.drag.to);
      else
        d.dragTo(move.drag.from, move.drag.to);
      return;
    }
    const hgd::FrameMove& f = move.frame;
    const Eigen::Vector3d centre = f.centre ? *f.centre : d.handleCentre();
    Eigen::Affine3d motion = Eigen::Affine3d::Identity();
    motion.translate(centre + f.translate);
    motion.rotate(Eigen::AngleAxisd(f.degrees * M_PI / 180.0, f.axis.normalized()));
    motion.translate(-centre);
    d.moveHandle(motion);
  }

  hgd::Shape shape_;
  std::shared_ptr<const hgd::Geometry> geometry_;
  hgd::RunOptions options_;
  hgd::Scenario scenario_;
  bool have_scenario_ = false;
  bool built_ = false;
  std::shared_ptr<hgd::Deformer> deformer_;  // shared with the `points` views of it
  hgd::DeformOptions built_options_;
  std::mutex mutex_;  // one frame at a time (the GIL is released while it runs)
};

}  // namespace hgd_py
