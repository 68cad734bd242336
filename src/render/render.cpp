#include "hgdeform/render.h"

#include <pcl/conversions.h>
#include <pcl/visualization/pcl_visualizer.h>
#include <vtkPNGWriter.h>
#include <vtkRenderWindow.h>
#include <vtkSmartPointer.h>
#include <vtkUnsignedCharArray.h>
#include <vtkWindowToImageFilter.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string_view>

#include "hgdeform/colormap.h"
#include "hgdeform/fields.h"
#include "hgdeform/geometry.h"
#include "hgdeform/io.h"

namespace hgd {

namespace {
pcl::PointCloud<pcl::PointXYZRGB>::Ptr colouredPoints(const hgd::Shape& shape, const hgd::Geometry& g,
                                                      const std::string& field) {
  pcl::PointCloud<pcl::PointXYZRGB>::Ptr out(new pcl::PointCloud<pcl::PointXYZRGB>);
  out->resize(g.size());
  const int f = field.empty() ? -1 : hgd::findField(shape.cloud, field);
  const ColourFields colours = findColourFields(shape.cloud);
  for (std::size_t i = 0; i < g.size(); ++i) {
    auto& p = (*out)[i];
    p.getVector3fMap() = (g.world(i)).cast<float>();
    const auto raw = static_cast<std::size_t>(g.raw_index[i]);
    const Eigen::Vector3f c = f >= 0
                                  ? colourMap(static_cast<float>(hgd::readValue(
                                        shape.cloud, raw, shape.cloud.fields[static_cast<std::size_t>(f)])))
                                  : readColour(shape.cloud, raw, colours);
    p.r = static_cast<std::uint8_t>(std::clamp(c.x(), 0.0f, 1.0f) * 255);
    p.g = static_cast<std::uint8_t>(std::clamp(c.y(), 0.0f, 1.0f) * 255);
    p.b = static_cast<std::uint8_t>(std::clamp(c.z(), 0.0f, 1.0f) * 255);
  }
  out->width = static_cast<std::uint32_t>(out->size());
  out->height = 1;
  return out;
}

/// The rotation that takes +y onto the unit axis `up` (one of the six), turning the default
/// view with it.
Eigen::Matrix3d turnYOnto(const Eigen::Vector3f& up) {
  Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
  if (up.x() > 0.5f) r << 0, 1, 0, -1, 0, 0, 0, 0, 1;
  if (up.x() < -0.5f) r << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  if (up.y() < -0.5f) r << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  if (up.z() > 0.5f) r << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  if (up.z() < -0.5f) r << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  return r;
}

}  // namespace

Eigen::Vector3f upAxis(const std::string& up, const std::vector<const Shape*>& shapes) {
  if (up == "auto") {
    const Shape* s = shapes.empty() ? nullptr : shapes.front();
    const bool posed = s && s->format == FileFormat::Pcd &&
                       (!s->sensor_origin.head<3>().isZero() ||
                        !s->sensor_orientation.isApprox(Eigen::Quaternionf::Identity()));
    return s && (s->isOrganized() || posed) ? Eigen::Vector3f(-Eigen::Vector3f::UnitY())
                                            : Eigen::Vector3f(Eigen::Vector3f::UnitY());
  }
  const bool minus = !up.empty() && up[0] == '-';
  const std::string axis = minus ? up.substr(1) : up;
  Eigen::Vector3f v;
  if (axis == "x") {
    v = Eigen::Vector3f::UnitX();
  } else if (axis == "y") {
    v = Eigen::Vector3f::UnitY();
  } else if (axis == "z") {
    v = Eigen::Vector3f::UnitZ();
  } else {
    throw std::invalid_argument("the up axis must be x, y, z, -x, -y, -z or auto, not '" + up + "'");
  }
  return minus ? Eigen::Vector3f(-v) : v;
}

std::string pictureSizeProblem(int width, int height) {
  const std::string size = std::to_string(width) + "x" + std::to_string(height);
  if (width < 1 || height < 1 || width > kMaxPictureSide || height > kMaxPictureSide)
    return "cannot render a " + size + " picture: each side must be from 1 to " +
           std::to_string(kMaxPictureSide) + " pixels (what OpenGL draws)";
  const std::size_t bytes =
      std::size_t{32} * static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  void* probe = std::malloc(bytes);  // given back at once: only whether the memory is there
  if (!probe) {
    char need[32];
    std::snprintf(need, sizeof need, "%.1f GB", static_cast<double>(bytes) / 1e9);
    return "cannot render a " + size + " picture: its buffers need about " + need +
           " of memory, more than this process can allocate (ulimit -v?)";
  }
  std::free(probe);
  return {};
}

void renderPng(const std::vector<const Shape*>& shapes, const std::string& png_path,
               const RenderOptions& options) {
  if (shapes.empty()) throw std::runtime_error(png_path + ": nothing to render");
  if (const std::string problem = pictureSizeProblem(options.width, options.height); !problem.empty())
    throw std::runtime_error(png_path + ": " + problem);
  const Eigen::Vector3f up = upAxis(options.up, shapes);
  const Eigen::Vector3d view = options.view ? Eigen::Vector3d(options.view->cast<double>())
                                            : Eigen::Vector3d(turnYOnto(up) * Eigen::Vector3d(1.0, 0.6, 1.4));
  std::vector<Geometry> geoms;
  for (const Shape* s : shapes) geoms.push_back(extractGeometry(*s));
  // One camera for all: the union of the bounding boxes, seen along `view`.
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  for (const auto& g : geoms)
    for (std::size_t i = 0; i < g.size(); ++i) {
      lo = lo.cwiseMin(g.world(i));
      hi = hi.cwiseMax(g.world(i));
    }
  const Eigen::Vector3d centre = 0.5 * (lo + hi);
  const double radius = std::max(0.5 * (hi - lo).norm(), 1e-9);
  const int width = options.width, height = options.height;

  pcl::visualization::PCLVisualizer viewer("hgdeform", false);
  viewer.setSize(width, height);
  const int n = static_cast<int>(shapes.size());
  for (int k = 0; k < n; ++k) {
    int vp = 0;
    viewer.createViewPort(static_cast<double>(k) / n, 0.0, static_cast<double>(k + 1) / n, 1.0, vp);
    viewer.setBackgroundColor(1.0, 1.0, 1.0, vp);
    const auto& g = geoms[static_cast<std::size_t>(k)];
    const auto cloud = colouredPoints(*shapes[static_cast<std::size_t>(k)], g, options.field);
    const std::string id = "shape" + std::to_string(k);
    if (!g.faces.empty()) {
      pcl::PolygonMesh mesh;
      pcl::toPCLPointCloud2(*cloud, mesh.cloud);
      mesh.polygons = g.faces;
      viewer.addPolygonMesh(mesh, id, vp);
    } else {
      viewer.addPointCloud<pcl::PointXYZRGB>(cloud, id, vp);
      viewer.setPointCloudRenderingProperties(pcl::visualization::PCL_VISUALIZER_POINT_SIZE,
                                              options.point_size, id, vp);
    }
    if (k < static_cast<int>(options.titles.size()))
      viewer.addText(options.titles[static_cast<std::size_t>(k)], 12, 12, 18, 0.1, 0.1, 0.1, id + "_title",
                     vp);
  }
  const Eigen::Vector3d eye = centre + view.normalized() * radius * 3.3;  // 30 degree view angle
  viewer.setCameraPosition(eye.x(), eye.y(), eye.z(), centre.x(), centre.y(), centre.z(), up.x(), up.y(),
                           up.z());
  viewer.setCameraClipDistances(radius * 0.1, radius * 10);
  // No interactor (a headless render): draw and grab the window ourselves. PCL's
  // saveScreenshot goes through the interactor style, which does not exist here.
  auto window = viewer.getRenderWindow();
  window->SetSize(width, height);
  window->SetOffScreenRendering(1);
  window->Render();
  writeWindowPng(window, png_path);
}

void writeWindowPng(vtkRenderWindow* window, const std::string& png_path,
                    const std::vector<std::string>& inputs, const std::string& what) {
  refuseInputs(png_path, inputs);
  auto grab = vtkSmartPointer<vtkWindowToImageFilter>::New();
  grab->SetInput(window);
  grab->SetInputBufferTypeToRGB();
  grab->ReadFrontBufferOff();
  grab->Update();
  // Encoded in memory, then written by the one atomic writer as every other output is: a
  // temporary file beside the target renamed over it (a link followed), a FIFO or a device
  // written to directly, nothing left behind on failure.
  auto writer = vtkSmartPointer<vtkPNGWriter>::New();
  writer->SetWriteToMemory(1);
  writer->SetInputConnection(grab->GetOutputPort());
  writer->Write();
  vtkUnsignedCharArray* png = writer->GetResult();
  if (writer->GetErrorCode() != 0 || !png || png->GetNumberOfValues() == 0)
    throw std::runtime_error(png_path + ": cannot write the " + what + ": the PNG could not be encoded");
  writeFileAtomically(png_path, std::string_view(reinterpret_cast<const char*>(png->GetPointer(0)),
                                                 static_cast<std::size_t>(png->GetNumberOfValues())));
}

}  // namespace hgd
