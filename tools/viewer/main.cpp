// hgdeform-view: the interactive front end. Pick handles, drag, see it live.
//
//   hgdeform-view INPUT [--scenario S.json] [--replay EVENTS.json] [--screenshot OUT.png]
//                 [--size WxH] [--stats] [--lod N] [--full-field]
//
// One mode at a time, shown at the start of the status line: pick (the mouse turns the view),
// area, drag or frame. The keys, and what each does when, are one table (keys.cpp): the help
// overlay ('h'), --help and the input handling are made of it. Shift and Caps Lock make capitals
// as on any keyboard. PCL's and VTK's own keys are off.
//
// --replay plays a script of events (picks, keys, drags in screen or world coordinates) and
// exits; with --screenshot it saves a picture at the end. The replay format, checked as a whole
// before the first event runs (tools/viewer/replay.cpp), is in docs/replay.md. Every committed
// drag is applied the way `hgdeform deform` replays a scenario's drag, so a saved session
// replays to the same shape.
//
// The viewer's code follows the pipeline, one file per stage: see tools/viewer/viewer.h.
#include <vtkRenderWindow.h>

#include <cstdio>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "blas_guard.h"
#include "cli_common.h"
#include "hgdeform/io/cleanup.h"
#include "hgdeform/io/io.h"
#include "hgdeform/render/render.h"
#include "keys.h"
#include "render_options.h"
#include "replay.h"
#include "viewer.h"

namespace {

using hgdview::Viewer;

const char* kDescription =
    "Opens a shape for interactive deformation; 'h' in the window lists the keys.\n"
    "--replay plays a script of events and exits (the whole file is checked first); with\n"
    "--screenshot it then saves a PNG, with --stats it prints frame timings. The replay format\n"
    "and how the options combine: docs/replay.md.";

/// hgdeform-view's command line.
struct ViewArgs {
  std::string input, scenario, replay, shot;
  int width = 1100, height = 800;
  bool stats = false, quiet = false, full_field = false;
  int lod = 100000;
  std::string up = "auto";
  std::optional<Eigen::Vector3f> view;
};

/// Parses the command line into `a`; returns -1 to go on, else the exit status.
int parseArgs(int argc, char** argv, ViewArgs& a) {
  CLI::App app(kDescription);
  hgdcli::configureApp(app, "hgdeform-view");
  app.add_option("INPUT", a.input, "the shape: PLY, PCD, OBJ, XYZ/TXT, PTS, LAS, OFF or STL")
      ->required()
      ->type_name("");
  app.add_option("-s,--scenario", a.scenario, "handles to load (docs/scenario.md)")->type_name("S.json");
  app.add_option("--replay", a.replay, "play a script of events, then exit (docs/replay.md)")
      ->type_name("EVENTS.json");
  app.add_option("--screenshot", a.shot, "save a PNG (after the replay, if any) and exit")
      ->type_name("OUT.png");
  hgdcli::addSizeOption(app, "window size (default 1100x800)", 64, hgd::kMaxPictureSide, a.width, a.height);
  app.add_flag("--stats", a.stats, "print frame timings");
  app.add_option("--lod", a.lod,
                 "while dragging a larger point cloud, draw and interpolate only this many of its points "
                 "(0: all; default 100000)")
      ->check(CLI::Range(0, 1000000000))
      ->type_name("N");
  app.add_flag("--full-field", a.full_field,
               "the field, pieces and clusters over every point, however many (as hgdeform deform "
               "--full-field; default: above 131,072 points on a coarse level)");
  hgdcli::addUpOption(
      app, a.up,
      "the axis that points up in the opening view, as hgdeform-render's: x|y|z|-x|-y|-z|auto "
      "(default auto: -y for a camera-frame scan, z for a shape clearly thinnest along y, else y)");
  hgdcli::addViewOption(
      app, a.view,
      "direction from the shape to the eye in the opening view (default: a camera-frame "
      "scan from its sensor's side, anything else in hgdeform-render's three-quarter view)");
  app.add_flag("-q,--quiet", a.quiet, "print nothing but errors");
  app.add_flag_callback(
      "--keys-markdown",
      [] {
        std::fputs(hgdview::keysMarkdown().c_str(), stdout);
        throw CLI::Success();
      },
      "print the keys as README.md's Markdown table and exit");
  app.footer(hgdview::keysHelp() + "\n" + app.get_footer());
  return hgdcli::parse(app, argc, argv);
}

}  // namespace

int main(int argc, char** argv) {
  hgd::removeTemporaryFilesOnSignals();  // no partial save or screenshot left by an interrupted run
  hgdcli::singleThreadBlas();            // as hgdeform does (blas_guard.h)
  ViewArgs args;
  if (const int status = parseArgs(argc, argv, args); status >= 0) return status;
  const std::string &input = args.input, &scenario = args.scenario, &replay = args.replay, &shot = args.shot;
  const int width = args.width, height = args.height;
  const bool stats = args.stats, quiet = args.quiet;
  try {
    // No output of the viewer (screenshots, saved shapes and scenarios, from keys or replay
    // events) may replace one of its inputs.
    const std::vector<std::string> inputs = {input, scenario, replay};
    if (!shot.empty()) hgd::refuseInputs(shot, inputs);
    // The whole replay is checked before anything runs (no display needed): a bad event late in
    // the file does nothing at all, not even the events before it.
    std::vector<hgdview::ReplayEvent> events;
    if (!replay.empty()) {
      events = hgdview::readReplay(replay);
      hgdview::refuseInputsAsOutputs(events, replay, inputs);
    }
    if (const std::string problem = hgd::displayProblem(); !problem.empty())
      throw std::runtime_error(problem);
    const auto start = hgdview::Clock::now();
    hgd::RunOptions run_options;
    if (args.full_field) run_options.deform.multires_above = 0;
    Viewer viewer(input, width, height, run_options);
    const double read_ms = hgdview::msSince(start);
    viewer.verbose_ = !quiet;
    viewer.inputs_ = inputs;
    viewer.lod_points_ = args.lod;
    viewer.up_option_ = args.up;
    if (args.view) viewer.view_option_ = args.view->cast<double>();
    if (!scenario.empty()) viewer.loadScenario(scenario);
    const auto opening = hgdview::Clock::now();
    viewer.open();
    viewer.vis().setSize(width, height);  // the first render may shrink the window
    if (stats)
      std::printf("opened: read %.0f ms, first frame %.0f ms after reading\n", read_ms,
                  hgdview::msSince(opening));
    if (!replay.empty() || !shot.empty()) viewer.drawWhole();  // pictures of the whole shape
    if (!replay.empty()) {
      viewer.replay(events, replay, viewer.vis().getRenderWindow()->GetInteractor());
      if (!shot.empty()) viewer.screenshot(shot);
      if (stats) viewer.printStats();
      return 0;  // scripted: no interactive loop (and no close(), which crashes without one)
    }
    if (!shot.empty()) {
      viewer.screenshot(shot);
      return 0;
    }
    viewer.spin();
    if (stats) viewer.printStats();
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "hgdeform-view: " << e.what() << "\n";
    return 1;
  }
}
