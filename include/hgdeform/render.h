// Off-screen pictures of shapes, drawn with PCL's visualizer: the one renderer shared by
// hgdeform-render, the batch runner's thumbnails and the viewer's screenshots. Needs an X
// display (xvfb-run on a headless machine). Lives in the separate target hgdeform_render so
// that the core library does not pull in VTK.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "hgdeform/shape.h"

namespace hgd {

struct RenderOptions {
  int width = 1200, height = 600;
  Eigen::Vector3f view = Eigen::Vector3f(1.0f, 0.6f, 1.4f);  ///< direction from the target to the eye
  std::string field;                ///< scalar field to colour by ("" = file colours or grey)
  std::vector<std::string> titles;  ///< one per viewport, optional
  int point_size = 3;
};

/// Empty when an X display can be opened; else what is wrong ("DISPLAY is not set", "cannot
/// open the X display ':99'"). VTK aborts the process when its window finds no display, so
/// every front end asks first.
std::string displayProblem();

/// Renders the shapes side by side (one viewport each, one shared camera framing them all) and
/// writes a PNG atomically. Throws std::runtime_error on failure.
void renderPng(const std::vector<const Shape*>& shapes, const std::string& png_path,
               const RenderOptions& options);

}  // namespace hgd
