// What the viewer draws over the shape: the lasso, the axes, the overlays' places, the status
// line and its messages.
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

void Viewer::drawLasso() {
  if (!lasso_actor_) {
    lasso_actor_ = vtkSmartPointer<vtkActor2D>::New();
    auto mapper = vtkSmartPointer<vtkPolyDataMapper2D>::New();
    mapper->SetInputData(vtkSmartPointer<vtkPolyData>::New());
    lasso_actor_->SetMapper(mapper);
    lasso_actor_->GetProperty()->SetColor(0.0, 0.5, 0.55);
    lasso_actor_->GetProperty()->SetLineWidth(2);
    renderer()->AddActor2D(lasso_actor_);
  }
  auto points = vtkSmartPointer<vtkPoints>::New();
  auto lines = vtkSmartPointer<vtkCellArray>::New();
  if (lasso_.size() >= 2) {
    lines->InsertNextCell(static_cast<vtkIdType>(lasso_.size() + 1));
    for (std::size_t k = 0; k <= lasso_.size(); ++k) {  // closed: back to the first vertex
      const Eigen::Vector2d& p = lasso_[k % lasso_.size()];
      lines->InsertCellPoint(points->InsertNextPoint(p.x(), p.y(), 0));
    }
  }
  auto poly = vtkSmartPointer<vtkPolyData>::New();
  poly->SetPoints(points);
  poly->SetLines(lines);
  vtkPolyDataMapper2D::SafeDownCast(lasso_actor_->GetMapper())->SetInputData(poly);
  render();
}

// The axes trihedron, as CloudCompare and MeshLab show one: x red, y green, z blue, turning with
// the view, in the lower right corner (the mode and the status line are at the lower left).
void Viewer::showAxes(bool on) {
  vtkRenderWindowInteractor* iren = vis_->getRenderWindow()->GetInteractor();
  if (on && !axes_ && iren) {
    auto axes = vtkSmartPointer<vtkAxesActor>::New();
    for (vtkCaptionActor2D* c :
         {axes->GetXAxisCaptionActor2D(), axes->GetYAxisCaptionActor2D(), axes->GetZAxisCaptionActor2D()}) {
      c->GetCaptionTextProperty()->SetColor(0.1, 0.1, 0.1);
      c->GetCaptionTextProperty()->ShadowOff();
      c->GetCaptionTextProperty()->ItalicOff();
    }
    axes_ = vtkSmartPointer<vtkOrientationMarkerWidget>::New();
    axes_->SetOrientationMarker(axes);
    axes_->SetInteractor(iren);
    axes_->SetViewport(0.86, 0.05, 1.0, 0.23);
  }
  axes_shown_ = on && axes_;
  if (axes_) {
    axes_->SetEnabled(axes_shown_ ? 1 : 0);
    if (axes_shown_) axes_->InteractiveOff();  // (VTK warns when asked while disabled)
  }
  if (!opening_) message(axes_shown_ ? "axes shown" : "axes hidden");
}

void Viewer::placeOverlays() {
  if (!help_) return;
  const int* size = vis_->getRenderWindow()->GetSize();
  // The help wraps to the window's width (8 pixels a Courier character at 13 points), as the
  // status line does: it was cut off in a window narrower than its longest line.
  const auto columns = static_cast<std::size_t>(std::max(20, (size[0] - 40) / 8));
  if (columns != help_columns_) {
    help_columns_ = columns;
    help_->SetInput(helpOverlay(columns).c_str());
  }
  help_->SetPosition(10, size[1] - 10);
  help_->SetVisibility(help_visible_);
  mode_label_->SetPosition(10, 10);
  status_->SetPosition(80, 10);
}

void Viewer::updateStatus() {
  if (!status_) return;
  static const char* kViews[3] = {"colours", "field", "clusters"};
  std::vector<std::string> parts;
  std::ostringstream s;
  s << run_.geometry().size() << " points";
  if (ready()) s << ", " << run_.deformer().clustering().clusters.size() << " clusters";
  parts.push_back(s.str());
  parts.push_back(std::string("view ") + kViews[view_]);
  if (!stats_.solve.empty())
    parts.push_back("solve " + num(stats_.solve.back()) + " ms, interpolate " +
                    num(stats_.interpolate.back()) + " ms, render " +
                    (stats_.render.empty() ? std::string("-") : num(stats_.render.back())) + " ms");
  for (std::size_t p = alert_.find(" | "); p != std::string::npos;) {
    const std::size_t next = alert_.find(" | ", p + 3);
    parts.push_back(alert_.substr(p + 3, next == std::string::npos ? std::string::npos : next - p - 3));
    p = next;
  }
  if (!message_.empty()) parts.push_back(message_);
  const int* size = vis_->getRenderWindow()->GetSize();
  // About 7 pixels a character at 13 points.
  const std::size_t columns = static_cast<std::size_t>(std::max(20, (size[0] - 90) / 7));
  std::string text, line;
  for (const std::string& part : parts) {
    const std::string add = line.empty() ? part : " | " + part;
    if (!line.empty() && line.size() + add.size() > columns) {
      text += line + "\n";
      line = part;
    } else {
      line += add;
    }
  }
  text += line;
  status_->SetInput(text.c_str());
  static const std::map<std::string, Eigen::Vector3d> kModeColour = {{"pick", {0.1, 0.1, 0.1}},
                                                                     {"area", {0.85, 0.45, 0.0}},
                                                                     {"lasso", {0.0, 0.5, 0.55}},
                                                                     {"drag", {0.8, 0.1, 0.1}},
                                                                     {"frame", {0.45, 0.1, 0.75}}};
  std::string label = mode();
  const Eigen::Vector3d c = kModeColour.at(label);
  for (char& ch : label) ch = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
  if (caps_lock_) label += "\nCAPS";
  mode_label_->SetInput(label.c_str());
  mode_label_->GetTextProperty()->SetColor(c.x(), c.y(), c.z());
}

void Viewer::message(const std::string& m, bool draw) {
  message_ = m;
  if (verbose_) std::fprintf(stderr, "hgdeform-view: %s\n", m.c_str());
  if (vis_ && draw) render();
}

}  // namespace hgdview
