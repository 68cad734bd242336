// The typed PCL entry, instantiated for PCL's common xyz point types (the only file that
// includes PCL's conversions for them).
#define HGD_PCL_INSTANTIATING
#include "hgdeform/app/pcl.h"

#include "hgdeform/app/impl/pcl.hpp"

#define HGD_PCL_INSTANTIATE(T)                                                               \
  template hgd::DeformReport hgd::deform<T>(const pcl::PointCloud<T>&, const hgd::Scenario&, \
                                            pcl::PointCloud<T>&, const hgd::RunOptions&);    \
  template class hgd::HandleDeformation<T>;

HGD_PCL_INSTANTIATE(pcl::PointXYZ)
HGD_PCL_INSTANTIATE(pcl::PointXYZI)
HGD_PCL_INSTANTIATE(pcl::PointXYZL)
HGD_PCL_INSTANTIATE(pcl::PointXYZRGB)
HGD_PCL_INSTANTIATE(pcl::PointXYZRGBA)
HGD_PCL_INSTANTIATE(pcl::PointNormal)
HGD_PCL_INSTANTIATE(pcl::PointXYZINormal)
HGD_PCL_INSTANTIATE(pcl::PointXYZRGBNormal)
