// Definitions of <hgdeform/pcl.h>. The library instantiates them for PCL's common xyz point
// types; include this header only to deform a point type of your own.
#pragma once

#include <pcl/common/io.h>
#include <pcl/conversions.h>
#include <pcl/point_traits.h>

#include <stdexcept>
#include <utility>

#include "hgdeform/app/pcl.h"

namespace hgd {
namespace pcl_detail {

template <typename PointT>
Shape shapeFromCloud(const pcl::PointCloud<PointT>& cloud) {
  Shape shape;
  pcl::toPCLPointCloud2(cloud, shape.cloud);
  shape.sensor_origin = cloud.sensor_origin_;
  shape.sensor_orientation = cloud.sensor_orientation_;
  shape.format = FileFormat::Pcd;
  return shape;
}

// The deformed positions (and normals, when PointT has them) written into `output`, which
// holds a copy of the cloud the runner was built on.
template <typename PointT>
void copyDeformed(const ScenarioRunner& runner, pcl::PointCloud<PointT>& output) {
  if (!runner.ready()) return;  // no handles: the rest shape
  const Geometry& g = runner.geometry();
  const Deformer& d = runner.deformer();
  // In double from the cloud's own values; points that do not move are not written (to the bit).
  const ExactInterpolation exact = d.exactInterpolation();
  const InterpolationTable& table = d.interpolationTable();
  for (std::size_t k = 0; k < g.size(); ++k) {
    if (!exact.moves(k)) continue;
    PointT& p = output[static_cast<std::size_t>(g.raw_index[k])];
    const Eigen::Vector3d rest(p.x, p.y, p.z);
    const Eigen::Vector3d w = exact.apply(k, rest - g.origin) + g.origin;
    p.x = static_cast<float>(w.x());
    p.y = static_cast<float>(w.y());
    p.z = static_cast<float>(w.z());
    if constexpr (pcl::traits::has_normal_v<PointT>) {
      // Only where the cloud's own normals were used: a cloud whose normals are unset keeps them.
      if (g.hasFileNormals() && table.has_normals && p.getNormalVector3fMap().allFinite()) {
        const Eigen::Vector3d n = exact.applyNormal(k, table.restNormal(k).template cast<double>());
        p.normal_x = static_cast<float>(n.x());
        p.normal_y = static_cast<float>(n.y());
        p.normal_z = static_cast<float>(n.z());
      }
    }
  }
}

}  // namespace pcl_detail

template <typename PointT>
DeformReport deform(const pcl::PointCloud<PointT>& input, const Scenario& scenario,
                    pcl::PointCloud<PointT>& output, const RunOptions& options) {
  ScenarioRunner run(pcl_detail::shapeFromCloud(input), options);
  run.setScenario(scenario);
  run.applyMoves();
  if (&output != &input) output = input;
  pcl_detail::copyDeformed(run, output);
  return run.report();
}

template <typename PointT>
HandleDeformation<PointT>::HandleDeformation() = default;

template <typename PointT>
HandleDeformation<PointT>::~HandleDeformation() = default;

template <typename PointT>
void HandleDeformation<PointT>::setInputCloud(const PointCloudConstPtr& cloud) {
  pcl::PCLBase<PointT>::setInputCloud(cloud);
  input_changed_ = true;
}

template <typename PointT>
void HandleDeformation<PointT>::setOptions(const RunOptions& options) {
  runner_.setOptions(options);
}

namespace pcl_detail {
inline std::vector<long long> indexList(const pcl::Indices& indices) {
  return std::vector<long long>(indices.begin(), indices.end());
}
}  // namespace pcl_detail

template <typename PointT>
void HandleDeformation<PointT>::setFixedHandles(const std::vector<pcl::Indices>& handles) {
  std::vector<std::vector<long long>> lists;
  for (const auto& h : handles) lists.push_back(pcl_detail::indexList(h));
  runner_.setFixedIndices(lists);
}

template <typename PointT>
void HandleDeformation<PointT>::setManipulatedHandle(const pcl::Indices& handle) {
  runner_.setManipulatedIndices(pcl_detail::indexList(handle));
}

template <typename PointT>
void HandleDeformation<PointT>::setJoints(const std::vector<pcl::Indices>& joints) {
  std::vector<std::vector<long long>> lists;
  for (const auto& j : joints) lists.push_back(pcl_detail::indexList(j));
  runner_.setJointIndices(lists);
}

template <typename PointT>
void HandleDeformation<PointT>::setScenario(const Scenario& scenario) {
  runner_.setScenarioLater(scenario);
}

template <typename PointT>
void HandleDeformation<PointT>::ensureBuilt() {
  if (!this->input_ || this->input_->empty())
    throw std::invalid_argument("HandleDeformation: no input cloud (setInputCloud)");
  if (input_changed_) {
    runner_.setShape(pcl_detail::shapeFromCloud(*this->input_));
    input_changed_ = false;
  }
  const std::string missing = runner_.session().missingHandle();
  if (missing == "fixed")
    throw ScenarioError("HandleDeformation: no fixed handle (setFixedHandles or setScenario)");
  if (!missing.empty())
    throw ScenarioError("HandleDeformation: no manipulated handle (setManipulatedHandle or setScenario)");
  if (runner_.ensureBuilt()) runner_.applyMoves();  // a scenario's moves, as hgdeform deform applies them
}

template <typename PointT>
SolveStats HandleDeformation<PointT>::drag(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  ensureBuilt();
  return runner_.deformer().drag(from, to);
}

template <typename PointT>
DragResult HandleDeformation<PointT>::dragTo(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  ensureBuilt();
  return runner_.deformer().dragTo(from, to);
}

template <typename PointT>
SolveStats HandleDeformation<PointT>::setHandleTransform(const Eigen::Affine3d& transform) {
  ensureBuilt();
  return runner_.deformer().setHandleTransform(transform);
}

template <typename PointT>
void HandleDeformation<PointT>::reset() {
  if (runner_.ready()) runner_.reset();
}

template <typename PointT>
void HandleDeformation<PointT>::getDeformedCloud(PointCloud& output) {
  ensureBuilt();
  output = *this->input_;
  pcl_detail::copyDeformed(runner_, output);
}

template <typename PointT>
ScenarioRunner& HandleDeformation<PointT>::runner() {
  ensureBuilt();
  return runner_;
}

}  // namespace hgd
