// What the tests of the pictures of hgdeform-view and hgdeform-render share (test_viewer.cpp,
// test_render.cpp): whether xvfb-run is there, where a colour lies in a picture, and a depth
// camera's scan.
#pragma once

#include <pcl/conversions.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <cmath>
#include <cstdlib>
#include <string>

#include "hgdeform/io/io.h"
#include "support/png_image.h"
#include "test_util.h"

namespace hgdtest {

inline bool haveXvfb() {
  std::string out;
  return hgdtest::run("command -v xvfb-run", out) == 0;
}

/// Mean column and row of the pixels near a colour, and how many there are.
struct Blob {
  int count = 0;
  double x = 0, y = 0;
};
inline Blob blob(const Image& img, int r, int g, int b) {
  Blob out;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      const unsigned char* p = img.at(x, y);
      if (std::abs(p[0] - r) < 40 && std::abs(p[1] - g) < 40 && std::abs(p[2] - b) < 40) {
        ++out.count;
        out.x += x;
        out.y += y;
      }
    }
  if (out.count > 0) {
    out.x /= out.count;
    out.y /= out.count;
  }
  return out;
}

/// A depth camera's organized scan in PCL's frame (+z forward, +y down): a wall 2 m ahead whose
/// top rows (smallest y) are red and right columns (largest x) green, the rest grey.
inline pcl::PointCloud<pcl::PointXYZRGB> cameraScan() {
  pcl::PointCloud<pcl::PointXYZRGB> cloud(40, 32);
  for (int v = 0; v < 32; ++v)
    for (int u = 0; u < 40; ++u) {
      auto& p = cloud.at(u, v);
      p.x = -0.5f + u / 39.0f;
      p.y = -0.4f + 0.8f * v / 31.0f;
      p.z = 2.0f + 0.05f * std::sin(0.3f * u);
      const bool top = v < 6, right = u >= 34;
      p.r = top ? 255 : right ? 0 : 128;
      p.g = top ? 0 : right ? 255 : 128;
      p.b = top || right ? 0 : 128;
    }
  return cloud;
}

/// cameraScan() written to `dir` twice: organized (scan.pcd) and as one row (flat.pcd).
inline void writeCameraScans(const TempDir& dir) {
  hgd::Shape organized;
  pcl::toPCLPointCloud2(cameraScan(), organized.cloud);
  organized.format = hgd::FileFormat::Pcd;
  hgd::writeShape(dir.file("scan.pcd"), organized);
  hgd::Shape flat = organized;
  flat.cloud.width = flat.cloud.width * flat.cloud.height;
  flat.cloud.height = 1;
  flat.cloud.row_step = flat.cloud.point_step * flat.cloud.width;
  hgd::writeShape(dir.file("flat.pcd"), flat);
}

}  // namespace hgdtest
