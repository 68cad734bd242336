#include "hgdeform/render/render.h"

#include <pcl/conversions.h>
#include <pcl/visualization/pcl_visualizer.h>
#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkEDLShading.h>
#include <vtkFloatArray.h>
#include <vtkImageData.h>
#include <vtkLODActor.h>
#include <vtkLookupTable.h>
#include <vtkMapper.h>
#include <vtkObjectFactory.h>
#include <vtkOpenGLFramebufferObject.h>
#include <vtkOpenGLHelper.h>
#include <vtkOpenGLRenderWindow.h>
#include <vtkOpenGLShaderCache.h>
#include <vtkOpenGLState.h>
#include <vtkOverlayPass.h>
#include <vtkPNGWriter.h>
#include <vtkPointData.h>
#include <vtkPolyData.h>
#include <vtkProperty.h>
#include <vtkRenderPassCollection.h>
#include <vtkRenderState.h>
#include <vtkRenderStepsPass.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkRendererCollection.h>
#include <vtkScalarBarActor.h>
#include <vtkSequencePass.h>
#include <vtkShaderProgram.h>
#include <vtkShaderProperty.h>
#include <vtkSmartPointer.h>
#include <vtkTextProperty.h>
#include <vtkTextureObject.h>
#include <vtkUnsignedCharArray.h>
#include <vtkWindowToImageFilter.h>
#include <vtk_glew.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string_view>

#include "hgdeform/io/colormap.h"
#include "hgdeform/io/fields.h"
#include "hgdeform/io/geometry.h"
#include "hgdeform/io/io.h"

namespace hgd {

namespace {
/// The points of `g` in world coordinates, coloured by the scalar `field`, else by `displacement`
/// (per file point, scaled by `scale`: NaN grey), else by the file's colours (grey without).
pcl::PointCloud<pcl::PointXYZRGB>::Ptr colouredPoints(const hgd::Shape& shape, const hgd::Geometry& g,
                                                      const std::string& field,
                                                      const std::vector<double>* displacement, double scale) {
  pcl::PointCloud<pcl::PointXYZRGB>::Ptr out(new pcl::PointCloud<pcl::PointXYZRGB>);
  out->resize(g.size());
  const int f = field.empty() ? -1 : hgd::findField(shape.cloud, field);
  const ColourFields colours = findColourFields(shape.cloud);
  for (std::size_t i = 0; i < g.size(); ++i) {
    auto& p = (*out)[i];
    p.getVector3fMap() = (g.world(i)).cast<float>();
    const auto raw = static_cast<std::size_t>(g.raw_index[i]);
    Eigen::Vector3f c;
    if (f >= 0) {
      c = colourMap(static_cast<float>(
          hgd::readValue(shape.cloud, raw, shape.cloud.fields[static_cast<std::size_t>(f)])));
    } else if (displacement) {
      const double d = (*displacement)[raw];
      c = std::isfinite(d) ? colourMap(static_cast<float>(scale > 0 ? d / scale : 0.0))
                           : Eigen::Vector3f(0.75f, 0.75f, 0.75f);
    } else {
      c = readColour(shape.cloud, raw, colours);
    }
    p.r = static_cast<std::uint8_t>(std::clamp(c.x(), 0.0f, 1.0f) * 255);
    p.g = static_cast<std::uint8_t>(std::clamp(c.y(), 0.0f, 1.0f) * 255);
    p.b = static_cast<std::uint8_t>(std::clamp(c.z(), 0.0f, 1.0f) * 255);
  }
  out->width = static_cast<std::uint32_t>(out->size());
  out->height = 1;
  return out;
}

/// The x, y, z fields of a shape (throws naming the file when one is missing).
struct Xyz {
  const pcl::PCLPointField *x, *y, *z;
};
Xyz xyzFields(const Shape& shape) {
  const int fx = findField(shape.cloud, "x"), fy = findField(shape.cloud, "y"),
            fz = findField(shape.cloud, "z");
  if (fx < 0 || fy < 0 || fz < 0)
    throw std::runtime_error((shape.path.empty() ? std::string("a shape") : shape.path) +
                             ": no x, y, z fields");
  return {&shape.cloud.fields[static_cast<std::size_t>(fx)],
          &shape.cloud.fields[static_cast<std::size_t>(fy)],
          &shape.cloud.fields[static_cast<std::size_t>(fz)]};
}

Eigen::Vector3d pointOf(const Shape& shape, const Xyz& f, std::size_t i) {
  return {readValue(shape.cloud, i, *f.x), readValue(shape.cloud, i, *f.y), readValue(shape.cloud, i, *f.z)};
}

/// The standard deviation of the finite points of `shape` along x, y and z (from at most about
/// 200,000 of them, evenly spaced in the file); ones when it has no finite point.
Eigen::Vector3d axisSpread(const Shape& shape) {
  const Xyz f = xyzFields(shape);
  const std::size_t n = shape.size(), stride = std::max<std::size_t>(1, n / 200000);
  Eigen::Vector3d first = Eigen::Vector3d::Zero(), sum = first, sum2 = first;
  bool have_first = false;
  double count = 0;
  for (std::size_t i = 0; i < n; i += stride) {
    const Eigen::Vector3d p = pointOf(shape, f, i);
    if (!p.allFinite()) continue;
    if (!have_first) {
      first = p;  // sums relative to a point of the shape: georeferenced coordinates keep precision
      have_first = true;
    }
    const Eigen::Vector3d q = p - first;
    sum += q;
    sum2 += q.cwiseProduct(q);
    ++count;
  }
  if (count < 1) return Eigen::Vector3d::Ones();
  const Eigen::Vector3d mean = sum / count;
  return (sum2 / count - mean.cwiseProduct(mean)).cwiseMax(0.0).cwiseSqrt();
}

/// How much thinner (in standard deviation) an axis must be than another to be taken as the
/// thinner one by upAxis and the default view: near-equal spreads keep the default.
constexpr double kThinnest = 0.85;

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

/// Encodes an RGB picture in memory, then writes it by the one atomic writer as every other
/// output is: a temporary file beside the target renamed over it (a link followed), a FIFO or a
/// device written to directly, nothing left behind on failure.
void writeImagePng(vtkImageData* image, const std::string& png_path, const std::string& what) {
  auto writer = vtkSmartPointer<vtkPNGWriter>::New();
  writer->SetWriteToMemory(1);
  writer->SetInputData(image);
  writer->Write();
  vtkUnsignedCharArray* png = writer->GetResult();
  if (writer->GetErrorCode() != 0 || !png || png->GetNumberOfValues() == 0)
    throw std::runtime_error(png_path + ": cannot write the " + what + ": the PNG could not be encoded");
  writeFileAtomically(png_path, std::string_view(reinterpret_cast<const char*>(png->GetPointer(0)),
                                                 static_cast<std::size_t>(png->GetNumberOfValues())));
}

/// The default view for `up`: a three-quarter view, 1.4 along a "forward" axis, 1 along the
/// side axis (up x forward) and 0.6 up: (1, 0.6, 1.4) for +y up.
Eigen::Vector3d threeQuarter(const Eigen::Vector3d& up, const Eigen::Vector3d& forward) {
  return 1.4 * forward + up.cross(forward) + 0.6 * up;
}

/// The direction from the target to the eye when none is given. The forward axis is the one
/// the up axis turns +z onto (+z for +y up, as ever); when the up axis was chosen from the shape
/// (`auto_up`), the other side axis instead when the shape is clearly thinner along it (`spread`:
/// its standard deviations along x, y, z): the shape is seen across its broad side. With a displacement
/// (`moved`, whose points are at their deformed places, and the rest shape), of the four sides the one from
/// which the motion shows best: the most displacement across the line of sight, less for moved points on the
/// far side of the shape (they may be hidden behind it), and less for a side that shows the shape edge-on.
Eigen::Vector3d chooseView(const Eigen::Vector3f& up_axis, const Eigen::Vector3d& spread, bool auto_up,
                           const Geometry* moved, const Shape* rest, const Eigen::Vector3d& centre,
                           double radius) {
  const Eigen::Vector3d up = up_axis.cast<double>();
  Eigen::Vector3d forward = turnYOnto(up_axis) * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d side = up.cross(forward);
  const auto along = [&](const Eigen::Vector3d& axis) { return axis.cwiseAbs().dot(spread); };
  if (auto_up && along(side) < kThinnest * along(forward)) forward = side;
  if (!moved || !rest) return threeQuarter(up, forward);
  // Sampled motion: at most about 20,000 points, evenly spaced.
  const Xyz f = xyzFields(*rest);
  std::vector<Eigen::Vector3d> at, motion;
  const std::size_t stride = std::max<std::size_t>(1, moved->size() / 20000);
  for (std::size_t i = 0; i < moved->size(); i += stride) {
    const Eigen::Vector3d p = moved->world(i);
    const Eigen::Vector3d d = p - pointOf(*rest, f, static_cast<std::size_t>(moved->raw_index[i]));
    if (!d.allFinite() || d.isZero()) continue;
    at.push_back(p);
    motion.push_back(d);
  }
  if (motion.empty()) return threeQuarter(up, forward);
  const Eigen::Vector3d sideways = up.cross(forward);
  const Eigen::Vector3d candidates[4] = {forward, sideways, -forward, -sideways};
  Eigen::Vector3d best = forward;
  double best_score = -1;
  for (const Eigen::Vector3d& c : candidates) {
    const Eigen::Vector3d eye = threeQuarter(up, c).normalized();
    // The share of the shape's spread (variance along x, y, z) that lies across the line of
    // sight, cubed: a side that shows the shape edge-on (a plate seen from its rim) loses.
    const Eigen::Vector3d variance = spread.cwiseProduct(spread);
    const double across =
        variance.dot(Eigen::Vector3d::Ones() - eye.cwiseProduct(eye)) / std::max(variance.sum(), 1e-300);
    double score = 0;
    for (std::size_t i = 0; i < motion.size(); ++i) {
      // A moved point on the far side may be hidden behind the rest: counted less.
      const double far = std::clamp((at[i] - centre).dot(c) / radius, -1.0, 0.0);
      score += motion[i].cross(eye).norm() * (1.0 + 0.5 * far);
    }
    score *= across * across * across;
    // A clear gain over the sides tried before is needed to leave the default (tried first).
    if (score > (best_score < 0 ? 0.0 : 1.15 * best_score)) {
      best_score = score;
      best = c;
    }
  }
  return threeQuarter(up, best);
}

constexpr std::size_t kMarks = 120;

/// Marks the handles of `options` on `g` (drawn in viewport `vp`) as larger points: fixed black,
/// manipulated magenta. Returns whether any was drawn.
bool markHandles(pcl::visualization::PCLVisualizer& viewer, const Geometry& g, const RenderOptions& options,
                 const std::string& id, int vp) {
  pcl::PointCloud<pcl::PointXYZRGB>::Ptr marks(new pcl::PointCloud<pcl::PointXYZRGB>);
  const auto add = [&](const std::vector<int>& raw, std::uint8_t r, std::uint8_t gr, std::uint8_t b) {
    // At most about kMarks points a handle, evenly spaced in the list: the region shows, and so
    // do the colours beneath (the handle is what moved most, or least).
    const std::size_t stride = std::max<std::size_t>(1, raw.size() / kMarks);
    for (std::size_t m = 0; m < raw.size(); m += stride) {
      const int k = raw[m];
      if (k < 0 || static_cast<std::size_t>(k) >= g.finite_index.size()) continue;
      const int i = g.finite_index[static_cast<std::size_t>(k)];
      if (i < 0) continue;
      pcl::PointXYZRGB p;
      p.getVector3fMap() = g.world(static_cast<std::size_t>(i)).cast<float>();
      p.r = r;
      p.g = gr;
      p.b = b;
      marks->push_back(p);
    }
  };
  add(options.fixed_points, 15, 15, 15);
  add(options.manipulated_points, 220, 0, 220);
  if (marks->empty()) return false;
  marks->width = static_cast<std::uint32_t>(marks->size());
  marks->height = 1;
  const pcl::visualization::PointCloudColorHandlerRGBField<pcl::PointXYZRGB> rgb(marks);
  viewer.addPointCloud<pcl::PointXYZRGB>(marks, rgb, id, vp);
  viewer.setPointCloudRenderingProperties(pcl::visualization::PCL_VISUALIZER_POINT_SIZE,
                                          std::max(5, options.point_size + 3), id, vp);
  return true;
}

/// The displacement colour scale (0 to `scale`, blue to red) at the top right of viewport `vp`.
void addDisplacementBar(pcl::visualization::PCLVisualizer& viewer, double scale, int vp) {
  auto lut = vtkSmartPointer<vtkLookupTable>::New();
  lut->SetNumberOfTableValues(256);
  for (int k = 0; k < 256; ++k) {
    const Eigen::Vector3f c = colourMap(static_cast<float>(k) / 255.0f);
    lut->SetTableValue(k, c.x(), c.y(), c.z(), 1.0);
  }
  lut->SetRange(0, scale > 0 ? scale : 1);
  lut->Build();
  auto bar = vtkSmartPointer<vtkScalarBarActor>::New();
  bar->SetLookupTable(lut);
  bar->SetTitle("displacement");
  bar->SetNumberOfLabels(3);
  bar->SetLabelFormat("%.3g");
  bar->UnconstrainedFontSizeOn();
  bar->GetTitleTextProperty()->SetFontSize(13);
  bar->GetLabelTextProperty()->SetFontSize(12);
  bar->GetTitleTextProperty()->SetColor(0.1, 0.1, 0.1);
  bar->GetTitleTextProperty()->ShadowOff();
  bar->GetTitleTextProperty()->ItalicOff();
  bar->GetLabelTextProperty()->SetColor(0.1, 0.1, 0.1);
  bar->GetLabelTextProperty()->ShadowOff();
  bar->GetLabelTextProperty()->ItalicOff();
  bar->SetOrientationToHorizontal();         // across the top right, beside the handles' legend
  bar->SetTextPositionToSucceedScalarBar();  // the labels below the bar, the title above
  bar->SetWidth(0.4);
  bar->SetHeight(0.13);
  bar->SetPosition(0.57, 0.85);
  vtkRenderer::SafeDownCast(viewer.getRendererCollection()->GetItemAsObject(vp))->AddActor2D(bar);
}

}  // namespace

std::vector<double> displacementFrom(const Shape& rest, const Shape& shape) {
  const std::string rest_name = rest.path.empty() ? std::string("the rest shape") : rest.path;
  const std::string name = shape.path.empty() ? std::string("the shape") : shape.path;
  if (rest.size() != shape.size())
    throw std::runtime_error(rest_name + ": the rest shape has " + std::to_string(rest.size()) +
                             " points but " + name + " has " + std::to_string(shape.size()) +
                             ": a displacement needs the same points in the same order");
  const Xyz fr = xyzFields(rest), fs = xyzFields(shape);
  std::vector<double> d(shape.size());
  for (std::size_t i = 0; i < d.size(); ++i) {
    const double v = (pointOf(shape, fs, i) - pointOf(rest, fr, i)).norm();
    d[i] = std::isfinite(v) ? v : NAN;
  }
  return d;
}

Eigen::Vector3d defaultView(const Shape& shape, const std::string& up) {
  return chooseView(upAxis(up, {&shape}), axisSpread(shape), up == "auto", nullptr, nullptr,
                    Eigen::Vector3d::Zero(), 1.0);
}

bool inSensorCone(const Shape& shape) {
  // Every point ahead of the sensor, inside a cone wider than any depth camera's field of view
  // (tan 60 degrees): a depth image's valid pixels, a stereo cloud. A model centred on the
  // origin, or standing on z = 0, is not.
  // A mesh is a model, not a sensor's points. At most about 200,000 points are looked at, evenly
  // spaced in the file.
  if (!shape.polygons.empty()) return false;
  const Xyz f = xyzFields(shape);
  const std::size_t n = shape.size(), stride = std::max<std::size_t>(1, n / 200000);
  constexpr double kTan60 = 1.7320508;
  std::size_t finite = 0;
  for (std::size_t i = 0; i < n; i += stride) {
    const Eigen::Vector3d p = pointOf(shape, f, i);
    if (!p.allFinite()) continue;
    if (!(p.z() > 0) || std::hypot(p.x(), p.y()) > kTan60 * p.z()) return false;
    ++finite;
  }
  return finite > 0;
}

bool isCameraFrame(const Shape& shape) {
  const bool posed =
      shape.format == FileFormat::Pcd && (!shape.sensor_origin.head<3>().isZero() ||
                                          !shape.sensor_orientation.isApprox(Eigen::Quaternionf::Identity()));
  return shape.isOrganized() || posed || inSensorCone(shape);
}

Eigen::Vector3f upAxis(const std::string& up, const std::vector<const Shape*>& shapes) {
  if (up == "auto") {
    const Shape* s = shapes.empty() ? nullptr : shapes.front();
    if (!s) return Eigen::Vector3f::UnitY();
    if (isCameraFrame(*s)) return -Eigen::Vector3f::UnitY();
    // A z-up model (a horse, a statue, a car: the convention of scanners and CAD) is thinnest
    // along y, the axis a y-up picture would look down: take z up when y is clearly the thinnest
    // (a margin, so that near-equal spreads keep +y and similar files do not flip).
    const Eigen::Vector3d spread = axisSpread(*s);
    if (spread.y() < kThinnest * std::min(spread.x(), spread.z())) return Eigen::Vector3f::UnitZ();
    return Eigen::Vector3f::UnitY();
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
  const std::size_t n = shapes.size();
  std::vector<Geometry> geoms;
  for (const Shape* s : shapes) geoms.push_back(extractGeometry(*s));
  // Displacements (per file point) of the inputs coloured by them, one scale for all.
  std::vector<std::vector<double>> displacement(n);
  double scale = 0;
  int moved = -1;  // the last input coloured by displacement: its motion chooses the view
  if (options.displacement_rest && options.field.empty())
    for (std::size_t k = 0; k < n; ++k) {
      if (shapes[k] == options.displacement_rest) continue;  // the rest itself: its own colours
      displacement[k] = displacementFrom(*options.displacement_rest, *shapes[k]);
      for (const double d : displacement[k])
        if (std::isfinite(d)) scale = std::max(scale, d);
      moved = static_cast<int>(k);
    }
  // One camera for all: the union of the bounding boxes, seen along `view`.
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  for (const auto& g : geoms)
    for (std::size_t i = 0; i < g.size(); ++i) {
      lo = lo.cwiseMin(g.world(i));
      hi = hi.cwiseMax(g.world(i));
    }
  const Eigen::Vector3d centre = 0.5 * (lo + hi);
  const double radius = std::max(0.5 * (hi - lo).norm(), 1e-9);
  const Eigen::Vector3d view =
      options.view ? Eigen::Vector3d(options.view->cast<double>())
                   : chooseView(up, axisSpread(*shapes.front()), options.up == "auto",
                                moved >= 0 ? &geoms[static_cast<std::size_t>(moved)] : nullptr,
                                moved >= 0 ? options.displacement_rest : nullptr, centre, radius);
  const int width = options.width, height = options.height;

  pcl::visualization::PCLVisualizer viewer("hgdeform", false);
  viewer.setSize(width, height);
  for (std::size_t k = 0; k < n; ++k) {
    int vp = 0;
    viewer.createViewPort(static_cast<double>(k) / static_cast<double>(n), 0.0,
                          static_cast<double>(k + 1) / static_cast<double>(n), 1.0, vp);
    viewer.setBackgroundColor(1.0, 1.0, 1.0, vp);
    const auto& g = geoms[k];
    const bool by_displacement = !displacement[k].empty();
    const auto cloud =
        colouredPoints(*shapes[k], g, options.field, by_displacement ? &displacement[k] : nullptr, scale);
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
      const bool file_colours =
          options.field.empty() && !by_displacement && findColourFields(shapes[k]->cloud).any();
      shadeCloud(viewer, id, g, file_colours, nullptr, vp);
    }
    const bool last = k + 1 == n;
    if (markHandles(viewer, g, options, id + "_handles", vp) && last) {
      viewer.addText("fixed handle", 12, height - 22, 13, 0.05, 0.05, 0.05, id + "_fixed_legend", vp);
      viewer.addText("moved handle", 12, height - 40, 13, 0.85, 0.0, 0.85, id + "_moved_legend", vp);
    }
    if (static_cast<int>(k) == moved) addDisplacementBar(viewer, scale, vp);
    if (k < options.titles.size())
      viewer.addText(options.titles[k], 12, 12, 18, 0.1, 0.1, 0.1, id + "_title", vp);
  }
  // 30 degree view angle: the bounding sphere fills the height, with a margin at the top for
  // the displacement scale and the handles' legend when they are drawn.
  const bool legends = moved >= 0 || !options.fixed_points.empty() || !options.manipulated_points.empty();
  const Eigen::Vector3d eye = centre + view.normalized() * radius * (legends ? 3.8 : 3.3);
  viewer.setCameraPosition(eye.x(), eye.y(), eye.z(), centre.x(), centre.y(), centre.z(), up.x(), up.y(),
                           up.z());
  viewer.setCameraClipDistances(radius * 0.1, radius * 10);
  // No interactor (a headless render): draw and grab the window ourselves. PCL's
  // saveScreenshot goes through the interactor style, which does not exist here.
  auto window = viewer.getRenderWindow();
  window->SetSize(width, height);
  window->SetOffScreenRendering(1);
  // One viewport at a time (the eye-dome pass clears the whole window when it composes), each
  // copied into its columns of the picture.
  vtkRendererCollection* renderers = viewer.getRendererCollection();
  auto picture = vtkSmartPointer<vtkImageData>::New();
  picture->SetDimensions(width, height, 1);
  picture->AllocateScalars(VTK_UNSIGNED_CHAR, 3);
  auto* out = static_cast<unsigned char*>(picture->GetScalarPointer());
  std::fill(out, out + std::size_t{3} * static_cast<std::size_t>(width) * static_cast<std::size_t>(height),
            static_cast<unsigned char>(255));
  for (int k = 1; k <= static_cast<int>(n); ++k) {
    for (int j = 0; j < renderers->GetNumberOfItems(); ++j)
      vtkRenderer::SafeDownCast(renderers->GetItemAsObject(j))->SetDraw(j == k);
    window->Render();
    auto grab = vtkSmartPointer<vtkWindowToImageFilter>::New();
    grab->SetInput(window);
    grab->SetInputBufferTypeToRGB();
    grab->ReadFrontBufferOff();
    grab->ShouldRerenderOff();
    grab->Update();
    vtkImageData* shot = grab->GetOutput();
    int dims[3];
    shot->GetDimensions(dims);
    if (dims[0] != width || dims[1] != height)
      throw std::runtime_error(png_path + ": cannot render: the window drew " + std::to_string(dims[0]) +
                               "x" + std::to_string(dims[1]) + " pixels");
    vtkRenderer* r = vtkRenderer::SafeDownCast(renderers->GetItemAsObject(k));
    const int* origin = r->GetOrigin();
    const int* size = r->GetSize();
    const int x0 = std::clamp(origin[0], 0, width), x1 = std::clamp(origin[0] + size[0], 0, width);
    const auto* in = static_cast<const unsigned char*>(shot->GetScalarPointer());
    for (int y = 0; y < height; ++y) {
      const std::size_t row = static_cast<std::size_t>(y) * static_cast<std::size_t>(width);
      std::copy(in + 3 * (row + static_cast<std::size_t>(x0)), in + 3 * (row + static_cast<std::size_t>(x1)),
                out + 3 * (row + static_cast<std::size_t>(x0)));
    }
  }
  writeImagePng(picture, png_path, "picture");
}

void writeWindowPng(vtkRenderWindow* window, const std::string& png_path,
                    const std::vector<std::string>& inputs, const std::string& what) {
  refuseInputs(png_path, inputs);
  auto grab = vtkSmartPointer<vtkWindowToImageFilter>::New();
  grab->SetInput(window);
  grab->SetInputBufferTypeToRGB();
  grab->ReadFrontBufferOff();
  grab->Update();
  writeImagePng(grab->GetOutput(), png_path, what);
}

}  // namespace hgd
