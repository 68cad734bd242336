// The viewer's window: opening it, and drawing the shape in its colours (file, field, clusters,
// handle roles, selection), shaded or not, and at its level of detail. (The camera's views:
// viewer_camera.cpp; the lasso, the axes, the rest-shape overlay and the status line:
// viewer_overlays.cpp.)
#include <pcl/conversions.h>
#include <vtkActor.h>
#include <vtkAxesActor.h>
#include <vtkCallbackCommand.h>
#include <vtkCamera.h>
#include <vtkCaptionActor2D.h>
#include <vtkCellArray.h>
#include <vtkFloatArray.h>
#include <vtkLODActor.h>
#include <vtkLookupTable.h>
#include <vtkMapper.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper2D.h>
#include <vtkProperty.h>
#include <vtkProperty2D.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkRendererCollection.h>
#include <vtkTextProperty.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>
#include <vector>

#include "hgdeform/io/colormap.h"
#include "hgdeform/io/fields.h"
#include "hgdeform/render/render.h"
#include "viewer.h"

namespace hgdview {

namespace {
const Eigen::Vector3f kRole[4] = {
    {0, 0, 0}, {0.15f, 0.35f, 0.95f}, {0.95f, 0.15f, 0.1f}, {0.2f, 0.75f, 0.2f}};
}  // namespace

void Viewer::open() {
  opening_ = true;
  style_ = vtkSmartPointer<Style>::Take(Style::New());
  style_->viewer = this;
  int argc = 0;
  vis_ =
      std::make_unique<pcl::visualization::PCLVisualizer>(argc, nullptr, "hgdeform-view", style_.Get(), true);
  vis_->setSize(width_, height_);
  // The window's title names the file, as every desktop viewer's does.
  const std::string& path = run_.shape().path;
  const std::size_t slash = path.find_last_of('/');
  if (!path.empty())
    vis_->setWindowName(path.substr(slash == std::string::npos ? 0 : slash + 1) + " - hgdeform-view");
  vis_->setBackgroundColor(1, 1, 1);
  vtkMapper::SetResolveCoincidentTopologyToPolygonOffset();  // the handles' marks lie over the shape
  fillDisplay();
  // A cloud larger than the level of detail opens drawn at it (its first frame comes sooner):
  // the whole cloud is handed to VTK by drawWhole(), on the spin loop's first turn.
  opened_at_lod_ = run_.geometry().faces.empty() && lod_points_ > 0 &&
                   run_.geometry().size() > static_cast<std::size_t>(lod_points_);
  if (run_.geometry().faces.empty()) {
    if (!opened_at_lod_) addShapeCloud();
  } else {
    pcl::PolygonMesh mesh;
    pcl::toPCLPointCloud2(*display_, mesh.cloud);
    mesh.polygons = run_.geometry().faces;
    vis_->addPolygonMesh(mesh, "shape");
  }
  // The overlays: help at the window's top, the mode and the status line at its bottom, placed
  // again before every render (placeOverlays), so that they follow the window's size.
  auto text = [this](bool top, bool bold) {
    auto a = vtkSmartPointer<vtkTextActor>::New();
    vtkTextProperty* p = a->GetTextProperty();
    p->SetFontSize(13);
    p->SetColor(0.1, 0.1, 0.1);
    p->SetBold(bold);
    p->SetVerticalJustification(top ? VTK_TEXT_TOP : VTK_TEXT_BOTTOM);
    renderer()->AddActor2D(a);
    return a;
  };
  help_ = text(true, false);
  // Monospaced: in the proportional font [ ] read as ( ).
  help_->GetTextProperty()->SetFontFamilyToCourier();
  help_->SetInput(helpOverlay().c_str());
  status_ = text(false, false);
  mode_label_ = text(false, true);
  help_visible_ = true;
  showAxes(true);
  auto place = vtkSmartPointer<vtkCallbackCommand>::New();
  place->SetClientData(this);
  place->SetCallback(
      [](vtkObject*, unsigned long, void* self, void*) { static_cast<Viewer*>(self)->placeOverlays(); });
  vis_->getRenderWindow()->AddObserver(vtkCommand::StartEvent, place);
  // The field's colour scale, shown in field view.
  auto lut = vtkSmartPointer<vtkLookupTable>::New();
  lut->SetNumberOfTableValues(256);
  for (int k = 0; k < 256; ++k) {
    const Eigen::Vector3f c = hgd::colourMap(static_cast<float>(k) / 255.0f);
    lut->SetTableValue(k, c.x(), c.y(), c.z(), 1.0);
  }
  lut->SetRange(0, 1);
  lut->Build();
  scale_bar_ = vtkSmartPointer<vtkScalarBarActor>::New();
  scale_bar_->SetLookupTable(lut);
  scale_bar_->SetTitle("harmonic");
  scale_bar_->SetNumberOfLabels(3);
  scale_bar_->GetTitleTextProperty()->SetColor(0.1, 0.1, 0.1);
  scale_bar_->GetLabelTextProperty()->SetColor(0.1, 0.1, 0.1);
  scale_bar_->SetWidth(0.08);
  scale_bar_->SetHeight(0.45);
  scale_bar_->SetPosition(0.9, 0.3);
  scale_bar_->SetVisibility(false);
  renderer()->AddActor2D(scale_bar_);
  vis_->resetCamera();
  openingView();
  opening_ = false;
  if (opened_at_lod_) {
    showLod(true);  // (display_ is filled: the subset is copied from it)
    render();       // handles' marks, the rest: with the whole cloud (drawWhole)
    return;
  }
  refresh();
}

void Viewer::addShapeCloud() {
  const pcl::visualization::PointCloudColorHandlerRGBField<pcl::PointXYZRGB> rgb(display_);
  vis_->addPointCloud<pcl::PointXYZRGB>(display_, rgb, "shape");
  vis_->setPointCloudRenderingProperties(pcl::visualization::PCL_VISUALIZER_POINT_SIZE, shapePointSize(),
                                         "shape");
  // Lit by its normals, else eye-dome lighting; file colours as they are.
  shade("shape", nullptr);
}

// The opening view, and `r`'s: the whole shape as it is now (deformed: `r` finds a shape dragged
// off the window), upright by hgdeform-render's rule (hgd::upAxis "auto": a camera-frame scan,
// organized, a PCD with a sensor pose or every point ahead of the origin, has -y up and is seen
// from the sensor's side, +x to the right; a shape clearly thinnest along y (a z-up statue, a
// horse) has +z up; anything else +y up), in the renderer's three-quarter view across the
// shape's broad side (a plane seen straight down was a flat square). Never along the up axis: a
// camera looking along its up vector is degenerate (a z-up statue opened as an empty window).
void Viewer::setShading(bool on) {
  shading_ = on;
  const bool file_colours = hgd::findColourFields(run_.shape().cloud).any();
  if (!run_.geometry().faces.empty()) {
    setMeshLighting(on);
  } else {
    const bool normals = ready() && run_.geometry().hasFileNormals();
    shade("shape", normals ? &run_.deformer().deformedNormals() : nullptr);
  }
  message(on ? (file_colours && run_.geometry().faces.empty()
                    ? "shading on (file colours are drawn as they are)"
                    : "shading on")
             : "shading off: the colours as they are");
}

// Every cloud the viewer shades goes through here: lit by `normals` (or the file's), or with
// eye-dome lighting; with shading off (`i`), neither, whatever redraws it.
void Viewer::shade(const std::string& id, const std::vector<Eigen::Vector3f>* normals) {
  if (shading_) {
    hgd::shadeCloud(*vis_, id, run_.geometry(), hgd::findColourFields(run_.shape().cloud).any(), normals);
    return;
  }
  renderer()->SetPass(nullptr);  // no eye-dome pass
  auto it = vis_->getCloudActorMap()->find(id);
  // Unlit by the light's own terms (all ambient), not LightingOff: without lighting VTK's shader
  // has no normal, and shadeCloud's two-sided normal code would not compile (a crash).
  if (it != vis_->getCloudActorMap()->end() && it->second.actor) {
    vtkProperty* p = it->second.actor->GetProperty();
    p->SetAmbient(1.0);
    p->SetDiffuse(0.0);
    p->SetSpecular(0.0);
  }
}

void Viewer::setMeshLighting(bool on) {
  auto it = vis_->getShapeActorMap()->find("shape");
  vtkActor* actor = it != vis_->getShapeActorMap()->end() ? vtkActor::SafeDownCast(it->second) : nullptr;
  if (actor) actor->GetProperty()->SetLighting(on);
}

void Viewer::drawWhole() {
  if (!opened_at_lod_) return;
  opened_at_lod_ = false;  // the opening frame was drawn at the level of detail: now whole
  addShapeCloud();         // (display_ was filled by open())
  showLod(false);
  drawHandles(kRole, view_ == 1 && ready());
  render();
}

void Viewer::spin() {
  async_builds_ = true;
  drawWhole();
  while (!vis_->wasStopped() && !quit_) {
    vis_->spinOnce(30);
    pollBuild();
  }
  waitForBuild();
}

void Viewer::screenshot(const std::string& path) {
  render();
  hgd::writeWindowPng(vis_->getRenderWindow(), path, inputs_, "screenshot");
  message("screenshot " + path);
}

void Viewer::fileColours() {
  const hgd::ColourFields fields = hgd::findColourFields(run_.shape().cloud);
  colours_.resize(run_.geometry().size());
  for (std::size_t i = 0; i < run_.geometry().size(); ++i)
    colours_[i] =
        hgd::readColour(run_.shape().cloud, static_cast<std::size_t>(run_.geometry().raw_index[i]), fields);
}

void Viewer::refreshRoles() {
  std::fill(role_.begin(), role_.end(), 0);
  for (const auto& f : handles_.fixed)
    for (int i : f) role_[static_cast<std::size_t>(i)] = 1;
  for (int i : handles_.manipulated) role_[static_cast<std::size_t>(i)] = 2;
  for (const auto& jt : handles_.joints)
    for (int i : jt) role_[static_cast<std::size_t>(i)] = 3;
}

// The drawn points: deformed positions, and colours by the view, the roles and the selection.
void Viewer::fillDisplay() {
  const bool field_view = view_ == 1 && ready();
  const bool cluster_view = view_ == 2 && ready();
  const long long n = static_cast<long long>(run_.geometry().size());
#pragma omp parallel for schedule(static)
  for (long long k = 0; k < n; ++k) {
    const std::size_t i = static_cast<std::size_t>(k);
    auto& p = (*display_)[i];
    p.getVector3fMap() = deformed(i).cast<float>();
    Eigen::Vector3f c = colours_[i];
    if (field_view) c = hgd::colourMap(run_.deformer().field()[i]);
    if (cluster_view) c = clusterColour(run_.deformer().interpolationTable().bracket(i).nearest());
    if (!field_view && role_[i] != 0) c = 0.35f * c + 0.65f * kRole[static_cast<int>(role_[i])];
    if (selected_[i]) c = Eigen::Vector3f(1.0f, 0.85f, 0.1f);
    p.r = static_cast<std::uint8_t>(std::clamp(c.x(), 0.0f, 1.0f) * 255);
    p.g = static_cast<std::uint8_t>(std::clamp(c.y(), 0.0f, 1.0f) * 255);
    p.b = static_cast<std::uint8_t>(std::clamp(c.z(), 0.0f, 1.0f) * 255);
  }
}

void Viewer::refresh() {
  if (!vis_) return;
  const bool field_view = view_ == 1 && ready();
  fillDisplay();
  drawHandles(kRole, field_view);
  if (run_.geometry().faces.empty()) {
    // With an explicit colour handler: PCL's plain update paints the cloud white.
    const pcl::visualization::PointCloudColorHandlerRGBField<pcl::PointXYZRGB> rgb(display_);
    vis_->updatePointCloud<pcl::PointXYZRGB>(display_, rgb, "shape");
    if (ready() && run_.geometry().hasFileNormals())  // lit by the deformed normals
      shade("shape", &run_.deformer().deformedNormals());
  } else {
    // PCL's updatePolygonMesh drops the colours (the mesh turns black): add it afresh.
    pcl::PolygonMesh mesh;
    pcl::toPCLPointCloud2(*display_, mesh.cloud);
    mesh.polygons = run_.geometry().faces;
    vis_->removePolygonMesh("shape");
    vis_->addPolygonMesh(mesh, "shape");
    if (!shading_) setMeshLighting(false);
  }
  // The rest shape: a mesh as a grey wireframe (its points alone were faint dots), a cloud as
  // translucent grey points.
  const bool mesh = !run_.geometry().faces.empty();
  if (overlay_ && !overlay_shown_) {
    if (mesh) {
      pcl::PolygonMesh rest;
      pcl::toPCLPointCloud2(*rest_, rest.cloud);
      rest.polygons = run_.geometry().faces;
      vis_->addPolygonMesh(rest, "rest");
      // (PCL keeps a mesh's actor among the clouds.)
      auto it = vis_->getCloudActorMap()->find("rest");
      if (it != vis_->getCloudActorMap()->end() && it->second.actor) {
        vtkActor* a = it->second.actor;
        a->GetMapper()->ScalarVisibilityOff();
        a->GetProperty()->SetRepresentationToWireframe();
        a->GetProperty()->SetColor(0.3, 0.3, 0.38);
        a->GetProperty()->SetOpacity(0.55);
        a->GetProperty()->SetLighting(false);
      }
    } else {
      const pcl::visualization::PointCloudColorHandlerRGBField<pcl::PointXYZRGB> grey(rest_);
      vis_->addPointCloud<pcl::PointXYZRGB>(rest_, grey, "rest");
      vis_->setPointCloudRenderingProperties(pcl::visualization::PCL_VISUALIZER_OPACITY, 0.35, "rest");
    }
    overlay_shown_ = true;
  } else if (!overlay_ && overlay_shown_) {
    if (mesh)
      vis_->removePolygonMesh("rest");
    else
      vis_->removePointCloud("rest");
    overlay_shown_ = false;
  }
  scale_bar_->SetVisibility(field_view);
  render();
}

// Handles and the selection stand out on any colours: drawn again over the shape as larger
// points in their pure colours (blue fixed, red manipulated, green joints, yellow selected),
// each on a dark halo, both pulled towards the eye so that the shape's own points do not
// cover them.
void Viewer::drawHandles(const Eigen::Vector3f* role_colours, bool field_view) {
  handle_points_.clear();
  std::size_t marked = 0;
  for (std::size_t i = 0; i < role_.size(); ++i) marked += selected_[i] || (role_[i] != 0 && !field_view);
  // At most kMaxMarks marks (an even subset of a larger handle): big points cost fill rate,
  // and a handle of a million points is seen without marking each.
  constexpr std::size_t kMaxMarks = 4000;
  const std::size_t stride = std::max<std::size_t>(1, (marked + kMaxMarks - 1) / kMaxMarks);
  std::size_t seen = 0;
  for (std::size_t i = 0; i < role_.size(); ++i)
    if ((selected_[i] || (role_[i] != 0 && !field_view)) && seen++ % stride == 0)
      handle_points_.push_back(static_cast<int>(i));
  for (const char* id : {"handles", "halo"})
    if (vis_->getCloudActorMap()->count(id)) vis_->removePointCloud(id);
  if (handle_points_.empty()) return;
  auto marks = pcl::make_shared<pcl::PointCloud<pcl::PointXYZRGB>>();
  auto halo = pcl::make_shared<pcl::PointCloud<pcl::PointXYZRGB>>();
  marks->reserve(handle_points_.size());
  for (const int i : handle_points_) {
    const std::size_t u = static_cast<std::size_t>(i);
    pcl::PointXYZRGB p = (*display_)[u];
    const Eigen::Vector3f c =
        selected_[u] ? Eigen::Vector3f(1.0f, 0.85f, 0.1f) : role_colours[static_cast<int>(role_[u])];
    p.r = static_cast<std::uint8_t>(c.x() * 255);
    p.g = static_cast<std::uint8_t>(c.y() * 255);
    p.b = static_cast<std::uint8_t>(c.z() * 255);
    marks->push_back(p);
    p.r = p.g = p.b = 25;
    halo->push_back(p);
  }
  const double size = run_.geometry().faces.empty() ? shapePointSize() : 3;
  const pcl::visualization::PointCloudColorHandlerRGBField<pcl::PointXYZRGB> halo_rgb(halo), marks_rgb(marks);
  vis_->addPointCloud<pcl::PointXYZRGB>(halo, halo_rgb, "halo");
  vis_->addPointCloud<pcl::PointXYZRGB>(marks, marks_rgb, "handles");
  vis_->setPointCloudRenderingProperties(pcl::visualization::PCL_VISUALIZER_POINT_SIZE, size + 4, "halo");
  vis_->setPointCloudRenderingProperties(pcl::visualization::PCL_VISUALIZER_POINT_SIZE, size + 2, "handles");
  auto* clouds = vis_->getCloudActorMap().get();
  for (const auto& [id, offset] : {std::pair<const char*, double>{"halo", -2.0}, {"handles", -4.0}}) {
    auto it = clouds->find(id);
    if (it != clouds->end() && it->second.actor && it->second.actor->GetMapper())
      it->second.actor->GetMapper()->SetRelativeCoincidentTopologyPointOffsetParameter(offset);
  }
}

double Viewer::shapePointSize() const {
  // Big points cost fill rate under software GL: dense clouds need no more than one pixel.
  return run_.geometry().size() > 200000 ? 1 : run_.geometry().size() > 50000 ? 2 : 3;
}

// Level of detail: a point cloud larger than --lod points is drawn, while a drag lasts, as
// an even subset of that many (every k-th point: scans arrive in no particular order, and
// organised ones are sampled evenly), without anti-aliasing, and only those points (and the
// handle's) are interpolated in the live frames (ScenarioRunner::liveDrag). On release the
// whole cloud is drawn again, with the committed move interpolated to every point. Meshes
// are always drawn whole.
void Viewer::showLod(bool on) {
  const std::size_t n = run_.geometry().size();
  const bool wanted =
      on && run_.geometry().faces.empty() && lod_points_ > 0 && n > static_cast<std::size_t>(lod_points_);
  auto* clouds = vis_->getCloudActorMap().get();
  auto shape = clouds->find("shape");
  if (!wanted) {
    if (lod_.empty()) return;
    lod_.clear();
    vis_->removePointCloud("lod");
    if (shape != clouds->end() && shape->second.actor) shape->second.actor->SetVisibility(true);
    vis_->getRenderWindow()->SetMultiSamples(multisamples_);
    return;
  }
  const std::size_t stride =
      (n + static_cast<std::size_t>(lod_points_) - 1) / static_cast<std::size_t>(lod_points_);
  lod_.clear();
  for (std::size_t i = 0; i < n; i += stride) lod_.push_back(static_cast<int>(i));
  lod_display_ = pcl::make_shared<pcl::PointCloud<pcl::PointXYZRGB>>();
  lod_display_->reserve(lod_.size());
  for (const int i : lod_) lod_display_->push_back((*display_)[static_cast<std::size_t>(i)]);
  const pcl::visualization::PointCloudColorHandlerRGBField<pcl::PointXYZRGB> rgb(lod_display_);
  vis_->addPointCloud<pcl::PointXYZRGB>(lod_display_, rgb, "lod");
  if (ready() && run_.geometry().hasFileNormals()) {  // lit as the whole cloud is
    const std::vector<Eigen::Vector3f>& deformed = run_.deformer().deformedNormals();
    std::vector<Eigen::Vector3f> normals;
    normals.reserve(lod_.size());
    for (const int i : lod_) normals.push_back(deformed[static_cast<std::size_t>(i)]);
    shade("lod", &normals);
  }
  // As many pixels as the whole cloud fills: each drawn point stands for `stride`.
  vis_->setPointCloudRenderingProperties(pcl::visualization::PCL_VISUALIZER_POINT_SIZE, 2, "lod");
  if (shape != clouds->end() && shape->second.actor) shape->second.actor->SetVisibility(false);
  // Anti-aliasing (4 samples a pixel) is most of a software-GL frame: off while dragging.
  multisamples_ = vis_->getRenderWindow()->GetMultiSamples();
  vis_->getRenderWindow()->SetMultiSamples(0);
}

// During a drag only positions change: write them straight into the VTK points of the shape
// (PCL's update would rebuild the whole poly data, colours included, on every mouse move).
void Viewer::updatePositions() {
  // The drawn points: the level of detail's subset while there is one, else the whole shape.
  const bool lod = !lod_.empty();
  vtkPolyData* poly = lod ? cloudPolyData("lod") : shapePolyData();
  const std::size_t count = lod ? lod_.size() : run_.geometry().size();
  vtkPoints* pts = poly ? poly->GetPoints() : nullptr;
  if (!pts || pts->GetNumberOfPoints() != static_cast<vtkIdType>(count) || pts->GetDataType() != VTK_FLOAT) {
    refresh();
    return;
  }
  float* raw = static_cast<vtkFloatArray*>(pts->GetData())->GetPointer(0);
  const long long n = static_cast<long long>(count);
  const auto& local = run_.deformer().deformedPoints();
  const Eigen::Vector3f origin = run_.geometry().origin.cast<float>();
#pragma omp parallel for schedule(static)
  for (long long k = 0; k < n; ++k) {
    const std::size_t i =
        lod ? static_cast<std::size_t>(lod_[static_cast<std::size_t>(k)]) : static_cast<std::size_t>(k);
    const Eigen::Vector3f p = local[i] + origin;
    raw[3 * k] = p.x();
    raw[3 * k + 1] = p.y();
    raw[3 * k + 2] = p.z();
  }
  pts->Modified();
  poly->Modified();
  // Lit by the deformed normals, as the frame kept on release is (what you see is what you get).
  if (run_.geometry().faces.empty() && ready() && run_.geometry().hasFileNormals()) {
    const std::vector<Eigen::Vector3f>& deformed_normals = run_.deformer().deformedNormals();
    if (lod) {
      std::vector<Eigen::Vector3f> normals;
      normals.reserve(lod_.size());
      for (const int i : lod_) normals.push_back(deformed_normals[static_cast<std::size_t>(i)]);
      shade("lod", &normals);
    } else {
      shade("shape", &deformed_normals);
    }
  }
  // The handles' marks and halos follow their points.
  for (const char* id : {"handles", "halo"}) {
    vtkPolyData* marks = cloudPolyData(id);
    vtkPoints* mp = marks ? marks->GetPoints() : nullptr;
    if (!mp || mp->GetNumberOfPoints() != static_cast<vtkIdType>(handle_points_.size())) continue;
    for (std::size_t k = 0; k < handle_points_.size(); ++k) {
      const Eigen::Vector3f p = local[static_cast<std::size_t>(handle_points_[k])] + origin;
      mp->SetPoint(static_cast<vtkIdType>(k), p.x(), p.y(), p.z());
    }
    mp->Modified();
    marks->Modified();
  }
  render();
}

vtkPolyData* Viewer::cloudPolyData(const std::string& id) {
  auto it = vis_->getCloudActorMap()->find(id);
  if (it == vis_->getCloudActorMap()->end() || !it->second.actor) return nullptr;
  return vtkPolyData::SafeDownCast(it->second.actor->GetMapper()->GetInput());
}

vtkPolyData* Viewer::shapePolyData() {
  if (run_.geometry().faces.empty()) return cloudPolyData("shape");
  auto it = vis_->getShapeActorMap()->find("shape");
  if (it == vis_->getShapeActorMap()->end()) return nullptr;
  auto* actor = vtkActor::SafeDownCast(it->second);
  return actor && actor->GetMapper() ? vtkPolyData::SafeDownCast(actor->GetMapper()->GetInput()) : nullptr;
}

void Viewer::render() {
  const auto t0 = Clock::now();
  updateStatus();
  vis_->getRenderWindow()->Render();
  if (dragging_ || timing_frame_) stats_.render.push_back(msSince(t0));
}

// The status line: the mode (its own label, always there), then what the shape is, the
// timings, the warnings and the last message; wrapped at " | " to the window's width (it grows
// upwards) rather than cut off.
Eigen::Vector3f Viewer::clusterColour(int id) {
  // Golden-ratio hues: neighbouring ids look different.
  const float h = std::fmod(static_cast<float>(id) * 0.618034f, 1.0f) * 6.0f;
  const float x = 1.0f - std::abs(std::fmod(h, 2.0f) - 1.0f);
  Eigen::Vector3f c;
  if (h < 1)
    c = {1, x, 0};
  else if (h < 2)
    c = {x, 1, 0};
  else if (h < 3)
    c = {0, 1, x};
  else if (h < 4)
    c = {0, x, 1};
  else if (h < 5)
    c = {x, 0, 1};
  else
    c = {1, 0, x};
  return 0.25f + 0.7f * c.array();
}

}  // namespace hgdview
