// How clouds are shaded (render.h's shadeCloud): lit through their normals, two-sided, when they
// have them, else with eye-dome lighting; used by render.cpp's pictures and by the viewer.
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
#include "hgdeform/render/render.h"

namespace hgd {

namespace {

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

/// Eye-dome lighting (Boucheny's, as CloudCompare draws it), on vtkEDLShading's framebuffers:
/// the scene is drawn into its projection buffer, then one pass shades each drawn pixel by how
/// far it lies behind its neighbours (the log of the eye distance, 8 neighbours at 1 and at 2
/// pixels). Neighbours that are background take no part, and the background is never shaded:
/// VTK's own shading darkened a drawn pixel beside the background, which put a dark ring round
/// every lone point (a stray looked like a handle's mark; issue 49). Only depth steps within the
/// drawn surface shade: its folds and the edges of its near parts over its far ones. The shade
/// darkens by kStrength of its own amount, and the clear is kept to the renderer's viewport (a
/// window of several viewports is drawn one at a time).
class SoftEyeDome : public vtkEDLShading {
 public:
  static SoftEyeDome* New();
  vtkTypeMacro(SoftEyeDome, vtkEDLShading)

      static constexpr float kStrength = 0.6f;
  /// The shade is 1 - exp(-kResponse * sum): a pixel 0.1% of its distance behind three of its 8
  /// neighbours at one pixel darkens by about a fifth of kStrength, 1% behind by nine tenths.
  static constexpr float kResponse = 60.0f;

  void Render(const vtkRenderState* s) override {
    this->NumberOfRenderedProps = 0;
    vtkRenderer* r = s->GetRenderer();
    auto* window = vtkOpenGLRenderWindow::SafeDownCast(r->GetRenderWindow());
    if (!this->DelegatePass || !window) return;
    this->ReadWindowSize(s);
    this->ExtraPixels = 0;
    this->W = this->Width;
    this->H = this->Height;
    vtkRenderState s2(r);
    s2.SetPropArrayAndCount(s->GetPropArray(), s->GetPropArrayCount());
    this->EDLInitializeFramebuffers(s2);
    if (!this->Compose.Program)
      this->Compose.Program = window->GetShaderCache()->ReadyShaderProgram(kQuadVS, kComposeFS, "");
    if (!this->Compose.Program) return;
    double znear = 0, zfar = 1;
    r->GetActiveCamera()->GetClippingRange(znear, zfar);
    this->Zn = static_cast<float>(znear);
    this->Zf = static_cast<float>(zfar);
    this->ProjectionFBO->SaveCurrentBindingsAndBuffers();
    this->ProjectionFBO->Bind();
    this->RenderDelegate(s, this->Width, this->Height, this->W, this->H, this->ProjectionFBO,
                         this->ProjectionColorTexture, this->ProjectionDepthTexture);
    this->ProjectionFBO->UnBind();
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
      "uniform sampler2D s2_C;\n"
      "uniform sampler2D s2_D;\n"
      "in vec2 tcoordVC;\n"
      "const vec2 kDirections[8] = vec2[8](vec2(1, 0), vec2(1, 1), vec2(0, 1), vec2(-1, 1), vec2(-1, 0),\n"
      "                                    vec2(-1, -1), vec2(0, -1), vec2(1, -1));\n"
      "uniform float zn;\n"
      "uniform float zf;\n"
      "uniform float strength;\n"
      "uniform float response;\n"
      "float logDistance(float d) {\n"
      "  float ndc = 2.0 * d - 1.0;\n"
      "  return log2(2.0 * zn * zf / (zf + zn - ndc * (zf - zn)));\n"
      "}\n"
      "void main() {\n"
      "  ivec2 last = textureSize(s2_D, 0) - ivec2(1);\n"
      "  ivec2 at = clamp(ivec2(tcoordVC.st * vec2(last + ivec2(1))), ivec2(0), last);\n"
      "  vec4 color = texelFetch(s2_C, at, 0);\n"
      "  float d = texelFetch(s2_D, at, 0).r;\n"
      "  float lum = 1.0;\n"
      "  if (d < 1.0) {\n"
      "    float own = logDistance(d);\n"
      "    float sum = 0.0;\n"
      "    for (int k = 0; k < 16; ++k) {\n"
      "      int radius = k < 8 ? 1 : 2;\n"
      "      ivec2 step = ivec2(kDirections[k % 8]) * radius;\n"
      "      float dn = texelFetch(s2_D, clamp(at + step, ivec2(0), last), 0).r;\n"
      "      if (dn < 1.0) sum += max(0.0, own - logDistance(dn)) / float(radius);\n"
      "    }\n"
      "    lum = 1.0 - strength * (1.0 - exp(-response * sum));\n"
      "  }\n"
      "  gl_FragData[0] = vec4(color.rgb * lum, color.a);\n"
      "  gl_FragDepth = d;\n"
      "}\n";

  void compose(vtkOpenGLRenderWindow* window) {
    window->GetShaderCache()->ReadyShaderProgram(this->Compose.Program);
    vtkShaderProgram* prog = this->Compose.Program;
    this->ProjectionColorTexture->Activate();
    prog->SetUniformi("s2_C", this->ProjectionColorTexture->GetTextureUnit());
    this->ProjectionDepthTexture->Activate();
    prog->SetUniformi("s2_D", this->ProjectionDepthTexture->GetTextureUnit());
    prog->SetUniformf("zn", this->Zn);
    prog->SetUniformf("zf", this->Zf);
    prog->SetUniformf("strength", kStrength);
    prog->SetUniformf("response", kResponse);
    vtkOpenGLState* state = window->GetState();
    state->vtkglEnable(GL_SCISSOR_TEST);
    state->vtkglScissor(this->Origin[0], this->Origin[1], this->W, this->H);
    state->vtkglClearColor(1., 1., 1., 1.);
    state->vtkglClearDepth(1.0);
    state->vtkglClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    state->vtkglDisable(GL_BLEND);
    state->vtkglEnable(GL_DEPTH_TEST);
    this->ProjectionColorTexture->CopyToFrameBuffer(0, 0, this->W - 1, this->H - 1, this->Origin[0],
                                                    this->Origin[1], this->Origin[0] + this->W - 1,
                                                    this->Origin[1] + this->H - 1, prog, this->Compose.VAO);
    this->ProjectionDepthTexture->Deactivate();
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

}  // namespace hgd
