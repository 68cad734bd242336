// The viewer's camera: the opening and standard views, the up axis, and the conversions between
// the shape's space and the screen (and the point nearest a place on it).
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

void Viewer::openingView() {
  const Eigen::Vector3d up = upVector();
  Eigen::Vector3d eye = defaultEye(up);
  if (view_option_) {
    const Eigen::Vector3d v = view_option_->normalized();
    if (std::abs(v.dot(up)) < 0.999)
      eye = v;
    else if (opening_)
      message("--view lies along the up axis (no picture can be upright so): the default view instead");
  }
  setView(eye, up);
}

Eigen::Vector3d Viewer::upVector() const {
  return hgd::upAxis(up_option_, {&run_.shape()}).cast<double>();
}

Eigen::Vector3d Viewer::defaultEye(const Eigen::Vector3d& up) const {
  if (up.y() < -0.5 && hgd::inSensorCone(run_.shape())) return {0, 0, -1};
  return hgd::defaultView(run_.shape(), up_option_).normalized();
}

// The front of the shape for the standard views: the opening view's eye direction across the up
// axis, on the nearest axis of the shape's frame.
void Viewer::standardView(int which) {
  const Eigen::Vector3d up = upVector();
  Eigen::Vector3d f = defaultEye(up);
  f -= f.dot(up) * up;
  Eigen::Index axis = 0;
  f.cwiseAbs().maxCoeff(&axis);
  const double sign = f[axis] < 0 ? -1.0 : 1.0;
  f = Eigen::Vector3d::Unit(axis) * sign;
  const Eigen::Vector3d right = up.cross(f);  // the shape's right seen from its front
  static const char* const kNames[6] = {"front", "back", "left", "right", "top", "bottom"};
  switch (which) {
    case 0: setView(f, up); break;
    case 1: setView(-f, up); break;
    case 2: setView(-right, up); break;
    case 3: setView(right, up); break;
    case 4: setView(up, -f); break;  // from above, the front at the bottom of the window
    default: setView(-up, f); break;
  }
  message(std::string(kNames[std::clamp(which, 0, 5)]) + " view");
}

void Viewer::cycleUp() {
  static const char* const kAxes[6] = {"y", "z", "x", "-y", "-z", "-x"};
  const Eigen::Vector3d up = upVector();
  int now = 0;
  for (int k = 0; k < 6; ++k)
    if (hgd::upAxis(kAxes[k], {}).cast<double>().isApprox(up)) now = k;
  up_option_ = kAxes[(now + 1) % 6];
  view_option_.reset();
  openingView();
  message(std::string("up axis ") + (up_option_[0] == '-' ? "" : "+") + up_option_ + " (u: the next)");
}

// Looks along -eye at the shape as it is now, `up` up, the whole of it in the window (its
// bounding sphere in the 30-degree view angle).
void Viewer::setView(const Eigen::Vector3d& eye_direction, const Eigen::Vector3d& up) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  for (std::size_t i = 0; i < run_.geometry().size(); ++i) {
    const Eigen::Vector3d p = deformed(i);
    if (!p.allFinite()) continue;
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const bool any = lo.allFinite() && hi.allFinite();
  const Eigen::Vector3d c = any ? Eigen::Vector3d(0.5 * (lo + hi)) : centre();
  const double diagonal = any && (hi - lo).norm() > 0 ? (hi - lo).norm() : diagonal_;
  const Eigen::Vector3d at = c + 2.2 * diagonal * eye_direction.normalized();
  if (opening_) {
    // PCL's own call once, at opening (nothing large is drawn yet, so its render is cheap):
    // without it PCL frames the view anew when the whole cloud is added later.
    vis_->setCameraPosition(at.x(), at.y(), at.z(), c.x(), c.y(), c.z(), up.x(), up.y(), up.z());
  }
  // Then on VTK's camera: PCL's setCameraPosition renders (seconds for a large cloud).
  vtkCamera* cam = renderer()->GetActiveCamera();
  cam->SetPosition(at.x(), at.y(), at.z());
  cam->SetFocalPoint(c.x(), c.y(), c.z());
  cam->SetViewUp(up.x(), up.y(), up.z());
  cam->SetViewAngle(30);  // VTK's default (PCL's camera calls may leave another)
  cam->SetClippingRange(0.01 * diagonal, 10 * diagonal);
  if (style_ && !opening_) render();  // (open() renders once, at its end)
}

vtkRenderer* Viewer::renderer() {
  return vis_->getRenderWindow()->GetRenderers()->GetFirstRenderer();
}

Eigen::Vector3d Viewer::toDisplay(const Eigen::Vector3d& w) {
  vtkRenderer* r = renderer();
  r->SetWorldPoint(w.x(), w.y(), w.z(), 1.0);
  r->WorldToDisplay();
  double d[3];
  r->GetDisplayPoint(d);
  return {d[0], d[1], d[2]};
}

Eigen::Vector3d Viewer::fromDisplay(double x, double y, double depth) {
  vtkRenderer* r = renderer();
  r->SetDisplayPoint(x, y, depth);
  r->DisplayToWorld();
  double w[4];
  r->GetWorldPoint(w);
  return Eigen::Vector3d(w[0], w[1], w[2]) / (w[3] != 0 ? w[3] : 1.0);
}

void Viewer::cameraAxes(Eigen::Vector3d& up, Eigen::Vector3d& right, Eigen::Vector3d& view) {
  vtkCamera* cam = renderer()->GetActiveCamera();
  double u[3], p[3], f[3];
  cam->GetViewUp(u);
  cam->GetPosition(p);
  cam->GetFocalPoint(f);
  view = (Eigen::Vector3d(f[0], f[1], f[2]) - Eigen::Vector3d(p[0], p[1], p[2])).normalized();
  up = Eigen::Vector3d(u[0], u[1], u[2]).normalized();
  right = view.cross(up).normalized();
  up = right.cross(view).normalized();
}

// The point nearest to the cursor on screen (within `pixels`), front-most on ties.
// The point under the cursor is the front-most one: of the points within `pixels` of it on
// screen, those within a band (3% of the diagonal) of the nearest one's depth, and of these the
// nearest on screen. Screen distance alone picked through the surface: a denser far side has a
// point nearer the cursor than the near side's (three of five clicks on the bunny's near flank
// selected its far flank).
int Viewer::nearestOnScreen(int x, int y, double pixels, bool manipulated_only) {
  vtkCamera* cam = renderer()->GetActiveCamera();
  double pos[3], dir[3];
  cam->GetPosition(pos);
  cam->GetDirectionOfProjection(dir);
  const Eigen::Vector3d eye(pos[0], pos[1], pos[2]), view(dir[0], dir[1], dir[2]);
  struct Candidate {
    int index;
    double screen2, depth;
  };
  std::vector<Candidate> near;
  double front = INFINITY;
  auto consider = [&](std::size_t i) {
    const Eigen::Vector3d w = deformed(i);
    const Eigen::Vector3d d = toDisplay(w);
    const double dd = (d.x() - x) * (d.x() - x) + (d.y() - y) * (d.y() - y);
    if (dd > pixels * pixels) return;
    const double depth = (w - eye).dot(view);
    if (depth <= 0) return;  // behind the eye
    near.push_back({static_cast<int>(i), dd, depth});
    front = std::min(front, depth);
  };
  if (manipulated_only) {
    for (int i : handles_.manipulated) consider(static_cast<std::size_t>(i));
  } else {
    for (std::size_t i = 0; i < run_.geometry().size(); ++i) consider(i);
  }
  const double band = 0.03 * diagonal_;
  int best = -1;
  double best_d = INFINITY, best_z = INFINITY;
  for (const Candidate& c : near) {
    if (c.depth > front + band) continue;
    if (c.screen2 < best_d - 1e-9 || (std::abs(c.screen2 - best_d) <= 1e-9 && c.depth < best_z)) {
      best_d = c.screen2;
      best_z = c.depth;
      best = c.index;
    }
  }
  return best;
}

}  // namespace hgdview
