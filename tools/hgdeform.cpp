// hgdeform: command-line front end. Thin: every stage lives in the library.
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "blas_guard.h"
#include "cli_common.h"
#include "hgdeform/app/memory.h"
#include "hgdeform/app/regions.h"
#include "hgdeform/app/report.h"
#include "hgdeform/app/runner.h"
#include "hgdeform/app/scenario.h"
#include "hgdeform/app/stream.h"
#include "hgdeform/deformer/deformer.h"
#include "hgdeform/field/harmonic_field.h"
#include "hgdeform/io/cleanup.h"
#include "hgdeform/io/fields.h"
#include "hgdeform/io/geometry.h"
#include "hgdeform/io/io.h"
#include "hgdeform/io/records.h"
#include "huge_pages.h"
#include "stream_mpi.h"
#include "stream_progress.h"

namespace hgdcli {
/// `hgdeform batch` (tools/batch/batch.cpp); argv[0] is "batch", the options follow.
int runBatch(int argc, char** argv);
}  // namespace hgdcli

namespace {

// Inputs from this size (a float x/y/z PLY of some 700,000 points) run with glibc's huge-page
// malloc (huge_pages.h): a 1M-point command on two threads took 417 ms without it, 383 ms
// restarting for it and 359 ms with it set beforehand; the restart costs about 10 ms, more than
// a 200,000-point run gains.
constexpr std::uintmax_t kHugePageInput = std::uintmax_t{8} << 20;

const char* kUsage =
    "usage: hgdeform <command> [options]\n"
    "\n"
    "commands:\n"
    "  field   INPUT --scenario S.json -o OUT   write the harmonic field as a per-point scalar\n"
    "  deform  INPUT --scenario S.json -o OUT   deform the shape as the scenario's moves say\n"
    "  batch   --scenario S.json IN_DIR -o OUT_DIR   deform every scan in a folder\n"
    "\n"
    "INPUT and OUT are PLY, PCD, OBJ, XYZ/TXT, PTS, LAS, OFF or STL files: OUT by extension, INPUT by its\n"
    "content (a note says when that differs from the extension). 'hgdeform <command> --help' for options.\n"
    "\n"
    "options:\n"
    "  -h, --help    this help\n"
    "  --version     print \"hgdeform VERSION\" and exit (also after a command)\n"
    "\n"
    "Exit status: 0 on success, 1 when the work failed, 2 on usage errors.\n";

// --- parsing: the command line into a struct, nothing else -------------------------------------

/// `hgdeform field`'s command line.
struct FieldArgs {
  std::string input, scenario, output;
  int k = hgd::FieldOptions().k_neighbors;
  std::string solver = "auto";
  bool mesh_ring = false, colour = false, ascii = false, quiet = false;
};

/// `hgdeform deform`'s command line (0 for the counts left to the scenario or the library).
struct DeformArgs {
  std::string input, scenario, output, report;
  int clusters = 0;  // 0: the scenario's
  int k = hgd::FieldOptions().k_neighbors;
  int samples = hgd::DeformOptions().clusters.samples;
  int joint_clusters = hgd::DeformOptions().clusters.joint_isovalues;
  int reweight = hgd::DeformOptions().gauss_newton.reweight_rounds;
  bool stream = false;  // --stream
  bool mpi = false;     // --mpi
  std::string blend;    // empty: the scenario's
  std::string solver = "auto";
  std::string memory;  // --memory: empty for the memory the machine has available
  bool mesh_ring = false, full_field = false, ascii = false, quiet = false;
};

/// A command's conventions (hgdcli::configureApp) and the options every command has.
void setUpCommand(CLI::App& app, const std::string& tool, std::string& input, std::string& scenario,
                  std::string& output, const std::string& scenario_help) {
  hgdcli::configureApp(app, tool);
  app.add_option("INPUT", input,
                 "the shape: PLY, PCD, OBJ, XYZ/TXT, PTS, LAS, OFF or STL (read by its content)")
      ->required()
      ->type_name("");
  app.add_option("-s,--scenario", scenario, scenario_help)->required()->type_name("FILE");
  app.add_option("-o,--output", output,
                 "output file (.ply, .pcd, .obj, .xyz, .txt, .off, .stl); required; never the input")
      ->required()
      ->type_name("FILE");
}

void addNeighbours(CLI::App& app, int& k) {
  hgdcli::addCount(app, "-k,--k", k, "neighbours per point for the Laplacian (default 10)", 2, 100);
}

void addOutputFlags(CLI::App& app, bool& ascii, bool& quiet) {
  app.add_flag("--ascii", ascii, "write ascii instead of binary");
  app.add_flag("-q,--quiet", quiet, "no summary line");
}

void addSolver(CLI::App& app, std::string& solver, const std::string& what) {
  app.add_option("--solver", solver, what + "auto | exact | multilevel (default auto)")
      ->check(hgdcli::oneOf({"auto", "exact", "multilevel"}))
      ->type_name("NAME");
}

/// Parses `hgdeform field ARGS`; returns -1 to go on, else the exit status.
int parseField(int argc, const char* const* argv, FieldArgs& a) {
  CLI::App app(
      "Computes the harmonic field (1 on the manipulated handle, 0 on the fixed handles) and writes\n"
      "the shape with it as the per-point scalar 'harmonic' (all other fields kept).");
  setUpCommand(app, "hgdeform field", a.input, a.scenario, a.output, "handles (docs/scenario.md); required");
  addNeighbours(app, a.k);
  addSolver(app, a.solver, "");
  app.add_flag("--mesh-ring", a.mesh_ring, "on meshes, use the faces' 1-ring instead of kNN");
  app.add_flag("--colour,--color", a.colour, "also write the field as a colour map (red/green/blue or rgb)");
  addOutputFlags(app, a.ascii, a.quiet);
  return hgdcli::parse(app, argc, argv);
}

/// Parses `hgdeform deform ARGS`; returns -1 to go on, else the exit status.
int parseDeform(int argc, const char* const* argv, DeformArgs& a) {
  CLI::App app(
      "Replays the scenario's move(s) (drag or frame) and writes the deformed shape: positions and\n"
      "normals change, every other field and the mesh faces are kept.");
  setUpCommand(app, "hgdeform deform", a.input, a.scenario, a.output,
               "handles and moves (docs/scenario.md); required");
  app.add_option("-r,--report", a.report,
                 "write a JSON report (version, points, clusters, iterations, energy, ms);\n"
                 "- for stdout; a link is followed, a FIFO or device written to")
      ->type_name("FILE");
  hgdcli::addCount(app, "-c,--clusters", a.clusters,
                   "isovalue count: isoclusters per branch (default: the scenario's, else 16)", 1, 1000);
  addNeighbours(app, a.k);
  hgdcli::addCount(app, "--samples", a.samples, "surface sample size for clustering (default 4000)", 10,
                   10000000);
  app.add_option("--blend", a.blend, "rotation (default) | linear: how points blend cluster transforms")
      ->check(hgdcli::oneOf({"linear", "rotation"}))
      ->type_name("MODE");
  hgdcli::addCount(app, "--reweight", a.reweight,
                   "reweight E_Prop per cluster pair over N rounds (default 0, the paper's solve): bends\n"
                   "at joints, closer to ARAP, each frame several times slower; a sharp bend of a thin\n"
                   "part can be pulled apart (the report says where; docs/method.md)",
                   0, 100);
  hgdcli::addCount(app, "--joint-clusters", a.joint_clusters,
                   "skeletal mode: isovalues inside each joint (default 3)", 1, 100);
  addSolver(app, a.solver, "field solver: ");
  app.add_flag("--mesh-ring", a.mesh_ring,
               "on meshes, the field's graph is the faces' 1-ring instead of kNN (at full resolution)");
  app.add_flag("--full-field", a.full_field,
               "the field, pieces and clusters over every point, however many (default: above 131,072\n"
               "points, on a subsample of about 65,536 or a tenth of the points, prolonged to every point)");
  app.add_flag("--stream", a.stream,
               "stream the scan: read and write its points block by block, in memory bounded by the coarse\n"
               "level, not by the points (binary PLY or PCD, written in the input's format; the same bytes\n"
               "as a run in memory). Chosen by itself when a shape does not fit in memory. A long run\n"
               "shows its pass, rate and time left on stderr (not with -q)");
  app.add_flag("--mpi", a.mpi,
               "one scan split across MPI ranks (mpirun -n N hgdeform deform --mpi ...): each rank reads,\n"
               "deforms and writes its share of the records into the one output file (MPI-IO), which is\n"
               "the file one process writes, byte for byte. Streamed (--stream); rank 0 reports");
  app.add_option("--memory", a.memory,
                 "the memory the run may take (e.g. 1.5G, 800M; default: what the machine has\n"
                 "available): a shape estimated to need more is streamed (binary PLY or PCD) or refused\n"
                 "before it is read")
      ->type_name("BYTES");
  addOutputFlags(app, a.ascii, a.quiet);
  return hgdcli::parse(app, argc, argv);
}

hgd::FieldSolver fieldSolver(const std::string& name) {
  if (name == "exact") return hgd::FieldSolver::Exact;
  if (name == "multilevel") return hgd::FieldSolver::Multilevel;
  return hgd::FieldSolver::Auto;
}

// --- the work ----------------------------------------------------------------------------------

/// What hgd::storeField(shape, ..., "harmonic", colour) writes over: the fields of `shape` it
/// replaces, as phrases for a warning ("field 'harmonic' is").
std::vector<std::string> replacedFields(const hgd::Shape& shape, bool colour) {
  std::vector<std::string> out;
  if (hgd::findField(shape.cloud, "harmonic") >= 0) out.push_back("field 'harmonic' is");
  if (!colour) return out;
  if (shape.format == hgd::FileFormat::Pcd || hgd::findField(shape.cloud, "rgb") >= 0) {
    if (hgd::findField(shape.cloud, "rgb") >= 0) out.push_back("colours (field 'rgb') are");
    return out;
  }
  std::string names;
  for (const char* name : {"red", "green", "blue"})
    if (hgd::findField(shape.cloud, name) >= 0) names += std::string(names.empty() ? "" : "/") + name;
  if (!names.empty()) out.push_back("colours (" + names + ") are");
  return out;
}

int runField(const FieldArgs& a) {
  const std::string& input = a.input;
  const std::string& scenario_path = a.scenario;
  const std::string& output = a.output;
  hgd::formatFromPath(output);  // fail on a bad extension before any work
  hgd::refuseInputs(output, {input, scenario_path});

  hgd::RunOptions ro;
  ro.deform.field.k_neighbors = a.k;
  ro.deform.field.solver = fieldSolver(a.solver);
  ro.deform.field.mesh_ring = a.mesh_ring;

  const auto t0 = std::chrono::steady_clock::now();
  const hgd::Scenario scenario = hgd::readScenario(scenario_path);
  hgd::Shape read = hgd::readShape(input);
  for (const std::string& w : read.warnings) std::fprintf(stderr, "hgdeform: warning: %s\n", w.c_str());
  hgd::ScenarioRunner run(std::move(read), ro);
  const double read_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  // The field alone, as `hgdeform deform` builds it at full resolution (the runner's rule for
  // the sensor viewpoint of scans), stored into the rest shape.
  const hgd::FieldResult field = run.field(scenario);
  const hgd::Geometry& geometry = run.geometry();
  hgd::Shape shape = run.release(false);

  // What the new field replaces is said, never done in silence.
  for (const std::string& replaced : replacedFields(shape, a.colour))
    std::fprintf(stderr, "hgdeform: warning: %s: its %s replaced in %s\n", input.c_str(), replaced.c_str(),
                 output.c_str());
  hgd::storeField(shape, geometry, field.values, "harmonic", a.colour);
  if (const std::string lost = hgd::extrasLost(shape, hgd::formatFromPath(output)); !lost.empty())
    std::fprintf(stderr, "hgdeform: warning: %s: %s\n", output.c_str(), lost.c_str());
  hgd::WriteOptions wo;
  if (a.ascii) wo.encoding = hgd::Encoding::Ascii;
  hgd::writeShape(output, shape, wo);

  if (!a.quiet) {
    const hgd::FieldTimings& t = field.timings;
    const hgd::Handles& handles = field.handles;
    std::size_t fixed_points = 0;
    for (const auto& f : handles.fixed) fixed_points += f.size();
    std::printf(
        "%s: %zu points, %zu fixed handle(s) (%zu points), manipulated %zu points, %zu unreachable; "
        "read %.0f ms, knn %.0f ms, normals %.0f ms, graph %.0f ms, laplacian %.0f ms, solve %.0f ms (%s), "
        "field "
        "%.0f ms -> %s\n",
        input.c_str(), geometry.size(), handles.fixed.size(), fixed_points, handles.manipulated.size(),
        field.unreachable, read_ms, t.knn_ms, t.normals_ms, t.graph_ms, t.laplacian_ms, t.solve_ms,
        t.exact ? "exact" : ("multilevel, " + std::to_string(t.iterations) + " iterations").c_str(),
        t.total(), output.c_str());
  }
  if (field.unreachable > 0)
    std::fprintf(stderr,
                 "hgdeform: warning: %zu points lie in parts that touch no handle; their field is 0\n",
                 field.unreachable);
  return 0;
}

int runDeform(const DeformArgs& a, hgd::StreamRanks* ranks = nullptr) {
  const bool lead = !ranks || ranks->rank() == 0;  // the rank that reports (and restores)
  const std::string& input = a.input;
  const std::string& scenario_path = a.scenario;
  const std::string& output = a.output;
  hgd::formatFromPath(output);
  // No output replaces an input, nor the report the output, however spelt; "-" is stdout.
  hgd::refuseInputs(output, {input, scenario_path});
  const std::string& report_path = a.report;
  if (!report_path.empty() && report_path != "-") {
    hgd::refuseInputs(report_path, {input, scenario_path});
    if (hgd::samePath(report_path, output))
      throw hgdcli::UsageError("--report " + report_path + " would replace the output " + output);
  }

  hgd::RunOptions ro;
  hgd::DeformOptions& opt = ro.deform;
  opt.field.k_neighbors = a.k;
  opt.field.solver = fieldSolver(a.solver);
  opt.field.mesh_ring = a.mesh_ring;
  if (a.full_field) opt.multires_above = 0;
  opt.clusters.samples = a.samples;
  opt.clusters.joint_isovalues = a.joint_clusters;
  opt.gauss_newton.reweight_rounds = a.reweight;
  if (a.clusters > 0) ro.clusters = a.clusters;
  if (!a.blend.empty()) {  // the command line wins over the scenario
    hgd::Blend blend;
    if (!hgd::parseBlend(a.blend, blend))
      throw hgdcli::UsageError("--blend must be linear or rotation (got '" + a.blend + "')");
    ro.blend = blend;
  }
  const std::uint64_t memory = hgdcli::memoryOption(a.memory);
  const hgd::Scenario scenario = hgd::readScenario(scenario_path);
  // A shape that does not fit in memory is streamed when its file allows (binary PLY or PCD)
  // and its build is on a coarse level; --stream asks for it whatever the size.
  // (The scenario's "resolution": "full" keeps every point in the graph, as --full-field.)
  const bool full = a.full_field || scenario.full_resolution.value_or(false);
  bool stream = a.stream || a.mpi;
  if (!stream) {
    try {
      hgd::checkDeformMemory(input, memory, full ? 0 : opt.multires_above);
    } catch (const hgd::IoError& too_big) {
      if (full || a.ascii) throw;
      if (!hgd::canStream(input, output)) throw;  // not records in place: the reason stands
      std::fprintf(stderr, "hgdeform: note: %s: streamed (%s)\n", input.c_str(), too_big.what());
      stream = true;
    }
  }
  const char* const streamed = a.mpi ? "--mpi" : "--stream";
  if (stream && a.ascii)
    throw hgdcli::UsageError(std::string(streamed) + " writes the input's binary format: not with --ascii");
  if (stream && full)
    throw hgdcli::UsageError(std::string(streamed) +
                             " builds on a coarse level: not with --full-field or \"resolution\": \"full\"");
  if (ranks && output == "-")
    throw hgdcli::UsageError("--mpi writes one file from every rank: not to standard output");
  // What a failed run leaves at `output` (rank 0's to put back: it writes the file).
  std::optional<hgd::PreviousOutput> previous;
  if (lead) previous.emplace(output);
  std::optional<hgd::ScenarioRunner> run;
  if (!stream) {
    run.emplace(hgd::ScenarioRunner::read(input, ro));
    run->setScenario(scenario);
    run->applyMoves();
    hgd::WriteOptions wo;
    if (a.ascii) wo.encoding = hgd::Encoding::Ascii;
    run->writeAndRelease(output, wo, {scenario_path});  // the shape held once, not copied to write
  }
  // A failed run leaves no output: when the report cannot be made or written, the shape goes
  // too, and a file that was there before is put back.
  hgd::DeformReport report;
  try {
    if (stream) {
      const hgdcli::StreamProgress progress(input, lead && !a.quiet, ::isatty(STDERR_FILENO) == 1);
      report = hgd::streamDeform(input, scenario, ro, output, ranks);
      if (!lead) return 0;  // rank 0 reports
    } else {
      report = run->report();
    }
    report.peak_rss_mb = hgdcli::peakResidentMb();
    report.huge_page_malloc = hgdcli::hugePageMallocOn();
    if (report_path == "-") {
      const std::string json = hgd::reportJson(report);
      // A reader that went away (a closed pipe) is a write error here, not SIGPIPE: the run
      // failed, so the output goes and the status says why.
      struct sigaction ignore {};
      struct sigaction before {};
      ignore.sa_handler = SIG_IGN;
      sigemptyset(&ignore.sa_mask);
      ::sigaction(SIGPIPE, &ignore, &before);
      errno = 0;
      const bool ok =
          std::fwrite(json.data(), 1, json.size(), stdout) == json.size() && std::fflush(stdout) == 0;
      const int e = errno;
      // Kept ignored after a failure: what is left in stdout's buffer is flushed at exit.
      if (ok) ::sigaction(SIGPIPE, &before, nullptr);
      if (!ok)
        throw hgd::IoError("-: cannot write the report to standard output" +
                           (e ? ": " + std::string(std::strerror(e)) : std::string()));
    } else if (!report_path.empty()) {
      hgd::writeReportJson(report_path, report);
    }
  } catch (...) {
    if (previous) previous->restore();
    throw;
  }
  for (const auto& note : report.notes) std::fprintf(stderr, "hgdeform: note: %s\n", note.c_str());
  for (const auto& w : report.warnings) std::fprintf(stderr, "hgdeform: warning: %s\n", w.c_str());
  // With the report on stdout, the summary goes to stderr so that stdout stays JSON.
  if (!a.quiet)
    std::fprintf(report_path == "-" ? stderr : stdout, "%s -> %s: %s\n", input.c_str(), output.c_str(),
                 hgd::summaryLine(report).c_str());
  return 0;
}

/// Called in a catch block: what the program says of the exception being handled (as
/// "hgdeform CMD: ..." lines) and its exit status: 2 for a usage error, else 1.
int failure(const std::string& cmd, std::string& said) {
  try {
    throw;
  } catch (const hgdcli::UsageError& e) {
    said = "hgdeform " + cmd + ": " + e.what() + "\n(see 'hgdeform " + cmd + " --help')\n";
    return 2;
  } catch (const std::bad_alloc&) {
    said = "hgdeform " + cmd + ": out of memory\n";
  } catch (const std::exception& e) {
    said = "hgdeform " + cmd + ": " + e.what() + "\n";
  }
  return 1;
}

/// `deform --mpi`: the run on every rank of an MPI launch, rank 0 reporting. Another rank says
/// nothing of a failure (rank 0 says it: every rank meets the same error) and exits non-zero.
int runDeformMpi(const DeformArgs& a) {
  if (!hgdcli::StreamMpi::available())
    throw hgdcli::UsageError("--mpi: this hgdeform was built without MPI (HGDEFORM_MPI=OFF)");
  hgdcli::StreamMpi mpi;
  if (!mpi.launched() && !a.quiet)
    std::fprintf(stderr, "hgdeform: note: --mpi without an MPI launcher (mpirun, srun): one process\n");
  // Every rank ends in finish(): rank 0 says why a run failed before any rank exits (a launcher
  // ends the whole job at the first rank that exits non-zero, and rank 0 with it).
  int status = 0;
  std::string error;
  try {
    status = runDeform(a, mpi.ranks());
  } catch (const std::exception& e) {
    std::string said;
    status = failure("deform", said);
    if (mpi.rank() == 0) std::fputs(said.c_str(), stderr);
    error = dynamic_cast<const std::bad_alloc*>(&e) ? "out of memory" : e.what();
  }
  std::fflush(stderr);
  std::fflush(stdout);
  return mpi.finish(status, error);
}

}  // namespace

int main(int argc, char** argv) {
  // An interrupted run (Ctrl-C, timeout, Slurm, a closed terminal or pipe) leaves no
  // temporary file behind.
  hgd::removeTemporaryFilesOnSignals();
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
  if (cmd == "--version") {
    std::cout << hgdcli::versionLine("hgdeform") << "\n";
    return 0;
  }
  try {
    // Each command parses its own options (argv[1], the command, stands for the program name),
    // then does the work with the parsed struct.
    // One shape a process: freed blocks reused, not fresh pages (huge_pages.h). Not for a batch,
    // whose workers would each hold the memory of the largest scan they met.
    if (cmd == "field" || cmd == "deform") hgdcli::keepFreedMemory();
    if (cmd == "field") {
      FieldArgs a;
      const int status = parseField(argc - 1, argv + 1, a);
      return status >= 0 ? status : runField(a);
    }
    if (cmd == "deform") {
      DeformArgs a;
      const int status = parseDeform(argc - 1, argv + 1, a);
      if (status >= 0) return status;
      if (a.mpi) return runDeformMpi(a);
      hgdcli::hugePageMallocFor(a.input.c_str(), kHugePageInput, argv);
      return runDeform(a);
    }
    if (cmd == "batch") {
      hgdcli::hugePageMalloc(argv);  // folders of scans: the restart is paid once
      return hgdcli::runBatch(argc - 1, argv + 1);
    }
    std::cerr << "hgdeform: unknown command '" << cmd << "'\n" << kUsage;
    return 2;
  } catch (const std::exception&) {
    std::string said;
    const int status = failure(cmd, said);
    std::cerr << said;
    return status;
  }
}
