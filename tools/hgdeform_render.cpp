// hgdeform-render: off-screen pictures of shapes (for the README, reports and thumbnails).
//
//   hgdeform-render IN.ply [IN2.ply ...] -o OUT.png [--field harmonic] [--size 1200x600]
//                   [--view x,y,z] [--title "a" --title "b" ...]
//
// Each input gets its own viewport, side by side, all seen from the same direction. A mesh is
// drawn as a surface, a cloud as points; colours come from the scalar field named by --field
// (blue to red), else from the file's colours, else a neutral grey. Needs an X display (run
// under xvfb-run on a headless machine).
#include <pcl/conversions.h>
#include <pcl/visualization/pcl_visualizer.h>
#include <vtkPNGWriter.h>
#include <vtkRenderWindow.h>
#include <vtkSmartPointer.h>
#include <vtkWindowToImageFilter.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <string>
#include <vector>

#include "hgdeform/fields.h"
#include "hgdeform/geometry.h"
#include "hgdeform/io.h"

namespace {

Eigen::Vector3f colourMap(float v) {
  v = std::clamp(std::isfinite(v) ? v : 0.0f, 0.0f, 1.0f);
  const Eigen::Vector3f stops[4] = {
      {0.23f, 0.30f, 0.75f}, {0.35f, 0.80f, 0.90f}, {0.95f, 0.85f, 0.30f}, {0.71f, 0.02f, 0.15f}};
  const float x = v * 3.0f;
  const int k = std::min(2, static_cast<int>(x));
  const float t = x - static_cast<float>(k);
  return (1 - t) * stops[k] + t * stops[k + 1];
}

pcl::PointCloud<pcl::PointXYZRGB>::Ptr colouredPoints(const hgd::Shape& shape, const hgd::Geometry& g,
                                                      const std::string& field) {
  pcl::PointCloud<pcl::PointXYZRGB>::Ptr out(new pcl::PointCloud<pcl::PointXYZRGB>);
  out->resize(g.size());
  const int f = field.empty() ? -1 : hgd::findField(shape.cloud, field);
  const int r = hgd::findField(shape.cloud, "red"), gr = hgd::findField(shape.cloud, "green"),
            b = hgd::findField(shape.cloud, "blue");
  for (std::size_t i = 0; i < g.size(); ++i) {
    auto& p = (*out)[i];
    p.getVector3fMap() = (g.world(i)).cast<float>();
    const auto raw = static_cast<std::size_t>(g.raw_index[i]);
    Eigen::Vector3f c(0.75f, 0.75f, 0.72f);
    if (f >= 0) {
      c = colourMap(static_cast<float>(
          hgd::readValue(shape.cloud, raw, shape.cloud.fields[static_cast<std::size_t>(f)])));
    } else if (r >= 0 && gr >= 0 && b >= 0) {
      const double scale =
          shape.cloud.fields[static_cast<std::size_t>(r)].datatype == pcl::PCLPointField::UINT8 ? 255.0 : 1.0;
      c = Eigen::Vector3f(
          static_cast<float>(
              hgd::readValue(shape.cloud, raw, shape.cloud.fields[static_cast<std::size_t>(r)]) / scale),
          static_cast<float>(
              hgd::readValue(shape.cloud, raw, shape.cloud.fields[static_cast<std::size_t>(gr)]) / scale),
          static_cast<float>(
              hgd::readValue(shape.cloud, raw, shape.cloud.fields[static_cast<std::size_t>(b)]) / scale));
    }
    p.r = static_cast<std::uint8_t>(std::clamp(c.x(), 0.0f, 1.0f) * 255);
    p.g = static_cast<std::uint8_t>(std::clamp(c.y(), 0.0f, 1.0f) * 255);
    p.b = static_cast<std::uint8_t>(std::clamp(c.z(), 0.0f, 1.0f) * 255);
  }
  out->width = static_cast<std::uint32_t>(out->size());
  out->height = 1;
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> inputs, titles;
  std::string output, field;
  int width = 1200, height = 600;
  Eigen::Vector3f view(1.0f, 0.6f, 1.4f);
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      auto next = [&]() -> std::string {
        if (i + 1 >= argc) throw std::runtime_error(a + " needs a value");
        return argv[++i];
      };
      if (a == "-o" || a == "--output") {
        output = next();
      } else if (a == "--field") {
        field = next();
      } else if (a == "--title") {
        titles.push_back(next());
      } else if (a == "--size") {
        const std::string s = next();
        if (std::sscanf(s.c_str(), "%dx%d", &width, &height) != 2 || width < 16 || height < 16)
          throw std::runtime_error("--size must be WIDTHxHEIGHT");
      } else if (a == "--view") {
        const std::string s = next();
        if (std::sscanf(s.c_str(), "%f,%f,%f", &view.x(), &view.y(), &view.z()) != 3 || view.norm() == 0)
          throw std::runtime_error("--view must be x,y,z");
      } else if (a == "-h" || a == "--help") {
        std::cout
            << "usage: hgdeform-render IN [IN ...] -o OUT.png [--field NAME] [--size WxH] [--view x,y,z] "
               "[--title T ...]\n";
        return 0;
      } else if (!a.empty() && a[0] == '-') {
        throw std::runtime_error("unknown option '" + a + "'");
      } else {
        inputs.push_back(a);
      }
    }
    if (inputs.empty() || output.empty()) throw std::runtime_error("need at least one input and -o OUT.png");

    std::vector<hgd::Shape> shapes;
    std::vector<hgd::Geometry> geoms;
    for (const auto& in : inputs) {
      shapes.push_back(hgd::readShape(in));
      geoms.push_back(hgd::extractGeometry(shapes.back()));
    }
    // One camera for all: the union of the bounding boxes, seen along `view`.
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
    for (const auto& g : geoms)
      for (std::size_t i = 0; i < g.size(); ++i) {
        lo = lo.cwiseMin(g.world(i));
        hi = hi.cwiseMax(g.world(i));
      }
    const Eigen::Vector3d centre = 0.5 * (lo + hi);
    const double radius = 0.5 * (hi - lo).norm();

    pcl::visualization::PCLVisualizer viewer("hgdeform-render", false);
    viewer.setSize(width, height);
    const int n = static_cast<int>(inputs.size());
    for (int k = 0; k < n; ++k) {
      int vp = 0;
      viewer.createViewPort(static_cast<double>(k) / n, 0.0, static_cast<double>(k + 1) / n, 1.0, vp);
      viewer.setBackgroundColor(1.0, 1.0, 1.0, vp);
      const auto cloud =
          colouredPoints(shapes[static_cast<std::size_t>(k)], geoms[static_cast<std::size_t>(k)], field);
      const std::string id = "shape" + std::to_string(k);
      if (!geoms[static_cast<std::size_t>(k)].faces.empty()) {
        pcl::PolygonMesh mesh;
        pcl::toPCLPointCloud2(*cloud, mesh.cloud);
        mesh.polygons = geoms[static_cast<std::size_t>(k)].faces;
        viewer.addPolygonMesh(mesh, id, vp);
      } else {
        viewer.addPointCloud<pcl::PointXYZRGB>(cloud, id, vp);
        viewer.setPointCloudRenderingProperties(pcl::visualization::PCL_VISUALIZER_POINT_SIZE, 3, id, vp);
      }
      if (k < static_cast<int>(titles.size()))
        viewer.addText(titles[static_cast<std::size_t>(k)], 12, 12, 18, 0.1, 0.1, 0.1, id + "_title", vp);
    }
    const Eigen::Vector3d eye =
        centre + view.cast<double>().normalized() * radius * 3.3;  // 30 degree view angle
    viewer.setCameraPosition(eye.x(), eye.y(), eye.z(), centre.x(), centre.y(), centre.z(), 0, 1, 0);
    viewer.setCameraClipDistances(radius * 0.1, radius * 10);
    // No interactor (a headless render): draw and grab the window ourselves. PCL's
    // saveScreenshot goes through the interactor style, which does not exist here.
    auto window = viewer.getRenderWindow();
    window->SetSize(width, height);
    window->SetOffScreenRendering(1);
    window->Render();
    auto grab = vtkSmartPointer<vtkWindowToImageFilter>::New();
    grab->SetInput(window);
    grab->SetInputBufferTypeToRGB();
    grab->ReadFrontBufferOff();
    grab->Update();
    // Written next to the target, then renamed: never a half-written picture.
    const std::string tmp = output + ".tmp.png";
    auto writer = vtkSmartPointer<vtkPNGWriter>::New();
    writer->SetFileName(tmp.c_str());
    writer->SetInputConnection(grab->GetOutputPort());
    writer->Write();
    if (writer->GetErrorCode() != 0 || std::rename(tmp.c_str(), output.c_str()) != 0) {
      std::remove(tmp.c_str());
      throw std::runtime_error(output + ": cannot write the picture");
    }
    std::cout << "wrote " << output << "\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "hgdeform-render: " << e.what() << "\n";
    return 1;
  }
}
