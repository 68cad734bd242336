// hgdeform-view's window: the Viewer (a shape, its selection and handles, the moves made through
// hgd::ScenarioRunner, which owns undo and redo) and the VTK interactor style that feeds it.
// The code follows the pipeline, one file per stage:
//   main.cpp           the command line; opens the viewer, replays or spins
//   viewer_input.cpp   the interactor style, keys, picks, the area selection, the drag gesture
//   viewer_replay.cpp  plays a replay file's events (read and checked by replay.cpp)
//   viewer.cpp         state: selection, handles, moves, undo, saving
//   viewer_draw.cpp    the window: drawing the shape, colours, shading, screenshots
//   viewer_overlays.cpp what is drawn over it: the lasso, the axes, the status line
//   viewer_camera.cpp  the views, the up axis, screen geometry
//   viewer_x11.cpp     what is asked of X directly (Caps Lock, queued pointer motions)
//   keys.cpp           the table of keys: what each does and when, the help and --help texts
#pragma once

#include <pcl/visualization/interactor_style.h>
#include <pcl/visualization/pcl_visualizer.h>
#include <vtkActor2D.h>
#include <vtkOrientationMarkerWidget.h>
#include <vtkRenderWindowInteractor.h>
#include <vtkScalarBarActor.h>
#include <vtkSmartPointer.h>
#include <vtkTextActor.h>

#include <Eigen/Core>
#include <atomic>
#include <chrono>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "hgdeform/app/regions.h"
#include "hgdeform/app/runner.h"
#include "hgdeform/app/scenario.h"
#include "keys.h"
#include "replay.h"

class vtkAbstractPicker;
class vtkPolyData;
class vtkRenderer;

namespace hgdview {

using Clock = std::chrono::steady_clock;
inline double msSince(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

class Viewer;

/// Whether Caps Lock is on (viewer_x11.cpp); `display` is the window's X Display.
bool capsLockOn(void* display);
/// The character the key that sends `keysym` gives with Shift, on the keyboard's layout (0: none).
char shiftedChar(void* display, const char* keysym);

/// The character a key press means: a letter in the case that Shift and Caps Lock make it
/// (VTK hands `s` with the shift flag from a keyboard, `S` from XLookupString or a replay).
char keyChar(char code, bool shift, bool caps_lock);

// The interactor style: our keys and the handle drag first, PCL's behaviour for the rest
// (viewer_input.cpp).
class Style : public pcl::visualization::PCLVisualizerInteractorStyle {
 public:
  static Style* New();
  vtkTypeMacro(Style, pcl::visualization::PCLVisualizerInteractorStyle) Viewer* viewer = nullptr;

  void OnKeyDown() override;
  void OnEnter() override;
  void OnChar() override;
  void OnLeftButtonDown() override;
  void OnLeftButtonUp() override;
  void OnMouseMove() override;
  void OnRightButtonDown() override;
  void OnRightButtonUp() override;
  void OnMouseWheelForward() override;
  void OnMouseWheelBackward() override;
  // vtkInteractorStyleRubberBandPick's modes: 0 orient (camera), 1 select (rubber band).
  bool selecting() const { return CurrentMode == 1; }
  /// Area mode on or off, with the picker PCL's area pick needs (as PCL's own `x` does).
  void setSelecting(bool on);
  bool band = false;                                // a rubber band was started by this press
  bool picked = false;                              // this press was a shift+click pick
  bool lasso = false;                               // this press draws a lasso
  vtkSmartPointer<vtkAbstractPicker> point_picker;  // kept while the area picker is in use
  bool replaying = false;  // keys come from a replay: as written, whatever Caps Lock says
  int caps_lock = -1;      // Caps Lock as the last Caps_Lock presses left it (-1: ask X)
  std::chrono::steady_clock::time_point caps_time;  // the last Caps_Lock press
  int askCapsLock();                                // Caps Lock as X has it now (0 or 1)
  void rubberBand(int& x0, int& y0, int& x1, int& y1) const {
    x0 = StartPosition[0];
    y0 = StartPosition[1];
    x1 = EndPosition[0];
    y1 = EndPosition[1];
  }
};

struct FrameStats {
  std::vector<double> solve, interpolate, render;
  std::size_t drawn = 0;  ///< points drawn (and interpolated) during the last drag
};

class Viewer {
 public:
  // --- state (viewer.cpp) -----------------------------------------------------------------
  /// `options`: the runner's (e.g. `deform.multires_above = 0` for --full-field).
  Viewer(const std::string& input, int width, int height, const hgd::RunOptions& options = {});
  ~Viewer();
  Viewer(const Viewer&) = delete;
  Viewer& operator=(const Viewer&) = delete;
  void loadScenario(const std::string& path);
  void printStats() const;

  // --- the window (viewer_draw.cpp) -------------------------------------------------------
  void open();
  void spin();
  /// After an opening frame drawn at the level of detail (a large cloud), draws it whole.
  void drawWhole();
  void screenshot(const std::string& path);

  // --- events (viewer_input.cpp) ----------------------------------------------------------
  bool key(const std::string& sym, char code);
  /// Caps Lock as the keyboard has it (shown beside the mode; named when it made a key capital).
  void setCapsLock(bool on);
  /// The current mode: "pick", "area", "lasso", "drag" or "frame".
  const char* mode() const;
  void pickAt(int x, int y, bool remove = false);
  void selectArea(int x0, int y0, int x1, int y1, bool remove = false);
  bool lassoing() const { return lasso_mode_; }
  void lassoBegin(int x, int y);
  void lassoMove(int x, int y);
  void lassoEnd(int x, int y, bool remove);
  /// < and >, ctrl+wheel: the points' size by `step` pixels (1 to 16).
  void changePointSize(int step);
  bool dragBegin(int x, int y);
  bool dragMove(int x, int y);
  bool dragging() const { return dragging_; }
  bool dragEnd(int x, int y);

  // --- replay (viewer_replay.cpp) ---------------------------------------------------------
  void replay(const std::vector<hgdview::ReplayEvent>& events, const std::string& path,
              vtkRenderWindowInteractor* iren);

  Style* style() { return style_.Get(); }
  pcl::visualization::PCLVisualizer& vis() { return *vis_; }

 private:
  // --- state changes (viewer.cpp) ---------------------------------------------------------
  void markSelection(int role);
  void buildDeformer();
  void finishHandles();
  /// Finishes a deformer built off the GUI thread, or says how long it has been building.
  void pollBuild();
  void waitForBuild();
  /// The deformer is there and not being built.
  bool ready() const { return !building_ && run_.ready(); }
  /// A change to save: a quit asked about before it must ask again.
  void markUnsaved(bool shape_moved = true) {
    unsaved_ = true;
    shape_unsaved_ = shape_unsaved_ || shape_moved;
    quit_asked_ = false;
  }
  void syncRegions();
  void clearSelection(bool redraw = true);
  void clearHandles();
  void keepForUndo(const std::string& what);
  void restoreCleared();
  void applyRestored();
  void updateAlerts(bool live = false);
  void commit(const hgd::Move& m);
  void frameMove(const Eigen::Vector3d& translate, const Eigen::Vector3d& axis, double degrees);
  void undo();
  void redo();
  /// Unsaved, alerts, `what` on the status line, redrawn: after undo, redo and resetShape.
  void shapeChanged(const std::string& what);
  void resetShape();
  void saveShape(const std::string& path);
  void saveScenario(const std::string& path);
  Eigen::Vector3d deformed(std::size_t i) const;
  Eigen::Vector3d centre() const;
  Eigen::Vector3d handleCentre() const;
  std::string defaultPath(const std::string& suffix, const std::string& ext) const;
  /// defaultPath(), numbered (-2, -3, ...) past every file that is there already.
  std::string freshPath(const std::string& suffix, const std::string& ext) const;
  void setMode(const std::string& mode);
  void requestQuit(char key);
  static std::string extensionOf(const std::string& path);
  static std::string num(double v);

  // --- drawing (viewer_draw.cpp) ----------------------------------------------------------
  void fileColours();
  /// Shading (light from the normals, or eye-dome lighting) on or off: the colours as they are.
  void setShading(bool on);
  void shade(const std::string& id, const std::vector<Eigen::Vector3f>* normals);
  void setMeshLighting(bool on);
  void refreshRoles();
  void refresh();
  void fillDisplay();
  void addShapeCloud();
  void drawHandles(const Eigen::Vector3f* role_colours, bool field_view);
  double shapePointSize() const;
  void updatePositions();
  void showLod(bool on);
  vtkPolyData* shapePolyData();
  vtkPolyData* cloudPolyData(const std::string& id);
  void render();
  static Eigen::Vector3f clusterColour(int id);

  // --- over the shape (viewer_overlays.cpp) -----------------------------------------------
  /// The lasso as drawn so far (none when lasso_ is empty).
  void drawLasso();
  /// The axes trihedron in the window's lower right corner.
  void showAxes(bool on);
  /// Places the help and the status line for the window's size (before every render).
  void placeOverlays();
  void updateStatus();
  /// `m` on the status line (and stderr unless quiet); drawn at once unless `draw` is false (the
  /// caller draws the frame it belongs to).
  void message(const std::string& m, bool draw = true);

  // --- the camera and geometry on screen (viewer_camera.cpp) -------------------------------
  void openingView();
  /// The up axis of up_option_ for this shape.
  Eigen::Vector3d upVector() const;
  /// 0 front, 1 back, 2 left, 3 right, 4 top, 5 bottom.
  void standardView(int which);
  /// The next up axis (u): +y, +z, +x, -y, -z, -x.
  void cycleUp();
  void setView(const Eigen::Vector3d& eye_direction, const Eigen::Vector3d& up);
  /// The opening view's eye direction for up axis `up` (unit): from the sensor's side for a scan
  /// in its sensor's frame, else the renderer's three-quarter view.
  Eigen::Vector3d defaultEye(const Eigen::Vector3d& up) const;
  vtkRenderer* renderer();
  Eigen::Vector3d toDisplay(const Eigen::Vector3d& w);
  Eigen::Vector3d fromDisplay(double x, double y, double depth);
  void cameraAxes(Eigen::Vector3d& up, Eigen::Vector3d& right, Eigen::Vector3d& view);
  int nearestOnScreen(int x, int y, double pixels, bool manipulated_only = false);

  // --- replay (viewer_replay.cpp) ---------------------------------------------------------
  Eigen::Vector2d screenOf(const hgdview::ReplayPosition& p);
  static int pixel(double v);
  void sendKey(vtkRenderWindowInteractor* iren, const std::string& key);
  void sendMouse(vtkRenderWindowInteractor* iren, unsigned long event, const Eigen::Vector2d& at,
                 bool shift = false);
  void replayEvent(const hgdview::ReplayEvent& e, vtkRenderWindowInteractor* iren);

 public:
  bool verbose_ = true;
  std::vector<std::string> inputs_;             // files no output may replace
  std::string up_option_ = "auto";              // --up: the opening view's up axis
  std::optional<Eigen::Vector3d> view_option_;  // --view: the opening view's eye direction
  bool drag_mode_ = false;
  bool keep_orientation_ = false;  // `l`: drags translate the handle without turning it
  int lod_points_ = 100000;        // --lod: points drawn during a drag of a larger cloud (0: all)

 private:
  std::string input_;
  int width_, height_;
  hgd::ScenarioRunner run_;  // the shape, its handles, the deformer, moves and undo
  double diagonal_ = 1, radius_ = 0.03;
  std::vector<hgd::Region> fixed_regions_, joint_regions_;
  hgd::Region manipulated_region_;
  hgd::Handles handles_;
  std::vector<char> role_, selected_;
  std::vector<Eigen::Vector3f> colours_;
  pcl::PointCloud<pcl::PointXYZRGB>::Ptr display_, rest_;
  std::unique_ptr<pcl::visualization::PCLVisualizer> vis_;
  vtkSmartPointer<Style> style_;
  vtkSmartPointer<vtkScalarBarActor> scale_bar_;
  int view_ = 0;
  bool overlay_ = false, overlay_shown_ = false, help_visible_ = false;
  bool lasso_mode_ = false, axes_shown_ = false, shading_ = true;
  std::vector<Eigen::Vector2d> lasso_;  // display pixels
  vtkSmartPointer<vtkActor2D> lasso_actor_;
  vtkSmartPointer<vtkOrientationMarkerWidget> axes_;
  bool frame_mode_ = false, dragging_ = false, live_shown_ = false, quit_ = false;
  bool async_builds_ = false;  // the interactive window builds the deformer off the GUI thread
  bool building_ = false;
  std::atomic<bool> build_done_{false};
  std::string build_error_;
  std::thread build_thread_;
  Clock::time_point build_start_, last_progress_;
  bool opening_ = false;        // inside open(): one render at its end
  bool opened_at_lod_ = false;  // the opening frame drew the level of detail (spin() draws it whole)
  bool timing_frame_ = false;   // a frame-mode key's render counts in --stats
  bool unsaved_ = false;        // moves or handles since the last save
  bool shape_unsaved_ = false;  // of which moves (the shape changed)
  bool quit_asked_ = false;     // q/e pressed once with unsaved changes
  /// What the last C or n threw away, for undo (the runner's history starts again after them).
  struct Cleared {
    hgd::Handles handles;
    std::vector<hgd::Region> fixed;
    hgd::Region manipulated;
    std::vector<hgd::Region> joints;
    std::vector<hgd::Move> moves;
    std::string what;
  };
  std::optional<Cleared> cleared_;
  std::optional<Cleared> restoring_;  // an undo of C: its moves, applied once the deformer is built
  std::size_t help_columns_ = 0;      // the width the help overlay is wrapped to
  std::vector<std::pair<std::string, char>> waiting_keys_;  // pressed during a build: run after it
  bool caps_lock_ = false;
  vtkSmartPointer<vtkTextActor> help_, status_, mode_label_;
  Eigen::Vector3d drag_from_, drag_last_;
  Eigen::Vector3d drag_press_;  // the pressed pixel at the picked point's depth: motions count from it
  double drag_depth_ = 0;
  std::string message_;
  std::string alert_;                  // see updateAlerts()
  std::vector<std::string> reported_;  // warnings already printed on stderr
  FrameStats stats_;
  std::vector<int> handle_points_;  // drawn again as marks with halos (drawHandles)
  std::vector<int> lod_;            // the drawn subset while dragging (empty: the whole shape is drawn)
  pcl::PointCloud<pcl::PointXYZRGB>::Ptr lod_display_;
  int multisamples_ = 0;  // the window's, restored after a drag drawn at a level of detail
};

}  // namespace hgdview
