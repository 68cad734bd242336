// hgdeform: command-line front end. Thin: every stage lives in the library.
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "blas_guard.h"
#include "hgdeform/deformer.h"
#include "hgdeform/fields.h"
#include "hgdeform/geometry.h"
#include "hgdeform/harmonic_field.h"
#include "hgdeform/io.h"
#include "hgdeform/regions.h"
#include "hgdeform/report.h"
#include "hgdeform/scenario.h"

namespace hgdcli {
/// `hgdeform batch` (tools/batch.cpp).
int runBatch(int argc, char** argv);
}  // namespace hgdcli

namespace {

const char* kUsage =
    "usage: hgdeform <command> [options]\n"
    "\n"
    "commands:\n"
    "  field   INPUT --scenario S.json -o OUT   write the harmonic field as a per-point scalar\n"
    "  deform  INPUT --scenario S.json -o OUT   deform the shape as the scenario's moves say\n"
    "  batch   --scenario S.json IN_DIR -o OUT_DIR   deform every scan in a folder\n"
    "\n"
    "INPUT and OUT are PLY, PCD, OBJ, XYZ/TXT, OFF or STL files: OUT by extension, INPUT by its\n"
    "content (a note says when that differs from the extension). 'hgdeform <command> --help' for options.\n";

const char* kFieldHelp =
    "usage: hgdeform field INPUT --scenario S.json -o OUT.ply|.pcd|.obj|.xyz|.txt|.off|.stl [options]\n"
    "\n"
    "Computes the harmonic field (1 on the manipulated handle, 0 on the fixed handles) and writes\n"
    "the shape with it as the per-point scalar 'harmonic' (all other fields kept).\n"
    "\n"
    "options:\n"
    "  -s, --scenario FILE   handles (README.md, section Scenarios); required\n"
    "  -o, --output FILE     output file; required; never the input\n"
    "  -k, --k N             neighbours per point for the Laplacian (default 10)\n"
    "      --solver NAME     auto | exact | multilevel (default auto)\n"
    "      --mesh-ring       on meshes, use the faces' 1-ring instead of kNN\n"
    "      --color           also write the field as a colour map (red/green/blue or rgb)\n"
    "      --ascii           write ascii instead of binary\n"
    "  -q, --quiet           no summary line\n"
    "  -h, --help            this help\n";

const char* kDeformHelp =
    "usage: hgdeform deform INPUT --scenario S.json -o OUT.ply|.pcd|.obj|.xyz|.txt|.off|.stl [options]\n"
    "\n"
    "Replays the scenario's move(s) (drag or frame) and writes the deformed shape: positions and\n"
    "normals change, every other field and the mesh faces are kept.\n"
    "\n"
    "options:\n"
    "  -s, --scenario FILE   handles and moves (README.md); required\n"
    "  -o, --output FILE     output file; required; never the input\n"
    "  -r, --report FILE     write a JSON report (points, clusters, iterations, energy, ms);\n"
    "                        - for stdout; a link is followed, a FIFO or device written to\n"
    "  -c, --clusters N      isoclusters (default: the scenario's, else 16)\n"
    "  -k, --k N             neighbours per point for the Laplacian (default 10)\n"
    "      --samples N       surface sample size for clustering (default 4000)\n"
    "      --blend MODE      rotation (default) | linear: how points blend cluster transforms\n"
    "      --joint-clusters N  skeletal mode: isoclusters inside each joint (default 3)\n"
    "      --solver NAME     field solver: auto | exact | multilevel (default auto)\n"
    "      --ascii           write ascii instead of binary\n"
    "  -q, --quiet           no summary line\n"
    "  -h, --help            this help\n";

struct Args {
  std::vector<std::string> positional;
  std::map<std::string, std::string> values;
  std::map<std::string, bool> flags;
};

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Parses "-x VALUE", "--name VALUE", "--name=VALUE" and flags. `with_value` lists the long
// names that take a value; `aliases` maps short to long names.
Args parseArgs(int argc, char** argv, const std::vector<std::string>& with_value,
               const std::vector<std::string>& flag_names,
               const std::map<std::string, std::string>& aliases) {
  Args a;
  auto isIn = [](const std::vector<std::string>& v, const std::string& s) {
    return std::find(v.begin(), v.end(), s) != v.end();
  };
  for (int i = 0; i < argc; ++i) {
    std::string s = argv[i];
    if (s.size() > 1 && s[0] == '-' &&
        !(s.size() > 1 && (std::isdigit(static_cast<unsigned char>(s[1])) || s[1] == '.'))) {
      std::string value;
      bool has_value = false;
      const auto eq = s.find('=');
      if (s.rfind("--", 0) == 0 && eq != std::string::npos) {
        value = s.substr(eq + 1);
        s = s.substr(0, eq);
        has_value = true;
      }
      if (auto al = aliases.find(s); al != aliases.end()) s = al->second;
      const std::string name = s.rfind("--", 0) == 0 ? s.substr(2) : s;
      if (isIn(with_value, name)) {
        if (!has_value) {
          if (i + 1 >= argc) throw UsageError("option --" + name + " needs a value");
          value = argv[++i];
        }
        a.values[name] = value;
      } else if (isIn(flag_names, name) && !has_value) {
        a.flags[name] = true;
      } else {
        throw UsageError("unknown option '" + std::string(argv[i]) + "'");
      }
    } else {
      a.positional.push_back(s);
    }
  }
  return a;
}

int intOption(const Args& a, const std::string& name, int fallback, int lo, int hi) {
  auto it = a.values.find(name);
  if (it == a.values.end()) return fallback;
  char* end = nullptr;
  const long v = std::strtol(it->second.c_str(), &end, 10);
  if (it->second.empty() || *end != '\0' || v < lo || v > hi)
    throw UsageError("--" + name + " must be an integer from " + std::to_string(lo) + " to " +
                     std::to_string(hi) + " (got '" + it->second + "')");
  return static_cast<int>(v);
}

hgd::FieldSolver solverOption(const Args& a) {
  auto it = a.values.find("solver");
  if (it == a.values.end() || it->second == "auto") return hgd::FieldSolver::Auto;
  if (it->second == "exact") return hgd::FieldSolver::Exact;
  if (it->second == "multilevel") return hgd::FieldSolver::Multilevel;
  throw UsageError("--solver must be auto, exact or multilevel (got '" + it->second + "')");
}

const std::string& required(const Args& a, const std::string& name) {
  auto it = a.values.find(name);
  if (it == a.values.end()) throw UsageError("--" + name + " is required");
  return it->second;
}

std::string singleInput(const Args& a) {
  if (a.positional.size() != 1)
    throw UsageError(a.positional.empty()
                         ? "missing INPUT file"
                         : "expected one INPUT file, got " + std::to_string(a.positional.size()));
  return a.positional[0];
}

int runField(int argc, char** argv) {
  const Args a = parseArgs(
      argc, argv, {"scenario", "output", "k", "solver"}, {"mesh-ring", "color", "ascii", "quiet", "help"},
      {{"-s", "--scenario"}, {"-o", "--output"}, {"-k", "--k"}, {"-q", "--quiet"}, {"-h", "--help"}});
  if (a.flags.count("help")) {
    std::cout << kFieldHelp;
    return 0;
  }
  const std::string input = singleInput(a);
  const std::string& scenario_path = required(a, "scenario");
  const std::string& output = required(a, "output");
  hgd::formatFromPath(output);  // fail on a bad extension before any work
  hgd::refuseInputs(output, {input, scenario_path});

  hgd::FieldOptions opt;
  opt.k_neighbors = intOption(a, "k", opt.k_neighbors, 2, 100);
  opt.solver = solverOption(a);
  opt.mesh_ring = a.flags.count("mesh-ring") > 0;

  const auto t0 = std::chrono::steady_clock::now();
  const hgd::Scenario scenario = hgd::readScenario(scenario_path);
  hgd::Shape shape = hgd::readShape(input);
  for (const std::string& w : shape.warnings) std::fprintf(stderr, "hgdeform: warning: %s\n", w.c_str());
  const hgd::Geometry geometry = hgd::extractGeometry(shape);
  const hgd::Handles handles = hgd::resolveHandles(scenario, geometry);
  const double read_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();

  hgd::HarmonicField field;
  field.setInputCloud(geometry.points);
  if (geometry.hasFileNormals()) field.setInputNormals(geometry.file_normals);
  if (!geometry.faces.empty()) field.setPolygons(geometry.faces);
  opt.orient_to_viewpoint = shape.isOrganized();
  opt.viewpoint = (shape.sensor_origin.head<3>().cast<double>() - geometry.origin).cast<float>();
  field.setOptions(opt);
  field.setHandles(handles.fixed, handles.manipulated);
  std::vector<float> phi;
  field.compute(phi);

  hgd::storeField(shape, geometry, phi, "harmonic", a.flags.count("color") > 0);
  if (const std::string lost = hgd::extrasLost(shape, hgd::formatFromPath(output)); !lost.empty())
    std::fprintf(stderr, "hgdeform: warning: %s: %s\n", output.c_str(), lost.c_str());
  hgd::WriteOptions wo;
  if (a.flags.count("ascii")) wo.encoding = hgd::Encoding::Ascii;
  hgd::writeShape(output, shape, wo);

  if (!a.flags.count("quiet")) {
    const auto& t = field.timings();
    std::size_t fixed_points = 0;
    for (const auto& f : handles.fixed) fixed_points += f.size();
    std::printf(
        "%s: %zu points, %zu fixed handle(s) (%zu points), manipulated %zu points, %zu unreachable; "
        "read %.0f ms, knn %.0f ms, normals %.0f ms, graph %.0f ms, laplacian %.0f ms, solve %.0f ms (%s), "
        "field "
        "%.0f ms -> %s\n",
        input.c_str(), geometry.size(), handles.fixed.size(), fixed_points, handles.manipulated.size(),
        field.unreachable().size(), read_ms, t.knn_ms, t.normals_ms, t.graph_ms, t.laplacian_ms, t.solve_ms,
        t.exact ? "exact" : ("multilevel, " + std::to_string(t.iterations) + " iterations").c_str(),
        t.total(), output.c_str());
  }
  if (!field.unreachable().empty())
    std::fprintf(stderr,
                 "hgdeform: warning: %zu points lie in parts that touch no handle; their field is 0\n",
                 field.unreachable().size());
  return 0;
}

int runDeform(int argc, char** argv) {
  const Args a = parseArgs(
      argc, argv,
      {"scenario", "output", "report", "clusters", "k", "samples", "solver", "blend", "joint-clusters"},
      {"ascii", "quiet", "help"},
      {{"-s", "--scenario"},
       {"-o", "--output"},
       {"-r", "--report"},
       {"-c", "--clusters"},
       {"-k", "--k"},
       {"-q", "--quiet"},
       {"-h", "--help"}});
  if (a.flags.count("help")) {
    std::cout << kDeformHelp;
    return 0;
  }
  const std::string input = singleInput(a);
  const std::string& scenario_path = required(a, "scenario");
  const std::string& output = required(a, "output");
  hgd::formatFromPath(output);
  // No output replaces an input, nor the report the output, however spelt; "-" is stdout.
  hgd::refuseInputs(output, {input, scenario_path});
  const auto report_it = a.values.find("report");
  const std::string report_path = report_it == a.values.end() ? "" : report_it->second;
  if (!report_path.empty() && report_path != "-") {
    hgd::refuseInputs(report_path, {input, scenario_path});
    if (hgd::samePath(report_path, output))
      throw UsageError("--report " + report_path + " would replace the output " + output);
  }

  hgd::DeformOptions opt;
  opt.field.k_neighbors = intOption(a, "k", opt.field.k_neighbors, 2, 100);
  opt.field.solver = solverOption(a);
  opt.clusters.samples = intOption(a, "samples", opt.clusters.samples, 10, 10000000);
  const int clusters_override = intOption(a, "clusters", 0, 1, 1000);
  opt.clusters.joint_isoclusters = intOption(a, "joint-clusters", opt.clusters.joint_isoclusters, 1, 100);

  hgd::Scenario scenario = hgd::readScenario(scenario_path);
  if (clusters_override > 0) scenario.clusters = clusters_override;
  if (auto it = a.values.find("blend"); it != a.values.end()) {
    if (it->second != "linear" && it->second != "rotation")
      throw UsageError("--blend must be linear or rotation (got '" + it->second + "')");
    scenario.blend = it->second;  // the command line wins over the scenario
  }
  const auto t0 = std::chrono::steady_clock::now();
  hgd::Shape shape = hgd::readShape(input);
  const double read_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  hgd::WriteOptions wo;
  if (a.flags.count("ascii")) wo.encoding = hgd::Encoding::Ascii;
  hgd::DeformReport report = hgd::deformShape(shape, scenario, opt);
  report.warnings.insert(report.warnings.begin(), shape.warnings.begin(), shape.warnings.end());
  if (const std::string lost = hgd::extrasLost(shape, hgd::formatFromPath(output)); !lost.empty())
    report.warnings.push_back(output + ": " + lost);
  report.read_ms = read_ms;  // reading is part of everything before the first solve
  report.build_ms += read_ms;
  report.total_ms += read_ms;
  hgd::writeShape(output, shape, wo);
  // A failed run leaves no output: when the report cannot be written, the shape goes too.
  if (!report_path.empty()) {
    try {
      if (report_path == "-") {
        const std::string json = hgd::reportJson(report);
        if (std::fwrite(json.data(), 1, json.size(), stdout) != json.size() || std::fflush(stdout) != 0)
          throw hgd::IoError("-: cannot write the report to standard output");
      } else {
        hgd::writeReportJson(report_path, report);
      }
    } catch (...) {
      hgd::removeOutput(output);
      throw;
    }
  }
  for (const auto& note : report.notes) std::fprintf(stderr, "hgdeform: note: %s\n", note.c_str());
  for (const auto& w : report.warnings) std::fprintf(stderr, "hgdeform: warning: %s\n", w.c_str());
  // With the report on stdout, the summary goes to stderr so that stdout stays JSON.
  if (!a.flags.count("quiet"))
    std::fprintf(report_path == "-" ? stderr : stdout, "%s -> %s: %s\n", input.c_str(), output.c_str(),
                 hgd::summaryLine(report).c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (const std::string problem = hgdcli::reserveBlasBuffer(argv); !problem.empty()) {
    std::cerr << "hgdeform" << (argc > 1 ? std::string(" ") + argv[1] : std::string()) << ": " << problem
              << "\n";
    return 1;
  }
  hgdcli::singleThreadBlas();
  if (argc < 2) {
    std::cerr << kUsage;
    return 2;
  }
  const std::string cmd = argv[1];
  if (cmd == "-h" || cmd == "--help" || cmd == "help") {
    std::cout << kUsage;
    return 0;
  }
  try {
    if (cmd == "field") return runField(argc - 2, argv + 2);
    if (cmd == "deform") return runDeform(argc - 2, argv + 2);
    if (cmd == "batch") return hgdcli::runBatch(argc - 2, argv + 2);
    std::cerr << "hgdeform: unknown command '" << cmd << "'\n" << kUsage;
    return 2;
  } catch (const UsageError& e) {
    std::cerr << "hgdeform " << cmd << ": " << e.what() << "\n(see 'hgdeform " << cmd << " --help')\n";
    return 2;
  } catch (const std::bad_alloc&) {
    std::cerr << "hgdeform " << cmd << ": out of memory\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "hgdeform " << cmd << ": " << e.what() << "\n";
    return 1;
  }
}
