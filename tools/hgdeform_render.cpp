// hgdeform-render: off-screen pictures of shapes (for the README, reports and thumbnails).
//
//   hgdeform-render IN.ply [IN2.ply ...] -o OUT.png [--field harmonic] [--size 1200x600]
//                   [--view x,y,z] [--up x|y|z|-x|-y|-z|auto] [--title "a" --title "b" ...]
//                   [--displacement REST.ply] [--scenario S.json]
//
// Each input gets its own viewport, side by side, all seen from the same direction. A mesh is
// drawn as a surface, a cloud as points; colours come from the scalar field named by --field
// (blue to red), else from the file's colours, else a neutral grey. A cloud is shaded: lit
// through its normals when it has them, else with eye-dome lighting (hgd::shadeCloud, as in the
// viewer). --displacement REST colours each input by the distance of its points from the same
// points of REST (with a colour bar), --scenario marks the handles its regions select. Needs an
// X display (run under xvfb-run on a headless machine).
#include <cstdio>
#include <iostream>
#include <new>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli_common.h"
#include "hgdeform/app/regions.h"
#include "hgdeform/app/scenario.h"
#include "hgdeform/io/cleanup.h"
#include "hgdeform/io/fields.h"
#include "hgdeform/io/geometry.h"
#include "hgdeform/io/io.h"
#include "hgdeform/render/render.h"
#include "render_options.h"

int main(int argc, char** argv) {
  hgd::removeTemporaryFilesOnSignals();  // no partial picture left by an interrupted run
  std::vector<std::string> inputs;
  std::string output;
  hgd::RenderOptions opt;
  CLI::App app(
      "Off-screen pictures of shapes. Each input gets its own viewport, side by side, all seen from\n"
      "the same direction. A mesh is drawn as a surface, a cloud as points; colours come from the\n"
      "scalar field named by --field (blue to red), else from the file's colours, else a neutral\n"
      "grey. A cloud is shaded: lit through its normals when it has them, else with eye-dome\n"
      "lighting. Needs an X display (run under xvfb-run on a headless machine).");
  hgdcli::configureApp(app, "hgdeform-render");
  app.add_option("IN", inputs,
                 "shapes to draw (PLY, PCD, OBJ, XYZ/TXT, PTS, LAS, OFF or STL), one viewport each")
      ->required()
      ->type_name("")
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  app.add_option("-o,--output", output, "the PNG to write; never an input")->required()->type_name("OUT.png");
  app.add_option("--field", opt.field, "colour by this per-point scalar (e.g. harmonic)")->type_name("NAME");
  hgdcli::addSizeOption(app, "picture size, 16x16 to 16384x16384 (default 1200x600)", 16,
                        hgd::kMaxPictureSide, opt.width, opt.height);
  hgdcli::addViewOption(
      app, opt.view,
      "direction from the target to the eye (default: 1,0.6,1.4 turned with --up; with --up "
      "auto across the shape's broad side; with --displacement the side where the motion "
      "shows best)");
  hgdcli::addUpOption(
      app, opt.up,
      "the axis that points up in the picture: x|y|z|-x|-y|-z|auto (default auto: -y when the "
      "first input is a camera-frame scan, i.e. organized (height > 1), a PCD with a sensor "
      "pose, or every point ahead of the origin within 60 degrees of +z; z when its points spread clearly "
      "least along y (a z-up model); else y)");
  std::string rest_path, scenario_path;
  app.add_option("--displacement", rest_path,
                 "colour each input by its points' distance from the same points (file order) of REST, "
                 "the rest shape (same point count), with a colour bar; the view faces the side where "
                 "the motion shows best. An input that is REST itself keeps its own colours")
      ->type_name("REST");
  app.add_option("--scenario", scenario_path,
                 "mark the handles this scenario's regions select (on REST when given, else on the "
                 "first input): fixed black, manipulated magenta")
      ->type_name("S.json");
  app.add_option("--title", opt.titles, "a title per viewport, in the inputs' order (repeat the option)")
      ->type_name("T")
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll)
      ->allow_extra_args(false);  // one title per --title: what follows is an input again
  if (const int status = hgdcli::parse(app, argc, argv); status >= 0) return status;
  try {
    hgd::refuseInputs(output, inputs);
    // Before the display: a picture too large is refused the same with or without one.
    if (const std::string problem = hgd::pictureSizeProblem(opt.width, opt.height); !problem.empty())
      throw std::runtime_error(output + ": " + problem);
    std::vector<hgd::Shape> shapes;
    for (const auto& in : inputs) {
      shapes.push_back(hgd::readShape(in));
      for (const std::string& w : shapes.back().warnings)
        std::cerr << "hgdeform-render: warning: " << w << "\n";
    }
    // A field to colour by that an input does not have is a mistake in the command, not a
    // picture without colours.
    if (!opt.field.empty())
      for (std::size_t k = 0; k < shapes.size(); ++k)
        if (hgd::findField(shapes[k].cloud, opt.field) < 0)
          throw hgdcli::UsageError("--field " + opt.field + ": " + inputs[k] + " has no field '" + opt.field +
                                   "'");
    std::vector<const hgd::Shape*> ptrs;
    for (const auto& s : shapes) ptrs.push_back(&s);
    hgd::Shape rest;
    if (!rest_path.empty()) {
      rest = hgd::readShape(rest_path);
      // An input that is the rest file itself is drawn as it is (its displacement is zero).
      for (std::size_t k = 0; k < inputs.size(); ++k)
        if (inputs[k] == rest_path) ptrs[k] = &rest;
      for (const hgd::Shape* s : ptrs)
        if (s != &rest) hgd::displacementFrom(rest, *s);  // a mismatch is refused before anything is drawn
      opt.displacement_rest = &rest;
    }
    if (!scenario_path.empty()) {
      const hgd::Shape& base = rest_path.empty() ? shapes.front() : rest;
      const hgd::Geometry g = hgd::extractGeometry(base);
      const hgd::Handles h = hgd::resolveHandles(hgd::readScenario(scenario_path), g, base);
      for (const auto& f : h.fixed)
        for (const int i : f) opt.fixed_points.push_back(g.raw_index[static_cast<std::size_t>(i)]);
      for (const int i : h.manipulated)
        opt.manipulated_points.push_back(g.raw_index[static_cast<std::size_t>(i)]);
    }
    // The inputs are read and checked first: their errors are the same with or without a display.
    if (const std::string problem = hgd::displayProblem(); !problem.empty())
      throw std::runtime_error(problem);
    hgd::renderPng(ptrs, output, opt);
    std::cout << "wrote " << output << "\n";
    return 0;
  } catch (const hgdcli::UsageError& e) {
    return hgdcli::usageError("hgdeform-render", e.what());
  } catch (const std::bad_alloc&) {  // what pictureSizeProblem could not foresee
    std::cerr << "hgdeform-render: " << output << ": out of memory drawing a " << opt.width << "x"
              << opt.height << " picture\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "hgdeform-render: " << e.what() << "\n";
    return 1;
  }
}
