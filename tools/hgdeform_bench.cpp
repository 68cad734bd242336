// hgdeform-bench: build, solve and interpolation timings against the paper's Table 1.
//
//   hgdeform-bench [--sizes 50000,173000,438000,1000000,4000000] [--repeat 5] [--clusters 16,100]
//                  [--models sphere,armadillo] [--armadillo PATH] [--json OUT]
//
// Each (model, size) runs in its own child process, so that the peak memory (RSS) reported is
// its own. Models: a procedural bumpy sphere of exactly N points (fixed: the bottom cap;
// manipulated: a cap on the side) and the Armadillo of ../shared/datasets resampled to N points
// in random order (fixed: the feet; manipulated: the top of the head), when that file is there:
// `armadillo` with the faces' normals stored, `armadillo-bare` positions only (normals
// estimated), `armadillo-outliers` with 1% stray points around it, `armadillo-pieces` with 43
// small dense pieces holding a quarter as many points again (a character's eyes and teeth).
// Beside every row, references measured in the same process on the same cloud: PCL's
// NormalEstimationOMP (k = 10) and a streaming pass (bench_references.h); the ratios printed
// (build / PCL normals, interpolation / stream) and the peak memory per point are the targets.
#include <malloc.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "bench_command.h"
#include "bench_peers.h"
#include "bench_phases.h"
#include "bench_references.h"
#include "blas_guard.h"
#include "cli_common.h"
#include "hgdeform/app/report.h"
#include "hgdeform/deformer/deformer.h"
#include "hgdeform/io/cleanup.h"
#include "hgdeform/io/io.h"
#include "hgdeform/version.h"
#include "huge_pages.h"
#include "support/arap.h"
#include "support/quality.h"
#include "support/shapes.h"

namespace {

using hgdbench::armadilloHandles;
using hgdbench::median;
using hgdbench::runArap;
using hgdbench::runQuality;
using hgdbench::standardDrag;

// The paper's Table 1 (Core 2 Duo, 2008), nearest model by size: build ms, GN ms/iteration
// (16 clusters), interpolation ms.
struct PaperRow {
  const char* model;
  double vertices, build, iteration, interpolation;
};
const PaperRow kPaper[] = {{"Armadillo 52k", 51893, 302, 4, 8},
                           {"Armadillo 173k", 172974, 1564, 5, 26},
                           {"Buddha 244k", 243652, 2659, 6, 40},
                           {"Dragon 438k", 437645, 5035, 7, 59}};
const PaperRow& paperRow(double n) {
  const PaperRow* best = &kPaper[0];
  for (const auto& r : kPaper)
    if (std::abs(std::log(r.vertices / n)) < std::abs(std::log(best->vertices / n))) best = &r;
  return *best;
}

/// Restarts the peak resident size the kernel keeps for this process (VmHWM) at the current size,
/// after handing freed memory back; false where the kernel does not allow it.
bool restartPeakRss() {
  malloc_trim(0);
  FILE* f = std::fopen("/proc/self/clear_refs", "w");
  if (!f) return false;
  const bool ok = std::fputs("5", f) >= 0;
  return std::fclose(f) == 0 && ok;
}

nlohmann::json runSize(const std::string& model, const std::string& armadillo, std::size_t n, int repeat,
                       const std::vector<long>& cluster_counts, bool phases, bool command) {
  using nlohmann::json;
  // Shared with the Deformer, as ScenarioRunner shares it (no second copy of the index maps).
  const auto shared_geometry = std::make_shared<hgd::Geometry>();
  hgd::Geometry& g = *shared_geometry;
  hgd::Handles h;
  hgd::Shape source;  // what the whole-command row writes to a file
  if (model.rfind("armadillo", 0) == 0) {
    hgd::Shape sampled = hgd::shapes::sampleMesh(hgd::readShape(armadillo), n, 7);
    if (model != "armadillo") {
      const hgd::Geometry s = hgd::extractGeometry(sampled);
      std::vector<Eigen::Vector3f> p(s.size()), none;
      for (std::size_t i = 0; i < s.size(); ++i) p[i] = s.world(i).cast<float>();
      if (model == "armadillo-outliers") {  // 1% strays, uniform in the box grown by 20%
        const Eigen::AlignedBox3f box = hgd::boundingBox(*s.points);
        const Eigen::Vector3f lo = box.min() + s.origin.cast<float>(), size = box.max() - box.min();
        std::mt19937 rng(13);
        std::uniform_real_distribution<float> u(-0.1f, 1.1f);
        for (std::size_t k = 0; k < n / 100; ++k)
          p.push_back(lo + Eigen::Vector3f(u(rng), u(rng), u(rng)).cwiseProduct(size));
      }
      if (model == "armadillo-pieces") {  // 43 small dense pieces, a quarter of the points
        const Eigen::AlignedBox3f box = hgd::boundingBox(*s.points);
        p = hgd::shapes::withDensePieces(std::move(p), 43, std::max<std::size_t>(1, n / 4 / 43),
                                         0.0015f * (box.max() - box.min()).norm(), 17);
      }
      sampled = hgd::shapes::cloudShape(p, none);
    }
    g = hgd::extractGeometry(sampled);
    h = armadilloHandles(g);
    if (command) source = std::move(sampled);
  } else {
    source = hgd::shapes::bumpySphere(n);
    g = hgd::extractGeometry(source);
    h.fixed.emplace_back();
    for (std::size_t i = 0; i < g.size(); ++i) {
      const Eigen::Vector3d w = g.world(i);
      if (w.z() < -0.9) h.fixed[0].push_back(static_cast<int>(i));
      if (w.x() > 0.9) h.manipulated.push_back(static_cast<int>(i));
    }
  }
  json out;
  out["model"] = model;
  out["points"] = g.size();
  out["reference"] = {{"pcl_normal_estimation_ms", hgdbench::pclNormalEstimationMs(g.points, 10, repeat)},
                      {"stream_ms", hgdbench::streamingReferenceMs(g.size(), std::max(15, 5 * repeat))}};
  // Field build: normals (file normals are ignored here so that estimation is measured),
  // kNN, graph, Laplacian, solve; a fresh HarmonicField each time.
  std::vector<double> knn, normals, graph, lap, solve, field_total;
  std::string solver;
  int cg_iterations = 0;
  for (int r = 0; r < repeat; ++r) {
    hgd::HarmonicField f;
    f.setInputCloud(g.points);
    f.setHandles(h.fixed, h.manipulated);
    std::vector<float> phi;
    f.compute(phi);
    const auto& t = f.timings();
    knn.push_back(t.knn_ms);
    normals.push_back(t.normals_ms);
    graph.push_back(t.graph_ms);
    lap.push_back(t.laplacian_ms);
    solve.push_back(t.solve_ms);
    field_total.push_back(t.total());
    solver = t.exact ? "exact" : "multilevel";
    cg_iterations = t.iterations;
  }
  out["field"] = {{"knn_ms", median(knn)},     {"normals_ms", median(normals)},
                  {"graph_ms", median(graph)}, {"laplacian_ms", median(lap)},
                  {"solve_ms", median(solve)}, {"total_ms", median(field_total)},
                  {"solver", solver},          {"cg_iterations", cg_iterations}};
  json per_clusters = json::array();
  double deformer_peak = -1;
  // The peak from here on: the Deformer's, with the cloud it deforms (what `hgdeform deform`
  // holds), not the references' or the full-resolution field's above.
  const double peak_before = hgdcli::peakResidentMb();  // (restarting the count restarts getrusage's too)
  const bool peak_restarted = restartPeakRss();
  for (long nc : cluster_counts) {
    std::vector<double> build, sampling, clusters, setup, per_iter, interp, frame, interp_linear,
        interp_rotation, b_knn, b_graph, b_lap, b_solve, b_field, interp_paired, stream_paired;
    int iterations_first = 0, max_frame_iterations = 0;
    std::size_t cluster_total = 0, coarse_points = 0;
    for (int r = 0; r < std::max(1, repeat / 2); ++r) {
      hgd::DeformOptions opt;
      opt.clusters.isovalues = static_cast<int>(nc);
      opt.clusters.samples = std::max(4000, static_cast<int>(nc) * 60);
      const auto t0 = std::chrono::steady_clock::now();
      hgd::Deformer d(std::shared_ptr<const hgd::Geometry>(shared_geometry), h, opt);
      build.push_back(
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      sampling.push_back(d.buildTimings().sampling_ms);
      b_field.push_back(d.buildTimings().field_ms);
      b_knn.push_back(d.buildTimings().field.knn_ms);
      b_graph.push_back(d.buildTimings().field.graph_ms);
      b_lap.push_back(d.buildTimings().field.laplacian_ms);
      b_solve.push_back(d.buildTimings().field.solve_ms);
      clusters.push_back(d.buildTimings().clusters_ms);
      setup.push_back(d.buildTimings().setup_ms);
      cluster_total = d.clustering().clusters.size();
      coarse_points = d.coarseLevel().points.size();
      double solve_ms = 0;
      int iterations = 0;
      standardDrag(d, h, 30, [&](int k, double frame_ms, const hgd::SolveStats& st) {
        frame.push_back(frame_ms);
        solve_ms += st.ms;
        iterations += st.iterations;
        interp.push_back(d.lastInterpolationMs());
        if (k == 1) iterations_first = st.iterations;
        max_frame_iterations = std::max(max_frame_iterations, st.iterations);
      });
      per_iter.push_back(solve_ms / std::max(1, iterations));
      // The same final shape with each blend, a few times each.
      for (int k = 0; k < 5; ++k) {
        d.setBlend(hgd::Blend::Linear);
        interp_linear.push_back(d.lastInterpolationMs());
        d.setBlend(hgd::Blend::Rotation);
        interp_rotation.push_back(d.lastInterpolationMs());
      }
      if (r + 1 == std::max(1, repeat / 2)) {
        // The peak so far is the Deformer's; then the interpolation (default blend) and the
        // streaming pass alternate, so that a slow spell of the machine weighs on both.
        if (peak_restarted) deformer_peak = std::max(deformer_peak, hgdcli::peakResidentMb());
        hgdbench::StreamingReference stream(g.size());
        for (int k = 0; k < 15; ++k) {
          d.setBlend(hgd::Blend::Rotation);
          interp_paired.push_back(d.lastInterpolationMs());
          stream_paired.push_back(stream.runMs());
        }
      }
    }
    const PaperRow& paper = paperRow(static_cast<double>(n));
    json row = {{"isovalues", nc},
                {"clusters", cluster_total},
                {"coarse_points", coarse_points},
                {"iterations_first_frame", iterations_first},
                {"max_frame_iterations", max_frame_iterations},
                {"build_over_pcl_normals",
                 median(build) / out["reference"]["pcl_normal_estimation_ms"].get<double>()},
                {"interpolation_over_stream", median(interp_paired) / median(stream_paired)},
                {"paper_model", paper.model},
                {"build_speedup", paper.build / std::max(1e-9, median(build))},
                {"interpolation_speedup", paper.interpolation / std::max(1e-9, median(interp))}};
    // The medians of the repeated measurements, by key.
    const std::pair<const char*, const std::vector<double>*> medians[] = {
        {"build_ms", &build},
        {"sampling_ms", &sampling},
        {"field_ms", &b_field},
        {"field_knn_ms", &b_knn},
        {"field_graph_ms", &b_graph},
        {"field_laplacian_ms", &b_lap},
        {"field_solve_ms", &b_solve},
        {"clusters_ms", &clusters},
        {"setup_ms", &setup},
        {"gn_iteration_ms", &per_iter},
        {"interpolation_ms", &interp},
        {"interpolation_linear_ms", &interp_linear},
        {"interpolation_rotation_ms", &interp_rotation},
        {"frame_ms", &frame},
        {"interpolation_paired_ms", &interp_paired},
        {"stream_paired_ms", &stream_paired}};
    for (const auto& [key, runs] : medians) row[key] = median(*runs);
    if (nc == 16) row["gn_iteration_speedup"] = paper.iteration / std::max(1e-9, median(per_iter));
    if (nc == 100)
      row["gn_iteration_speedup"] = 36.0 / std::max(1e-9, median(per_iter));  // Dinosaur, 100 clusters
    per_clusters.push_back(row);
    if (phases && nc == cluster_counts.front()) {
      hgd::DeformOptions opt;
      opt.clusters.isovalues = static_cast<int>(nc);
      opt.clusters.samples = std::max(4000, static_cast<int>(nc) * 60);
      out["build_phases"] = hgdbench::buildPhaseScaling(shared_geometry, h, opt, repeat);
    }
  }
  out["deform"] = per_clusters;
  if (command) {
    // The whole command on the same points: the bottom tenth fixed, the top tenth moved a twentieth
    // of the height (boxes, as a user's scenario has, not the bench's index lists).
    const Eigen::AlignedBox3f box = hgd::boundingBox(*g.points);
    const Eigen::Vector3d lo = box.min().cast<double>() + g.origin, hi = box.max().cast<double>() + g.origin;
    const double dy = hi.y() - lo.y();
    auto v = [](double x, double y, double z) { return nlohmann::json::array({x, y, z}); };
    const nlohmann::json scenario = {{"format", "hgdeform-scenario/1"},
                                     {"fixed",
                                      {{{"box",
                                         {{"min", v(lo.x() - 1, lo.y() - 1, lo.z() - 1)},
                                          {"max", v(hi.x() + 1, lo.y() + 0.1 * dy, hi.z() + 1)}}}}}},
                                     {"manipulated",
                                      {{"box",
                                        {{"min", v(lo.x() - 1, hi.y() - 0.1 * dy, lo.z() - 1)},
                                         {"max", v(hi.x() + 1, hi.y() + 1, hi.z() + 1)}}}}},
                                     {"move", {{{"frame", {{"translate", v(0.05 * dy, 0, 0)}}}}}}};
    // The memory this process keeps (keepFreedMemory) given back first: the command is forked
    // from here, and a fork copies the page tables of all that is mapped.
    malloc_trim(0);
    out["command"] = hgdbench::commandReference(source, scenario.dump(), repeat);
  }
  if (peak_restarted) {
    out["deformer_peak_rss_mb"] = deformer_peak;
    out["peak_rss_before_deformer_mb"] = peak_before;
  }
  return out;
}

/// hgdeform-bench's command line.
struct BenchArgs {
  std::vector<long> sizes{50000, 173000, 438000, 1000000};
  std::vector<long> clusters{16, 100};
  std::vector<long> stream_sizes{20000000, 200000000};
  std::vector<std::string> models{"sphere", "armadillo"};
  std::string armadillo = HGD_DEFAULT_ARMADILLO;
  int repeat = 5;
  std::string json;
  bool arap = false;
  bool quality = true;
  bool phases = true;
  bool command = true;
};

/// Parses the command line into `a`; returns -1 to go on, else the exit status.
int parseArgs(int argc, char** argv, BenchArgs& a) {
  CLI::App app(
      "Build, solve and interpolation timings against the paper's Table 1. Each (model, size) runs in\n"
      "its own child process, so that the peak memory (RSS) reported is its own.");
  hgdcli::configureApp(app, "hgdeform-bench");
  app.add_option("--sizes", a.sizes, "point counts (default 50000,173000,438000,1000000)")
      ->delimiter(',')
      ->check(hgdcli::integerFrom(1, 1000000000))
      ->type_name("N,N,...");
  app.add_option("--stream-sizes", a.stream_sizes,
                 "streaming rows' point counts (default 20000000,200000000; 0: none), at most 3 runs each")
      ->delimiter(',');
  app.add_option("--clusters", a.clusters, "isovalue counts (default 16,100)")
      ->delimiter(',')
      ->check(hgdcli::integerFrom(1, 1000000000))
      ->type_name("N,N");
  app.add_option("--repeat", a.repeat, "runs per measurement, the median is shown (default 5)")
      ->check(hgdcli::integerFrom(1, 1000))
      ->type_name("R");
  app.add_option("--models", a.models,
                 "sphere, armadillo (face normals stored), armadillo-bare (no normals), armadillo-outliers "
                 "(1% strays), armadillo-pieces (43 small dense pieces) (default sphere,armadillo)")
      ->delimiter(',')
      ->check(
          hgdcli::oneOf({"sphere", "armadillo", "armadillo-bare", "armadillo-outliers", "armadillo-pieces"}))
      ->type_name("M,M");
  app.add_option("--armadillo", a.armadillo,
                 "the Armadillo mesh (default ../shared/datasets/meshes/armadillo_49990.ply)")
      ->type_name("PATH");
  app.add_flag("--arap", a.arap,
               "also the peer: one frame against five iterations of CGAL's ARAP on the Armadillo mesh, same "
               "handles and drag (needs CGAL at build time)");
  app.add_flag("--quality,!--no-quality", a.quality,
               "the quality rows (default on): local distortion of hgdeform and of CGAL's ARAP run to "
               "convergence on the same meshes, handles and moves (the Armadillo, a procedural quadruped)");
  app.add_flag("--phases,!--no-phases", a.phases,
               "the build's thread scaling (default on): each build phase's time on one thread and on "
               "every thread (OMP_NUM_THREADS), builds alternating, at the first --clusters count");
  app.add_flag(
      "--command,!--no-command", a.command,
      "the whole command (default on): `hgdeform deform` (beside the bench) on the cloud written as a "
      "binary PLY, a frame move, its wall time and peak memory, against PCL reading and writing the "
      "same file (PLYReader, PLYWriter), alternating");
  app.add_option("--json", a.json,
                 "also write every measurement (with the tool and its version) as JSON; never the mesh")
      ->type_name("OUT");
  // A list keeps all its values (the tools' default policy, the last value wins, would keep one).
  for (const char* name : {"--sizes", "--clusters", "--models", "--stream-sizes"})
    app.get_option(name)->multi_option_policy(CLI::MultiOptionPolicy::TakeAll)->allow_extra_args(false);
  return hgdcli::parse(app, argc, argv);
}

}  // namespace

int main(int argc, char** argv) {
  // PCL's reference for the whole-command row, run by the bench itself (bench_command.h).
  if (argc == 4 && std::strcmp(argv[1], hgdbench::kPclIoFlag) == 0) {
    hgdcli::singleThreadBlas();  // (a PCL program has no BLAS worker spinning beside it)
    return hgdbench::pclIoReference(argv[2], argv[3]);
  }
  hgd::removeTemporaryFilesOnSignals();         // no partial --json left by an interrupted run
  hgdcli::hugePageMalloc(argv);                 // as hgdeform does for large inputs (huge_pages.h)
  hgdcli::singleThreadBlas();                   // as hgdeform does (blas_guard.h)
  const bool kept = hgdcli::keepFreedMemory();  // as hgdeform does (huge_pages.h)
  BenchArgs args;
  if (const int status = parseArgs(argc, argv, args); status >= 0) return status;
  const std::vector<long>& sizes = args.sizes;
  const std::vector<long>& cluster_counts = args.clusters;
  const std::string& armadillo = args.armadillo;
  std::vector<std::string> models = args.models;
  const int repeat = args.repeat;
  const bool phases = args.phases;
  const bool command = args.command;
  const std::string& json_path = args.json;
  try {  // before any work: --json never replaces the mesh read
    if (!json_path.empty()) hgd::refuseInputs(json_path, {armadillo});
  } catch (const std::exception& e) {
    std::fprintf(stderr, "hgdeform-bench: %s\n", e.what());
    return 1;
  }
  nlohmann::json all = nlohmann::json::array();
  if (!std::filesystem::exists(armadillo)) {
    const auto was = models.size();
    models.erase(std::remove_if(models.begin(), models.end(),
                                [](const std::string& m) { return m.rfind("armadillo", 0) == 0; }),
                 models.end());
    if (models.size() != was) std::printf("(no %s: the Armadillo rows are left out)\n", armadillo.c_str());
  }
  std::printf(
      "%18s %9s %10s | %6s %6s %6s %6s %6s %7s | %5s %6s %6s %6s %8s %5s %7s %7s %7s | %7s %6s | %6s %6s %6s "
      "%6s %6s\n",
      "model", "points", "solver", "knn", "normal", "graph", "lapl", "solve", "field", "clus", "build",
      "sample", "clust", "ms/iter", "iters", "i.lin", "i.rot", "frame", "RSS MB", "xpaper", "pclN", "b/pclN",
      "stream", "i/strm", "B/pt");
  for (const std::string& model : models)
    for (long n : sizes) {
      int pipefd[2];
      if (pipe(pipefd) != 0) return 1;
      const pid_t pid = fork();
      if (pid == 0) {
        close(pipefd[0]);
        const std::string text =
            runSize(model, armadillo, static_cast<std::size_t>(n), repeat, cluster_counts, phases, command)
                .dump();
        if (write(pipefd[1], text.data(), text.size()) < 0) _exit(1);
        close(pipefd[1]);
        _exit(0);
      }
      close(pipefd[1]);
      std::string text;
      char buf[4096];
      ssize_t got;
      while ((got = read(pipefd[0], buf, sizeof buf)) > 0) text.append(buf, static_cast<std::size_t>(got));
      close(pipefd[0]);
      int status = 0;
      struct rusage ru;
      wait4(pid, &status, 0, &ru);
      if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || text.empty()) {
        std::fprintf(stderr, "hgdeform-bench: %s at %ld points failed\n", model.c_str(), n);
        return 1;
      }
      nlohmann::json r = nlohmann::json::parse(text);
      r["process_peak_rss_mb"] =
          std::max(static_cast<double>(ru.ru_maxrss) / 1024.0, r.value("peak_rss_before_deformer_mb", 0.0));
      // The Deformer's peak where the kernel could restart the count, else the whole child's.
      r["peak_rss_mb"] = r.contains("deformer_peak_rss_mb") && r["deformer_peak_rss_mb"].get<double>() > 0
                             ? r["deformer_peak_rss_mb"].get<double>()
                             : r["process_peak_rss_mb"].get<double>();
      r["tool"] = "hgdeform-bench";
      r["huge_page_malloc"] = hgdcli::hugePageMallocOn();
      r["version"] = hgd::version();
      const auto& f = r["field"];
      const double pcl_ms = r["reference"]["pcl_normal_estimation_ms"].get<double>();
      r["peak_bytes_per_point"] = r["peak_rss_mb"].get<double>() * 1048576.0 / r["points"].get<double>();
      for (const auto& d : r["deform"]) {
        std::printf(
            "%18s %9ld %10s | %6.0f %6.0f %6.0f %6.0f %6.0f %7.0f | %5ld %6.0f %6.1f %6.0f %8.3f %5d %7.2f "
            "%7.2f %7.2f | %7.0f %6.1f | %6.0f %6.2f %6.2f %6.1f %6.0f\n",
            model.c_str(), r["points"].get<long>(), f["solver"].get<std::string>().c_str(),
            f["knn_ms"].get<double>(), f["normals_ms"].get<double>(), f["graph_ms"].get<double>(),
            f["laplacian_ms"].get<double>(), f["solve_ms"].get<double>(), f["total_ms"].get<double>(),
            d["isovalues"].get<long>(), d["build_ms"].get<double>(), d["sampling_ms"].get<double>(),
            d["clusters_ms"].get<double>(), d["gn_iteration_ms"].get<double>(),
            d["max_frame_iterations"].get<int>(), d["interpolation_linear_ms"].get<double>(),
            d["interpolation_rotation_ms"].get<double>(), d["frame_ms"].get<double>(),
            r["peak_rss_mb"].get<double>(), d["build_speedup"].get<double>(), pcl_ms,
            d["build_over_pcl_normals"].get<double>(), d["stream_paired_ms"].get<double>(),
            d["interpolation_over_stream"].get<double>(), r["peak_bytes_per_point"].get<double>());
      }
      std::fflush(stdout);
      all.push_back(r);
    }
  // How the bench's own memory is served (the commands it times run as a user runs them).
  const bool huge = hgdcli::hugePageMallocOn();
  const std::string malloc_said =
      std::string(
          huge ? "glibc's huge pages (glibc.malloc.hugetlb=1, as hgdeform deform for inputs from 8 MiB)"
               : "4 KiB pages") +
      (kept ? ", freed memory kept for reuse (M_MMAP_MAX 0, M_TRIM_THRESHOLD 2 GiB, as hgdeform deform and "
              "field)"
            : "") +
      " for the bench's own measurements; the whole command and PCL's read + write run in fresh processes" +
      (huge ? " in the user's environment" : "");
  std::printf(
      "columns: field phases in ms (median of %d); clus = isovalues asked for; build = Deformer construction "
      "(field, "
      "sample, clusters, solver set-up), of which sample and clust (clustering) in ms; ms/iter = "
      "Gauss-Newton ms per iteration over a 30-frame drag; iters "
      "= most "
      "iterations in one frame; i.lin / i.rot = interpolation to all points with the linear / rotation-aware "
      "(default) blend; frame = solve + interpolation per frame (default blend); xpaper = the paper's build "
      "time (nearest model in Table 1) / ours; references in the same run on the same cloud: pclN = PCL "
      "NormalEstimationOMP (k = 10, every thread) ms, b/pclN = build / pclN, stream = a streaming pass (20 "
      "bytes read, 12 written, two 3x4 transforms blended per point) ms and i/strm = interpolation (default "
      "blend) / stream, medians of 15 passes of each, alternating, after the drag; "
      "B/pt = peak RSS bytes per point from the Deformer's build on (the cloud included; the references and "
      "the\n"
      "full-resolution field measured above excluded); malloc: %s\n",
      repeat, malloc_said.c_str());
  for (const auto& r : all)
    if (r.contains("build_phases"))
      hgdbench::printPhaseScaling(r["model"].get<std::string>(), r["points"].get<long>(), r["build_phases"]);
  for (const auto& r : all) {
    if (!r.contains("command")) continue;
    const auto& c = r["command"];
    if (c.contains("left_out")) {
      std::printf("whole command, %s: left out: %s\n", r["model"].get<std::string>().c_str(),
                  c["left_out"].get<std::string>().c_str());
      continue;
    }
    const double pcl = c["pcl_read_ms"].get<double>() + c["pcl_write_ms"].get<double>();
    std::printf(
        "whole command, %s at %ld points: hgdeform deform %.0f ms, peak %.0f MB (%.0f B/pt); PCL read + "
        "write "
        "%.0f + %.0f = %.0f ms; command / PCL %.2fx\n",
        r["model"].get<std::string>().c_str(), r["points"].get<long>(), c["command_ms"].get<double>(),
        c["command_peak_mb"].get<double>(), c["bytes_per_point"].get<double>(),
        c["pcl_read_ms"].get<double>(), c["pcl_write_ms"].get<double>(), pcl,
        c["command_ms"].get<double>() / std::max(1e-9, pcl));
  }
  for (const long n : args.stream_sizes)
    if (n > 0) {
      const nlohmann::json row = hgdbench::streamReference(n, std::min(repeat, 3));
      hgdbench::printStreamRow(row);
      std::fflush(stdout);
      all.push_back({{"stream", row}});
    }
  if (args.quality) {
    if (!hgdbench::haveCgalArap()) {
      const std::string why = "this build has no CGAL (install libcgal-dev and configure again)";
      std::fprintf(stderr, "hgdeform-bench: warning: the quality rows are left out: %s\n", why.c_str());
      all.push_back({{"quality", {{"left_out", why}}}});
    } else {
      if (!std::filesystem::exists(armadillo))
        std::printf("(no %s: the Armadillo's quality row is left out)\n", armadillo.c_str());
      nlohmann::json rows;
      try {  // a peer that fails (CGAL's factorisation) is said, not an abort
        rows = runQuality(armadillo);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "hgdeform-bench: the quality rows failed: %s\n", e.what());
        return 1;
      }
      std::printf("%10s %7s %5s | %9s %9s %7s %7s | %8s %8s | %7s %7s | %6s %8s %8s\n", "quality", "points",
                  "clus", "distort", "ARAP", "/ARAP", "/ref", "branch", "ARAP br", "legs", "ARAP lg", "iters",
                  "move ms", "ARAP ms");
      // A percentage column, or "-" where the case has no such part (the Armadillo's branch and legs).
      const auto pct = [](const nlohmann::json& r, const char* key) {
        if (!r.contains(key)) return std::string("-");
        char buf[32];
        std::snprintf(buf, sizeof buf, "%.2f%%", 100 * r[key].get<double>());
        return std::string(buf);
      };
      for (const auto& r : rows) {
        std::printf("%10s %7ld %5ld | %9.5f %9.5f %6.3fx %6.3fx | %8s %8s | %7s %7s | %6d %8.1f %8.0f%s\n",
                    r["case"].get<std::string>().c_str(), r["points"].get<long>(), r["clusters"].get<long>(),
                    r["hgdeform_distortion"].get<double>(), r["arap_distortion"].get<double>(),
                    r["distortion_over_arap"].get<double>(), r["over_reference"].get<double>(),
                    pct(r, "hgdeform_other_branch").c_str(), pct(r, "arap_other_branch").c_str(),
                    pct(r, "hgdeform_length_change").c_str(), pct(r, "arap_length_change").c_str(),
                    r["arap_iterations"].get<int>(), r["hgdeform_move_ms"].get<double>(),
                    r["arap_ms"].get<double>(),
                    r["arap_converged"].get<bool>() ? "" : " (ARAP not converged)");
        std::printf(
            "%10s %7s %5s | %9.5f %9s %6.3fx %7s | %8s %8s | %7s %7s | %6s %8.1f   (opt-in: 32 isovalues, "
            "E_Prop reweighted over 8 rounds)\n",
            "+reweight", "", "", r["reweighted_distortion"].get<double>(), "",
            r["reweighted_over_arap"].get<double>(), "", pct(r, "reweighted_other_branch").c_str(), "",
            pct(r, "reweighted_length_change").c_str(), "", "", r["reweighted_move_ms"].get<double>());
        if (r["over_reference"].get<double>() > 1.05)
          std::printf("quality: %s's distortion is %.0f%% worse than the reference recorded in the bench\n",
                      r["case"].get<std::string>().c_str(), 100 * (r["over_reference"].get<double>() - 1));
      }
      std::printf(
          "quality columns: distort = local distortion (per point, its 10 nearest rest neighbours, the best "
          "rotation between their rest and deformed offsets; the mean residual over the mean offset length, "
          "averaged over points) of hgdeform at default settings, ARAP = the same of CGAL's ARAP run to "
          "convergence on the same mesh, handles and move; /ARAP their ratio (target <= 1); /ref against the "
          "figure recorded in the bench (more than 1.05 is said); branch = mean motion of a branch no handle "
          "is on (the quadruped's other hind shin) over the move (target <= 1.5%%); legs = the largest "
          "change in length of the quadruped's three planted legs (foot to top, between the centroids of "
          "the two rings; target <= 1%%)\n");
      all.push_back({{"quality", rows}});
    }
  }
  if (args.arap) {
    std::string why;
    if (!hgdbench::haveCgalArap())
      why = "this build has no CGAL (install libcgal-dev and configure again)";
    else if (!std::filesystem::exists(armadillo))
      why = "no " + armadillo;
    if (!why.empty()) {
      std::fprintf(stderr, "hgdeform-bench: warning: --arap left out: %s\n", why.c_str());
      all.push_back({{"arap", {{"left_out", why}}}});
    } else {
      nlohmann::json a = runArap(armadillo, repeat);
      std::printf(
          "ARAP peer, Armadillo %ld vertices / %ld faces (%ld refused by CGAL), %ld fixed and %ld handle "
          "points, 10-frame drag: hgdeform frame (solve + interpolation) %.3f ms, CGAL "
          "Surface_mesh_deformation "
          "5 iterations %.1f ms (preprocess %.0f ms, hgdeform build %.0f ms): %.0fx; opt-in reweighted "
          "(32 isovalues, 8 rounds) frame %.3f ms: %.0fx\n",
          a["points"].get<long>(), a["faces"].get<long>(), a["faces_refused_by_cgal"].get<long>(),
          a["fixed"].get<long>(), a["manipulated"].get<long>(), a["hgdeform_frame_ms"].get<double>(),
          a["cgal_arap_5_iterations_ms"].get<double>(), a["cgal_arap_preprocess_ms"].get<double>(),
          a["hgdeform_build_ms"].get<double>(), a["arap_over_frame"].get<double>(),
          a["hgdeform_reweighted_frame_ms"].get<double>(), a["arap_over_reweighted_frame"].get<double>());
      all.push_back({{"arap", a}});
    }
  }
  if (!json_path.empty()) hgd::writeFileAtomically(json_path, all.dump(2) + "\n");
  return 0;
}
