// hgdeform-render: off-screen pictures of shapes (for the README, reports and thumbnails).
//
//   hgdeform-render IN.ply [IN2.ply ...] -o OUT.png [--field harmonic] [--size 1200x600]
//                   [--view x,y,z] [--title "a" --title "b" ...]
//
// Each input gets its own viewport, side by side, all seen from the same direction. A mesh is
// drawn as a surface, a cloud as points; colours come from the scalar field named by --field
// (blue to red), else from the file's colours, else a neutral grey. Needs an X display (run
// under xvfb-run on a headless machine).
#include <cstdio>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "hgdeform/io.h"
#include "hgdeform/render.h"

int main(int argc, char** argv) {
  std::vector<std::string> inputs;
  std::string output;
  hgd::RenderOptions opt;
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      auto next = [&]() -> std::string {
        if (i + 1 >= argc) throw std::runtime_error(a + " needs a value");
        return argv[++i];
      };
      if (a == "-o" || a == "--output") {
        output = next();
      } else if (a == "--field") {
        opt.field = next();
      } else if (a == "--title") {
        opt.titles.push_back(next());
      } else if (a == "--size") {
        const std::string s = next();
        if (std::sscanf(s.c_str(), "%dx%d", &opt.width, &opt.height) != 2 || opt.width < 16 ||
            opt.height < 16)
          throw std::runtime_error("--size must be WIDTHxHEIGHT");
      } else if (a == "--view") {
        const std::string s = next();
        if (std::sscanf(s.c_str(), "%f,%f,%f", &opt.view.x(), &opt.view.y(), &opt.view.z()) != 3 ||
            opt.view.norm() == 0)
          throw std::runtime_error("--view must be x,y,z");
      } else if (a == "-h" || a == "--help") {
        std::cout
            << "usage: hgdeform-render IN [IN ...] -o OUT.png [--field NAME] [--size WxH] [--view x,y,z] "
               "[--title T ...]\n";
        return 0;
      } else if (!a.empty() && a[0] == '-') {
        throw std::runtime_error("unknown option '" + a + "'");
      } else {
        inputs.push_back(a);
      }
    }
    if (inputs.empty() || output.empty()) throw std::runtime_error("need at least one input and -o OUT.png");
    hgd::refuseInputs(output, inputs);
    if (const std::string problem = hgd::displayProblem(); !problem.empty())
      throw std::runtime_error(problem);
    std::vector<hgd::Shape> shapes;
    for (const auto& in : inputs) {
      shapes.push_back(hgd::readShape(in));
      for (const std::string& w : shapes.back().warnings)
        std::cerr << "hgdeform-render: warning: " << w << "\n";
    }
    std::vector<const hgd::Shape*> ptrs;
    for (const auto& s : shapes) ptrs.push_back(&s);
    hgd::renderPng(ptrs, output, opt);
    std::cout << "wrote " << output << "\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "hgdeform-render: " << e.what() << "\n";
    return 1;
  }
}
