// Off-screen pictures of shapes, drawn with PCL's visualizer: the one renderer shared by
// hgdeform-render, the batch runner's thumbnails and the viewer's screenshots. Needs an X
// display (xvfb-run on a headless machine). Lives in the separate target hgdeform_render so
// that the core library does not pull in VTK.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "hgdeform/io/geometry.h"
#include "hgdeform/io/shape.h"

namespace pcl {
namespace visualization {
class PCLVisualizer;
}
}  // namespace pcl
class vtkActor;
class vtkRenderWindow;
class vtkRenderer;

namespace hgd {

struct RenderOptions {
  int width = 1200, height = 600;
  /// Direction from the target to the eye. Unset: chosen from the shapes (see chooseView): a
  /// three-quarter view (1, 0.6, 1.4) in a frame whose "forward" axis is the shape's thinnest
  /// side axis, or, with a displacement, the side from which the motion shows best.
  std::optional<Eigen::Vector3f> view;
  /// Which axis points up in the picture: "x", "y", "z", "-x", "-y", "-z", or "auto" (upAxis):
  /// -y for a shape in a camera's frame (PCL's convention: +z forward, +y down), i.e. organized
  /// (height > 1), a PCD with a sensor pose or an unorganized scan in its sensor's frame
  /// (isCameraFrame); +z for a shape whose y extent is clearly its
  /// thinnest (a z-up model: a horse, a statue, a car); else +y.
  std::string up = "auto";
  std::string field;                ///< scalar field to colour by ("" = file colours or grey)
  std::vector<std::string> titles;  ///< one per viewport, optional
  int point_size = 3;
  /// Colour by displacement: each point by its distance from the same point (file order) of
  /// this rest shape, blue (0) to red (the largest over the inputs), with a colour bar; the view
  /// then faces the side where the motion shows best. An input that is this very shape (the same
  /// object) is drawn in its own colours. Every input must have the rest shape's point count.
  const Shape* displacement_rest = nullptr;
  /// Handles to mark (file point indices, the same in every input): larger points, the fixed
  /// ones black, the manipulated ones magenta (colours the displacement scale does not use),
  /// with a legend.
  std::vector<int> fixed_points, manipulated_points;
};

/// Per file point of `shape`, its distance from the same point of `rest` (NaN where either is
/// not finite). Throws std::runtime_error naming both files when their point counts differ.
std::vector<double> displacementFrom(const Shape& rest, const Shape& shape);

/// How a point cloud's points are shaded (shadeCloud).
enum class CloudShading {
  None,     ///< drawn as it is: the file's own colours
  Normals,  ///< lit by the renderer's headlight through the points' normals, like a surface
  EyeDome,  ///< eye-dome lighting on the whole renderer (no normals needed)
};

/// Shades a point cloud so that its shape reads instead of a flat silhouette: the one rule of
/// hgdeform-render, the batch thumbnails and the viewer. `actor` draws the cloud's points (its
/// mapper's input is a vtkPolyData of `normals->size()` points) in `renderer`.
/// - With `normals` (one per point, in the poly data's order: the file's normals), they become
///   the poly data's point normals and the points are lit by the headlight (ambient 0.3,
///   diffuse 0.7), on both sides: a normal facing away from the eye is turned towards it, so
///   unoriented scan normals light as well as oriented ones. Calling it again replaces them (the
///   viewer passes the deformed normals).
/// - Without (nullptr, or a count that does not fit), the renderer draws with eye-dome lighting
///   (VTK's vtkEDLShading render pass, as CloudCompare and Potree do): each pixel darkened by how
///   far its neighbours lie in front of it, which outlines the shape and its folds from depth
///   alone. The pass covers all that renderer draws (meshes and text too); set once.
CloudShading shadeCloud(vtkRenderer* renderer, vtkActor* actor, const std::vector<Eigen::Vector3f>* normals);

/// shadeCloud for the point cloud `id` of a PCLVisualizer, drawn in `viewport` (0 for a window of
/// one renderer), the points of `geometry` in its order: by its file normals when it has them
/// (or by `normals` instead, e.g. the deformed ones, when given and the file has normals), else
/// with eye-dome lighting. A cloud drawn in its file's colours (`file_colours`: a scan's colours
/// are a photograph of the surface, shaded already) is left as it is (CloudShading::None); grey
/// and computed colours (a field, the displacement, handle roles) are shaded. What
/// hgdeform-render and the viewer both call.
CloudShading shadeCloud(pcl::visualization::PCLVisualizer& visualizer, const std::string& id,
                        const Geometry& geometry, bool file_colours,
                        const std::vector<Eigen::Vector3f>* normals = nullptr, int viewport = 0);

/// Empty when an X display can be opened and has the GLX extension (OpenGL); else what is
/// wrong ("DISPLAY is not set", "cannot open the X display ':99'", "the X display ':97' has no
/// GLX extension"). VTK aborts the process when its window finds no display or no OpenGL
/// visual, so every front end asks first.
std::string displayProblem();

/// The largest side of a picture: what OpenGL drivers render (Mesa's llvmpipe among them; an
/// X window cannot be larger than 32767 either).
constexpr int kMaxPictureSide = 16384;

/// Empty when a `width` x `height` picture can be rendered; else why not: a side outside 1 to
/// kMaxPictureSide (X ended such a render with a raw BadValue), or buffers (colour, depth, the
/// window's buffers, the grab and the PNG: about 32 bytes a pixel) that this process cannot allocate, as
/// under `ulimit -v` (the OpenGL driver's own allocation then failed unchecked and crashed). Asks for no
/// display; renderPng asks it first, front ends before they open a display.
std::string pictureSizeProblem(int width, int height);

/// The unit vector `up` names for these shapes (see RenderOptions::up; "auto" looks at the first
/// shape: its organization and sensor pose, then the spread of its points along x, y and z).
/// Throws std::invalid_argument naming the accepted values for anything else.
Eigen::Vector3f upAxis(const std::string& up, const std::vector<const Shape*>& shapes);

/// Whether `shape` is in a depth camera's frame (+z forward, +y down): organized, or a PCD with
/// a sensor pose, or every finite point in front of the origin (z > 0) within 60 degrees of +z,
/// as a scan written in its sensor's frame is. upAxis("auto") takes -y up for it.
bool isCameraFrame(const Shape& shape);

/// Whether every finite point of `shape` is ahead of the origin (z > 0) within 60 degrees of +z:
/// where a sensor at the origin looking along +z sees them. The viewer opens such a shape seen
/// from the sensor's side.
bool inSensorCone(const Shape& shape);

/// The direction from the target to the eye the renderer takes for `shape` when no view is given
/// and nothing is coloured by displacement, with the up axis `up` names (see upAxis): a
/// three-quarter view across the shape's broad side, never along the up axis.
Eigen::Vector3d defaultView(const Shape& shape, const std::string& up);

/// Renders the shapes side by side (one viewport each, one shared camera framing them all) and
/// writes a PNG atomically. Throws std::runtime_error on failure.
void renderPng(const std::vector<const Shape*>& shapes, const std::string& png_path,
               const RenderOptions& options);

/// Writes what `window` shows (its back buffer, as last rendered) as a PNG: encoded in memory,
/// then written by hgd::writeFileAtomically like every other output (a temporary file beside the
/// target renamed over it, a symbolic link followed, a FIFO or a device written to directly;
/// never a half-written picture, nothing left behind on failure). Refuses (hgd::refuseInputs)
/// to replace one of `inputs`. Throws std::runtime_error ("<png_path>: cannot write the <what>:
/// …", or the writer's hgd::IoError "<png_path>: cannot write: …") on failure. renderPng and the
/// viewer's screenshots both write through it.
void writeWindowPng(vtkRenderWindow* window, const std::string& png_path,
                    const std::vector<std::string>& inputs = {}, const std::string& what = "picture");

}  // namespace hgd
