// The typed PCL entry: deform a pcl::PointCloud<PointT> by handles.
//
//   #include <hgdeform/pcl.h>     (this file, by its stable name)
//   pcl::PointCloud<pcl::PointXYZRGB> cloud, deformed;
//   hgd::Scenario s;
//   s.fix(hgd::Region::box(lo, hi)).manipulate(hgd::Region::sphere(c, r)).drag(from, to);
//   hgd::DeformReport report = hgd::deform(cloud, s, deformed);
//
// Every field other than the position (and the normal, which turns with the surface) is copied
// unchanged; NaN points stay where they are; width, height, is_dense and the sensor pose are
// kept. For interactive use, hgd::HandleDeformation<PointT> is a PCL-style stage:
//
//   hgd::HandleDeformation<pcl::PointXYZ> hd;
//   hd.setInputCloud(cloud);                       // a PointCloud<PointT>::ConstPtr
//   hd.setFixedHandles({base_indices});            // pcl::Indices into the cloud
//   hd.setManipulatedHandle(hand_indices);         // (or hd.setScenario(s))
//   hd.drag(from, to);                             // one interactive frame
//   hd.setHandleTransform(T);                      // or: the frame metaphor
//   hd.getDeformedCloud(out);
//
// Instantiated in the library for PointXYZ, PointXYZI, PointXYZL, PointXYZRGB, PointXYZRGBA,
// PointNormal, PointXYZINormal and PointXYZRGBNormal. For another point type with x, y, z,
// include <hgdeform/app/impl/pcl.hpp> as well (it holds the definitions).
#pragma once

#include <pcl/pcl_base.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/types.h>

#include <Eigen/Geometry>
#include <memory>
#include <vector>

#include "hgdeform/app/runner.h"
#include "hgdeform/app/scenario.h"

namespace hgd {

/// The scenario applied to `input` (its regions resolved on the cloud, its moves replayed);
/// the deformed cloud in `output` (which may be `input`). Throws ScenarioError when a region
/// does not fit the cloud, IoError when the cloud has no finite point.
template <typename PointT>
DeformReport deform(const pcl::PointCloud<PointT>& input, const Scenario& scenario,
                    pcl::PointCloud<PointT>& output, const RunOptions& options = {});

/// A PCL-style stage for interactive deformation, thin over a ScenarioRunner and its Session
/// (session.h): the deformer is built on the first frame after the input, the options or the
/// handles change (normals, kNN and the graph are kept when only the handles change; another
/// isovalue count or resolution builds a new one).
template <typename PointT>
class HandleDeformation : public pcl::PCLBase<PointT> {
 public:
  using PointCloud = pcl::PointCloud<PointT>;
  using PointCloudConstPtr = typename PointCloud::ConstPtr;
  using Ptr = std::shared_ptr<HandleDeformation<PointT>>;
  using ConstPtr = std::shared_ptr<const HandleDeformation<PointT>>;

  HandleDeformation();
  ~HandleDeformation() override;
  HandleDeformation(const HandleDeformation&) = delete;
  HandleDeformation& operator=(const HandleDeformation&) = delete;

  /// The cloud to deform (the deformation starts over from it).
  void setInputCloud(const PointCloudConstPtr& cloud) override;

  /// Options (kNN size, solver, isovalue count, blend ...).
  void setOptions(const RunOptions& options);

  /// Handles as indices into the input cloud (NaN points among them are skipped).
  void setFixedHandles(const std::vector<pcl::Indices>& handles);
  void setManipulatedHandle(const pcl::Indices& handle);
  void setJoints(const std::vector<pcl::Indices>& joints);
  /// Handles (and options: clusters, blend) from a scenario; its moves are applied when the
  /// deformer is built. Replaces handles set by index.
  void setScenario(const Scenario& scenario);

  /// One interactive frame of direct manipulation: the manipulated handle's point nearest
  /// `from` (world coordinates, deformed shape) is pulled towards `to`.
  SolveStats drag(const Eigen::Vector3d& from, const Eigen::Vector3d& to);
  /// A whole drag replayed until the picked point reaches `to` (as a scenario's drag move).
  DragResult dragTo(const Eigen::Vector3d& from, const Eigen::Vector3d& to);
  /// Frame metaphor: the manipulated handle gets `transform` (world, relative to rest) exactly.
  SolveStats setHandleTransform(const Eigen::Affine3d& transform);
  /// Back to the rest shape.
  void reset();

  /// The deformed cloud: the input with deformed positions (and normals).
  void getDeformedCloud(PointCloud& output);

  /// The runner behind the stage (built on demand): the deformer, the field, the report.
  ScenarioRunner& runner();

 private:
  void ensureBuilt();

  ScenarioRunner runner_;      // its session holds the handles and options until the input comes
  bool input_changed_ = true;  // the input cloud is not the runner's shape yet
};

}  // namespace hgd

#ifndef HGD_PCL_INSTANTIATING
#define HGD_PCL_EXTERN(T)                                                                           \
  extern template hgd::DeformReport hgd::deform<T>(const pcl::PointCloud<T>&, const hgd::Scenario&, \
                                                   pcl::PointCloud<T>&, const hgd::RunOptions&);    \
  extern template class hgd::HandleDeformation<T>;
HGD_PCL_EXTERN(pcl::PointXYZ)
HGD_PCL_EXTERN(pcl::PointXYZI)
HGD_PCL_EXTERN(pcl::PointXYZL)
HGD_PCL_EXTERN(pcl::PointXYZRGB)
HGD_PCL_EXTERN(pcl::PointXYZRGBA)
HGD_PCL_EXTERN(pcl::PointNormal)
HGD_PCL_EXTERN(pcl::PointXYZINormal)
HGD_PCL_EXTERN(pcl::PointXYZRGBNormal)
#undef HGD_PCL_EXTERN
#endif
