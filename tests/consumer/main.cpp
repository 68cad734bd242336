// A downstream program built against the installed hgdeform: a PCL cloud deformed through
// <hgdeform/pcl.h> (the documented name), once with a scenario built in code and once with the
// interactive stage.
#include <hgdeform/hgdeform.h>  // the whole API, as installed
#include <hgdeform/pcl.h>

#include <cmath>
#include <cstdio>
#include <memory>

int main() {
  // A 1 x 0.1 strip of 2,000 points, with colours that must come back unchanged.
  auto cloud = std::make_shared<pcl::PointCloud<pcl::PointXYZRGB>>();
  for (int i = 0; i < 200; ++i)
    for (int j = 0; j < 10; ++j) {
      pcl::PointXYZRGB p;
      p.x = i / 199.0f;
      p.y = j / 90.0f;
      p.z = 0.0f;
      p.r = static_cast<std::uint8_t>(i);
      p.g = static_cast<std::uint8_t>(j);
      p.b = 7;
      cloud->push_back(p);
    }
  hgd::Scenario s;
  s.fix(hgd::Region::box(Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(0.1, 1, 1)))
      .manipulate(hgd::Region::box(Eigen::Vector3d(0.9, -1, -1), Eigen::Vector3d(2, 1, 1)))
      .drag(Eigen::Vector3d(1, 0.05, 0), Eigen::Vector3d(1, 0.05, 0.3));
  pcl::PointCloud<pcl::PointXYZRGB> out;
  const hgd::DeformReport report = hgd::deform(*cloud, s, out);
  std::printf("consumer: %zu points, %zu clusters, tip at z = %.3f\n", report.points, report.clusters,
              out[cloud->size() - 5].z);
  if (out.size() != cloud->size() || !report.reached) return 1;
  for (std::size_t i = 0; i < out.size(); ++i)
    if (out[i].r != (*cloud)[i].r || out[i].g != (*cloud)[i].g || out[i].b != 7) return 1;
  if (!(std::abs(out[cloud->size() - 5].z - 0.3f) < 0.01f)) return 1;

  hgd::HandleDeformation<pcl::PointXYZRGB> stage;
  stage.setInputCloud(cloud);
  pcl::Indices base, tip;
  for (std::size_t i = 0; i < cloud->size(); ++i) {
    if ((*cloud)[i].x < 0.1f) base.push_back(static_cast<pcl::index_t>(i));
    if ((*cloud)[i].x > 0.9f) tip.push_back(static_cast<pcl::index_t>(i));
  }
  stage.setFixedHandles({base});
  stage.setManipulatedHandle(tip);
  Eigen::Affine3d lift = Eigen::Affine3d::Identity();
  lift.translate(Eigen::Vector3d(0, 0, 0.2));
  stage.setHandleTransform(lift);
  stage.getDeformedCloud(out);
  std::printf("consumer: stage tip at z = %.3f\n", out[cloud->size() - 5].z);
  return std::abs(out[cloud->size() - 5].z - 0.2f) < 1e-3f ? 0 : 1;
}
