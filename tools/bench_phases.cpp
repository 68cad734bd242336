#include "bench_phases.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "bench_references.h"

namespace hgdbench {

nlohmann::json buildPhaseScaling(const std::shared_ptr<const hgd::Geometry>& geometry,
                                 const hgd::Handles& handles, const hgd::DeformOptions& options, int repeat) {
  const int threads = omp_get_max_threads();
  const int counts[2] = {1, threads};
  std::vector<double> build[2];
  std::vector<std::string> order;  // the phases in the order of the first build
  std::map<std::string, std::vector<double>> ms[2];
  for (int r = 0; r < repeat; ++r)
    for (int t = 0; t < 2; ++t) {
      omp_set_num_threads(counts[t]);
      const auto t0 = std::chrono::steady_clock::now();
      hgd::Deformer d(geometry, handles, options);
      build[t].push_back(
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      std::map<std::string, double> sum;
      for (const hgd::BuildPhase& p : d.buildTimings().phases) {
        if (std::find(order.begin(), order.end(), p.name) == order.end()) order.push_back(p.name);
        sum[p.name] += p.ms;
      }
      for (const auto& [name, v] : sum) ms[t][name].push_back(v);
    }
  omp_set_num_threads(threads);
  nlohmann::json phases = nlohmann::json::array();
  for (const std::string& name : order)
    phases.push_back({{"name", name}, {"ms_1", median(ms[0][name])}, {"ms_n", median(ms[1][name])}});
  return {{"threads", threads},
          {"build_1_ms", median(build[0])},
          {"build_n_ms", median(build[1])},
          {"phases", phases}};
}

void printPhaseScaling(const std::string& model, long points, const nlohmann::json& s) {
  const int n = s["threads"].get<int>();
  const double b1 = s["build_1_ms"].get<double>(), bn = s["build_n_ms"].get<double>();
  std::printf("build phases, %s at %ld points, 1 / %d threads (ms, medians):\n", model.c_str(), points, n);
  std::printf("  %-26s %9s %9s %8s %7s\n", "phase", "1 thread", "threads", "speed-up", "share");
  double listed_1 = 0, listed_n = 0;
  for (const auto& p : s["phases"]) {
    const double m1 = p["ms_1"].get<double>(), mn = p["ms_n"].get<double>();
    listed_1 += m1, listed_n += mn;
    std::printf("  %-26s %9.1f %9.1f %7.2fx %6.1f%%\n", p["name"].get<std::string>().c_str(), m1, mn,
                m1 / std::max(1e-9, mn), 100.0 * mn / std::max(1e-9, bn));
  }
  std::printf("  %-26s %9.1f %9.1f %7.2fx %6.1f%%\n", "(not in a phase)", b1 - listed_1, bn - listed_n,
              (b1 - listed_1) / std::max(1e-9, bn - listed_n), 100.0 * (bn - listed_n) / std::max(1e-9, bn));
  const double speedup = b1 / std::max(1e-9, bn);
  std::printf("  %-26s %9.1f %9.1f %7.2fx", "build", b1, bn, speedup);
  if (n > 1) {
    // Amdahl: bn = b1 (s + (1 - s) / n), so the serial share s = (n bn / b1 - 1) / (n - 1).
    const double serial = std::clamp((n * bn / b1 - 1.0) / (n - 1.0), 0.0, 1.0);
    std::printf("   serial share %.1f%%, so at 16 threads %.1fx", 100.0 * serial,
                1.0 / (serial + (1 - serial) / 16.0));
  }
  std::printf("\n");
}

}  // namespace hgdbench
