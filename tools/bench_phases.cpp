#include "bench_phases.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "bench_references.h"

namespace hgdbench {

namespace {

// A chain of dependent multiply-adds: no memory traffic, nothing shared between threads.
double arithmetic(long iterations, double seed) {
  double x = 1.0 + seed, y = 0.5;
  for (long i = 0; i < iterations; ++i) {
    x = x * 1.0000001 + y;
    y = y * 0.9999999 + 1e-9;
  }
  return x + y;
}

// The arithmetic loop split evenly over `threads` (about 50 ms on one thread here): what this
// machine gives a loop that is all parallel, in ms.
double arithmeticMs(int threads) {
  constexpr long kIterations = 45'000'000;
  const auto t0 = std::chrono::steady_clock::now();
  double sum = 0;
#pragma omp parallel num_threads(threads) reduction(+ : sum)
  sum += arithmetic(kIterations / omp_get_num_threads(), omp_get_thread_num());
  const double ms = msSince(t0);
  if (!std::isfinite(sum))  // (never: the sum is used, so the loop is kept)
    std::fprintf(stderr, "hgdeform-bench: the arithmetic reference overflowed\n");
  return ms;
}

// Random reads: a 3-float record at a random place of a table as large as the cloud's points,
// once per point, as the build's neighbour searches and graph passes read (on every thread).
class RandomReads {
 public:
  explicit RandomReads(std::size_t n)
      : table_(3 * std::max<std::size_t>(n, 1)), at_(std::max<std::size_t>(n, 1)) {
    std::mt19937 rng(5);
    for (float& x : table_) x = static_cast<float>(rng() % 1000) * 1e-3f;
    for (std::uint32_t& i : at_) i = static_cast<std::uint32_t>(rng() % at_.size());
  }
  double runMs() {
    const long long n = static_cast<long long>(at_.size());
    const auto t0 = std::chrono::steady_clock::now();
    double sum = 0;
#pragma omp parallel for schedule(static) reduction(+ : sum)
    for (long long i = 0; i < n; ++i) {
      const float* r = table_.data() + 3 * std::size_t{at_[static_cast<std::size_t>(i)]};
      sum += r[0] + r[1] + r[2];
    }
    const double ms = msSince(t0);
    if (!std::isfinite(sum)) std::fprintf(stderr, "hgdeform-bench: the random-read reference overflowed\n");
    return ms;
  }

 private:
  std::vector<float> table_;
  std::vector<std::uint32_t> at_;
};

}  // namespace

nlohmann::json buildPhaseScaling(const std::shared_ptr<const hgd::Geometry>& geometry,
                                 const hgd::Handles& handles, const hgd::DeformOptions& options, int repeat) {
  const int threads = omp_get_max_threads();
  const int counts[2] = {1, threads};
  std::vector<double> build[2];
  std::vector<std::string> order;  // the phases in the order of the first build
  std::map<std::string, std::vector<double>> ms[2];
  std::vector<double> reference[2], stream[2], random[2];
  for (int r = 0; r < repeat; ++r)
    for (int t = 0; t < 2; ++t) {
      omp_set_num_threads(counts[t]);
      {
        // The machine's own scaling, between the builds (the same spells weigh on both); the
        // references' buffers (48 bytes a point) are gone before the build.
        StreamingReference streaming(geometry->points->size());
        RandomReads random_reads(geometry->points->size());
        for (int k = 0; k < 3; ++k) {
          reference[t].push_back(arithmeticMs(counts[t]));
          stream[t].push_back(streaming.runMs());
          random[t].push_back(random_reads.runMs());
        }
      }
      const auto t0 = std::chrono::steady_clock::now();
      hgd::Deformer d(geometry, handles, options);
      build[t].push_back(msSince(t0));
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
          {"arithmetic_1_ms", median(reference[0])},
          {"arithmetic_n_ms", median(reference[1])},
          {"stream_1_ms", median(stream[0])},
          {"stream_n_ms", median(stream[1])},
          {"random_1_ms", median(random[0])},
          {"random_n_ms", median(random[1])},
          {"phases", phases}};
}

namespace {

// One phase's line: its medians, its speed-up (none where a median is below 0.05 ms or negative,
// as the "not in a phase" rest can be: a ratio of noise) and its share of the build.
void row(const std::string& name, double m1, double mn, double bn) {
  char speedup[32] = "      -";
  if (m1 >= 0.05 && mn >= 0.05) std::snprintf(speedup, sizeof speedup, "%7.2fx", m1 / mn);
  std::printf("  %-26s %9.1f %9.1f %8s %6.1f%%\n", name.c_str(), m1, mn, speedup,
              100.0 * mn / std::max(1e-9, bn));
}

}  // namespace

void printPhaseScaling(const std::string& model, long points, const nlohmann::json& s) {
  const int n = s["threads"].get<int>();
  const double b1 = s["build_1_ms"].get<double>(), bn = s["build_n_ms"].get<double>();
  std::printf("build phases, %s at %ld points, 1 / %d threads (ms, medians):\n", model.c_str(), points, n);
  std::printf("  %-26s %9s %9s %8s %7s\n", "phase", "1 thread", "threads", "speed-up", "share");
  double listed_1 = 0, listed_n = 0;
  for (const auto& p : s["phases"]) {
    const double m1 = p["ms_1"].get<double>(), mn = p["ms_n"].get<double>();
    listed_1 += m1, listed_n += mn;
    row(p["name"].get<std::string>(), m1, mn, bn);
  }
  // The build's median less the sum of the phases' medians: noise about zero, or time between
  // the phases.
  row("(not in a phase)", b1 - listed_1, bn - listed_n, bn);
  const double speedup = b1 / std::max(1e-9, bn);
  std::printf("  %-26s %9.1f %9.1f %7.2fx", "build", b1, bn, speedup);
  if (n > 1) {
    // Amdahl: bn = b1 (s + (1 - s) / n), so the serial share s = (n bn / b1 - 1) / (n - 1).
    const double serial = std::clamp((n * bn / b1 - 1.0) / (n - 1.0), 0.0, 1.0);
    std::printf("   serial share %.1f%%, so at 16 threads %.1fx", 100.0 * serial,
                1.0 / (serial + (1 - serial) / 16.0));
  }
  std::printf("\n");
  if (n > 1 && s.contains("arithmetic_1_ms")) {
    // What the machine gives a loop with no serial part, no memory traffic and nothing shared,
    // a streaming pass over every point (the bench's interpolation reference) and random reads
    // over every point, in the same run, between the builds.
    const double a1 = s["arithmetic_1_ms"].get<double>(), an = s["arithmetic_n_ms"].get<double>();
    const double machine = a1 / std::max(1e-9, an);
    // Amdahl against it: bn = b1 (s + (1 - s) / machine), the parallel part scaling as the loop.
    std::printf("  %-26s %9.1f %9.1f %7.2fx   the build reaches %.0f%% of it", "machine: arithmetic loop", a1,
                an, machine, 100.0 * speedup / std::max(1e-9, machine));
    if (machine > 1.05)  // (a machine that gives nothing to share leaves no serial share to say)
      std::printf("; serial share against it %.1f%%",
                  100.0 * std::clamp((bn / b1 - 1.0 / machine) / (1.0 - 1.0 / machine), 0.0, 1.0));
    std::printf("\n");
    const double s1 = s["stream_1_ms"].get<double>(), sn = s["stream_n_ms"].get<double>();
    std::printf("  %-26s %9.2f %9.2f %7.2fx\n", "machine: streaming pass", s1, sn, s1 / std::max(1e-9, sn));
    const double r1 = s["random_1_ms"].get<double>(), rn = s["random_n_ms"].get<double>();
    std::printf("  %-26s %9.2f %9.2f %7.2fx\n", "machine: random reads", r1, rn, r1 / std::max(1e-9, rn));
  }
}

}  // namespace hgdbench
