// PyHandleDeformation: the C++ side of hgdeform.HandleDeformation (its binding:
// handle_deformation.cpp). Internal to the module.
#pragma once

#include <cmath>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "common.h"
#include "hgdeform/app/runner.h"
#include "hgdeform/deformer/deformer.h"
#include "hgdeform/io/geometry.h"

namespace hgd_py {

/// Interactive deformation of one shape: handles by index (or a scenario), frames one at a time,
/// the deformed positions as a read-only view of the deformer's own buffer.
class PyHandleDeformation {
 public:
  // extractGeometry's own geometry (Morton order, its origin), as `hgdeform deform` builds it:
  // the library's sampling depends on the points' order, so any other order gives another
  // (equally valid, not bit-equal) result. The session behind it is the CLI's (hgd::Session,
  // through ScenarioRunner): the same handles, rebuild rule and moves.
  PyHandleDeformation(hgd::Shape shape, hgd::RunOptions options)
      : run_((checkThreadStacks(), std::move(shape)), options) {}

  void setFixed(const std::vector<std::vector<long long>>& handles) {
    std::lock_guard<std::mutex> lock(mutex_);
    run_.setFixedIndices(handles);
  }
  void setManipulated(std::vector<long long> handle) {
    std::lock_guard<std::mutex> lock(mutex_);
    run_.setManipulatedIndices(std::move(handle));
  }
  void setJoints(const std::vector<std::vector<long long>>& joints) {
    std::lock_guard<std::mutex> lock(mutex_);
    run_.setJointIndices(joints);
  }
  void setScenario(const hgd::Scenario& scenario) {
    std::lock_guard<std::mutex> lock(mutex_);
    run_.setScenarioLater(scenario);
  }

  hgd::SolveStats drag(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    return run_.deformer().drag(from, to);
  }
  hgd::DragResult dragTo(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    return run_.deformer().dragTo(from, to);
  }
  hgd::SolveStats setHandleTransform(const Eigen::Affine3d& t) {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    return run_.deformer().setHandleTransform(t);
  }
  void reset() {
    std::lock_guard<std::mutex> lock(mutex_);
    run_.reset();  // also after a handle change not built yet
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
    (void)run_.deformer().deformedPoints();
    return run_.sharedDeformer();
  }
  std::vector<Eigen::Vector3f> normals() {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    return run_.deformer().deformedNormals();
  }
  std::vector<float> field() {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    return run_.deformer().field();
  }
  /// The deformed shape written as `hgdeform deform` writes it (in double from the input's values).
  hgd::Shape deformedShape() {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    return run_.deformedShape();
  }
  double lastInterpolationMs() {
    std::lock_guard<std::mutex> lock(mutex_);
    const std::shared_ptr<const hgd::Deformer> d = run_.sharedDeformer();
    return d ? d->lastInterpolationMs() : 0.0;
  }
  hgd::Energies energies() {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    return run_.deformer().energies();
  }

  /// `f(deformer)` under the lock (built first if due): a read of the deformed shape that no
  /// frame of another thread changes half-way (world_points()).
  template <typename F>
  void withDeformer(F&& f) {
    std::lock_guard<std::mutex> lock(mutex_);
    ensureBuilt();
    f(run_.deformer());
  }

  const hgd::Geometry& geometry() const { return run_.geometry(); }
  const hgd::Shape& shape() const { return run_.shape(); }

 private:
  void ensureBuilt() {
    const std::string missing = run_.session().missingHandle();
    if (missing == "fixed")
      throw hgd::ScenarioError("HandleDeformation: no fixed handle (set_fixed or set_scenario)");
    if (!missing.empty())
      throw hgd::ScenarioError("HandleDeformation: no manipulated handle (set_manipulated or set_scenario)");
    if (run_.ensureBuilt()) run_.applyMoves();  // a scenario's moves, as `hgdeform deform` applies them
  }

  hgd::ScenarioRunner run_;
  std::mutex mutex_;  // one frame at a time (the GIL is released while it runs)
};

}  // namespace hgd_py
