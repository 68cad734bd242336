#include "hgdeform/render.h"

#include <pcl/conversions.h>
#include <pcl/visualization/pcl_visualizer.h>
#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkEDLShading.h>
#include <vtkFloatArray.h>
#include <vtkImageData.h>
#include <vtkLODActor.h>
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
#include <vtkSequencePass.h>
#include <vtkShaderProgram.h>
#include <vtkShaderProperty.h>
#include <vtkSmartPointer.h>
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

/// Appended to VTK's fragment-shader normal code: a normal facing away from the eye (view
/// coordinates: the eye looks down -z) is turned towards it. Points have no front or back face,
/// so without this a point whose normal faces away would get ambient light only.
constexpr const char* kNormalTag = "//VTK::Normal::Impl";
constexpr const char* kTwoSidedNormal =
    "//VTK::Normal::Impl\n"
    "  if (normalVCVSOutput.z < 0.0) { normalVCVSOutput = -normalVCVSOutput; }\n";

/// PCL draws clouds with a vtkLODActor, which renders through an inner actor of its own (its
/// protected `Device`) that does not take the outer actor's shader property: reach it (a pointer
/// to a protected member formed through a derived class is the standard's legal way).
struct LodDevice : vtkLODActor {
  static vtkActor* of(vtkLODActor* actor) { return actor->*(&LodDevice::Device); }
};

/// The overlay (text, colour bars) drawn after the eye-dome pass, blended: the pass leaves
/// blending off, which would draw anti-aliased text with opaque edges.
class BlendedOverlayPass : public vtkOverlayPass {
 public:
  static BlendedOverlayPass* New();
  vtkTypeMacro(BlendedOverlayPass, vtkOverlayPass) void Render(const vtkRenderState* s) override {
    if (auto* window = vtkOpenGLRenderWindow::SafeDownCast(s->GetRenderer()->GetRenderWindow())) {
      vtkOpenGLState* state = window->GetState();
      state->vtkglEnable(GL_BLEND);
      state->vtkglBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
    }
    vtkOverlayPass::Render(s);
  }
};
vtkStandardNewMacro(BlendedOverlayPass);

/// VTK's eye-dome lighting (vtkEDLShading: the same depth passes), composed more softly and
/// within its viewport. VTK's own composition multiplies the colour by the shade as is, which on
/// a sparse cloud (the background showing between its points is "far") turns most of it near
/// black, and clears the whole window, erasing the other viewports. Here the shade darkens by
/// kStrength of its own amount and the clear is kept to the renderer's viewport.
class SoftEyeDome : public vtkEDLShading {
 public:
  static SoftEyeDome* New();
  vtkTypeMacro(SoftEyeDome, vtkEDLShading)

      static constexpr float kStrength = 0.6f;

  void Render(const vtkRenderState* s) override {
    this->NumberOfRenderedProps = 0;
    vtkRenderer* r = s->GetRenderer();
    auto* window = vtkOpenGLRenderWindow::SafeDownCast(r->GetRenderWindow());
    if (!this->DelegatePass || !window) return;
    // What vtkEDLShading::Render does, up to its composition.
    this->ReadWindowSize(s);
    this->ExtraPixels = 0;
    this->W = this->Width;
    this->H = this->Height;
    vtkRenderState s2(r);
    s2.SetPropArrayAndCount(s->GetPropArray(), s->GetPropArrayCount());
    this->EDLInitializeFramebuffers(s2);
    this->EDLInitializeShaders(window);
    if (!this->Compose.Program)
      this->Compose.Program = window->GetShaderCache()->ReadyShaderProgram(kQuadVS, kComposeFS, "");
    if (!this->EDLShadeProgram.Program || !this->BilateralProgram.Program || !this->Compose.Program) return;
    double znear = 0, zfar = 1;
    r->GetActiveCamera()->GetClippingRange(znear, zfar);
    this->Zn = static_cast<float>(znear);
    this->Zf = static_cast<float>(zfar);
    this->ProjectionFBO->SaveCurrentBindingsAndBuffers();
    this->ProjectionFBO->Bind();
    this->RenderDelegate(s, this->Width, this->Height, this->W, this->H, this->ProjectionFBO,
                         this->ProjectionColorTexture, this->ProjectionDepthTexture);
    this->ProjectionFBO->UnBind();
    if (!this->EDLShadeHigh(s2, window)) this->ProjectionFBO->RestorePreviousBindingsAndBuffers();
    if (!this->EDLShadeLow(s2, window)) this->ProjectionFBO->RestorePreviousBindingsAndBuffers();
    if (this->EDLIsFiltered) this->EDLBlurLow(s2, window);
    if (s->GetFrameBuffer()) vtkOpenGLFramebufferObject::SafeDownCast(s->GetFrameBuffer())->Bind();
    this->ProjectionFBO->RestorePreviousBindingsAndBuffers();
    compose(window);
  }

  void ReleaseGraphicsResources(vtkWindow* w) override {
    this->Compose.ReleaseGraphicsResources(w);
    vtkEDLShading::ReleaseGraphicsResources(w);
  }

 private:
  static constexpr const char* kQuadVS =
      "//VTK::System::Dec\n"
      "in vec4 vertexMC;\n"
      "in vec2 tcoordMC;\n"
      "out vec2 tcoordVC;\n"
      "void main() { tcoordVC = tcoordMC; gl_Position = vertexMC; }\n";
  static constexpr const char* kComposeFS =
      "//VTK::System::Dec\n"
      "//VTK::Output::Dec\n"
      "in vec2 tcoordVC;\n"
      "uniform sampler2D s2_S1;\n"
      "uniform sampler2D s2_S2;\n"
      "uniform sampler2D s2_C;\n"
      "uniform float strength;\n"
      "void main() {\n"
      "  vec4 shade1 = texture2D(s2_S1, tcoordVC.st);\n"
      "  vec4 shade2 = texture2D(s2_S2, tcoordVC.st);\n"
      "  vec4 color = texture2D(s2_C, tcoordVC.st);\n"
      "  float lum = 1.0 - strength * (1.0 - mix(shade1.r, shade2.r, 0.3));\n"
      "  gl_FragData[0] = vec4(color.rgb * lum, color.a);\n"
      "  gl_FragDepth = shade1.a;\n"
      "}\n";

  void compose(vtkOpenGLRenderWindow* window) {
    window->GetShaderCache()->ReadyShaderProgram(this->Compose.Program);
    vtkShaderProgram* prog = this->Compose.Program;
    vtkTextureObject* low = this->EDLIsFiltered ? this->EDLLowBlurTexture : this->EDLLowShadeTexture;
    this->EDLHighShadeTexture->Activate();
    prog->SetUniformi("s2_S1", this->EDLHighShadeTexture->GetTextureUnit());
    low->Activate();
    prog->SetUniformi("s2_S2", low->GetTextureUnit());
    this->ProjectionColorTexture->Activate();
    prog->SetUniformi("s2_C", this->ProjectionColorTexture->GetTextureUnit());
    prog->SetUniformf("strength", kStrength);
    vtkOpenGLState* state = window->GetState();
    state->vtkglEnable(GL_SCISSOR_TEST);
    state->vtkglScissor(this->Origin[0], this->Origin[1], this->W, this->H);
    state->vtkglClearColor(1., 1., 1., 1.);
    state->vtkglClearDepth(1.0);
    state->vtkglClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    state->vtkglDisable(GL_BLEND);
    state->vtkglEnable(GL_DEPTH_TEST);
    this->EDLHighShadeTexture->CopyToFrameBuffer(0, 0, this->W - 1, this->H - 1, this->Origin[0],
                                                 this->Origin[1], this->Origin[0] + this->W - 1,
                                                 this->Origin[1] + this->H - 1, prog, this->Compose.VAO);
    low->Deactivate();
    this->EDLHighShadeTexture->Deactivate();
    this->ProjectionColorTexture->Deactivate();
    // The overlay (drawn next) goes into the renderer's viewport, whatever the passes left set.
    state->vtkglViewport(this->Origin[0], this->Origin[1], this->W, this->H);
    state->vtkglScissor(this->Origin[0], this->Origin[1], this->W, this->H);
  }

  vtkOpenGLHelper Compose;
};
vtkStandardNewMacro(SoftEyeDome);

/// Whether `renderer` already draws with the eye-dome pass set by shadeCloud.
bool hasEyeDome(vtkRenderer* renderer) {
  auto* seq = vtkSequencePass::SafeDownCast(renderer->GetPass());
  return seq && seq->GetPasses() && seq->GetPasses()->GetNumberOfItems() > 0 &&
         vtkEDLShading::SafeDownCast(seq->GetPasses()->GetItemAsObject(0));
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

}  // namespace

CloudShading shadeCloud(vtkRenderer* renderer, vtkActor* actor, const std::vector<Eigen::Vector3f>* normals) {
  vtkPolyData* poly = actor && actor->GetMapper()
                          ? vtkPolyData::SafeDownCast(actor->GetMapper()->GetInputAsDataSet())
                          : nullptr;
  if (normals && poly && static_cast<vtkIdType>(normals->size()) == poly->GetNumberOfPoints()) {
    auto array = vtkSmartPointer<vtkFloatArray>::New();
    array->SetName("Normals");
    array->SetNumberOfComponents(3);
    array->SetNumberOfTuples(static_cast<vtkIdType>(normals->size()));
    float* out = array->GetPointer(0);
    for (std::size_t i = 0; i < normals->size(); ++i) {
      const Eigen::Vector3f& n = (*normals)[i];
      out[3 * i] = n.x();
      out[3 * i + 1] = n.y();
      out[3 * i + 2] = n.z();
    }
    poly->GetPointData()->SetNormals(array);
    poly->Modified();
    vtkProperty* p = actor->GetProperty();
    p->LightingOn();
    p->SetInterpolationToGouraud();  // PCL sets flat, with which VTK ignores point normals
    p->SetAmbient(0.3);
    p->SetDiffuse(0.7);
    p->SetSpecular(0.0);
    vtkShaderProperty* sp = actor->GetShaderProperty();
    sp->ClearFragmentShaderReplacement(kNormalTag, true);
    sp->AddFragmentShaderReplacement(kNormalTag, true, kTwoSidedNormal, false);
    if (auto* lod = vtkLODActor::SafeDownCast(actor)) LodDevice::of(lod)->SetShaderProperty(sp);
    return CloudShading::Normals;
  }
  if (renderer && !hasEyeDome(renderer)) {
    // The eye-dome pass shades what its delegate draws: the 3D scene only. Text and colour bars
    // (the overlay) are drawn after it, unshaded. Its final step clears the whole window, so a
    // window of several viewports draws them one at a time (renderPng).
    auto steps = vtkSmartPointer<vtkRenderStepsPass>::New();
    steps->SetOverlayPass(nullptr);
    auto edl = vtkSmartPointer<SoftEyeDome>::New();
    edl->SetDelegatePass(steps);
    auto overlay = vtkSmartPointer<BlendedOverlayPass>::New();
    auto passes = vtkSmartPointer<vtkRenderPassCollection>::New();
    passes->AddItem(edl);
    passes->AddItem(overlay);
    auto seq = vtkSmartPointer<vtkSequencePass>::New();
    seq->SetPasses(passes);
    renderer->SetPass(seq);
  }
  return CloudShading::EyeDome;
}

CloudShading shadeCloud(pcl::visualization::PCLVisualizer& visualizer, const std::string& id,
                        const Geometry& geometry, bool file_colours,
                        const std::vector<Eigen::Vector3f>* normals, int viewport) {
  if (file_colours) return CloudShading::None;
  vtkRendererCollection* renderers = visualizer.getRendererCollection();
  vtkRenderer* renderer = viewport >= 0 && viewport < renderers->GetNumberOfItems()
                              ? vtkRenderer::SafeDownCast(renderers->GetItemAsObject(viewport))
                              : nullptr;
  const auto clouds = visualizer.getCloudActorMap();
  const auto it = clouds->find(id);
  vtkActor* actor = it != clouds->end() ? it->second.actor.Get() : nullptr;
  std::vector<Eigen::Vector3f> file;
  if (geometry.hasFileNormals() && !normals) {
    file.reserve(geometry.file_normals->size());
    for (const auto& fn : *geometry.file_normals) file.push_back(fn.getNormalVector3fMap());
    normals = &file;
  }
  return shadeCloud(renderer, actor, geometry.hasFileNormals() ? normals : nullptr);
}

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
      shadeCloud(viewer, id, g,
                 options.field.empty() && findColourFields(shapes[static_cast<std::size_t>(k)]->cloud).any(),
                 nullptr, vp);
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
  // One viewport at a time (the eye-dome pass clears the whole window when it composes), each
  // copied into its columns of the picture.
  vtkRendererCollection* renderers = viewer.getRendererCollection();
  auto picture = vtkSmartPointer<vtkImageData>::New();
  picture->SetDimensions(width, height, 1);
  picture->AllocateScalars(VTK_UNSIGNED_CHAR, 3);
  auto* out = static_cast<unsigned char*>(picture->GetScalarPointer());
  std::fill(out, out + std::size_t{3} * static_cast<std::size_t>(width) * static_cast<std::size_t>(height),
            static_cast<unsigned char>(255));
  for (int k = 1; k <= n; ++k) {
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
