// The typed PCL entry, where programs written against hgdeform 0.x include it: deform a
// pcl::PointCloud<PointT> by handles (hgd::deform, hgd::HandleDeformation<PointT>). Kept as the
// documented, stable name; the declarations live in hgdeform/app/pcl.h, beside the runner
// they use.
#pragma once

#include "hgdeform/app/pcl.h"  // IWYU pragma: export
