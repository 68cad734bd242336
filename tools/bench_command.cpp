#include "bench_command.h"

#include <fcntl.h>
#include <pcl/io/ply_io.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <vector>

#include "bench_references.h"
#include "hgdeform/app/memory.h"
#include "hgdeform/io/io.h"
#include "huge_pages.h"
#include "support/shapes.h"

namespace hgdbench {

namespace fs = std::filesystem;

namespace {

constexpr const char* kPclIoMark = "hgdeform-bench pcl-io ms: ";

/// Starts args[0] with `args` in the user's environment, not the bench's restarted one (a
/// program decides on huge pages itself and pays its own restart, as when a user runs it):
/// stdout to `out_fd` (/dev/null when -1), stderr to /dev/null. Its pid, or -1.
pid_t spawnAsUser(const std::vector<std::string>& args, int out_fd) {
  const std::vector<std::string> env_entries = hgdcli::userEnvironment();
  std::vector<char*> argv, env;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  for (const auto& e : env_entries) env.push_back(const_cast<char*>(e.c_str()));
  argv.push_back(nullptr);
  env.push_back(nullptr);
  const pid_t pid = fork();
  if (pid == 0) {
    // dup2, not freopen: closing stdout would flush the bench's own unwritten output a second time.
    const int null = open("/dev/null", O_WRONLY | O_CLOEXEC);
    if (null < 0 || dup2(out_fd >= 0 ? out_fd : null, 1) < 0 || dup2(null, 2) < 0) _exit(127);
    execve(argv[0], argv.data(), env.data());
    _exit(127);
  }
  return pid;
}

/// Runs `args` (spawnAsUser); its wall ms and peak RSS in MB (wait4's ru_maxrss, which also
/// counts the bench's own image the child was forked from), or -1 ms when it failed.
std::pair<double, double> timeChild(const std::vector<std::string>& args) {
  const auto t0 = std::chrono::steady_clock::now();
  const pid_t pid = spawnAsUser(args, -1);
  int status = 0;
  struct rusage ru {};
  if (pid < 0 || wait4(pid, &status, 0, &ru) != pid) return {-1, 0};
  const double ms = msSince(t0);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) return {-1, 0};
  return {ms, static_cast<double>(ru.ru_maxrss) / 1024.0};
}

/// PCL's read + write of `in` in a fresh process of this program (pclIoReference, spawnAsUser):
/// {read ms, write ms}, or {-1, -1} when it failed.
std::pair<double, double> pclInChild(const std::string& in, const std::string& out) {
  int pipefd[2];
  if (pipe2(pipefd, O_CLOEXEC) != 0) return {-1, -1};
  // (/proc/self/exe itself: the bench's file may have been rebuilt meanwhile.)
  const pid_t pid = spawnAsUser({"/proc/self/exe", kPclIoFlag, in, out}, pipefd[1]);
  close(pipefd[1]);
  std::string text;
  char buf[256];
  for (ssize_t got; pid > 0 && ((got = read(pipefd[0], buf, sizeof buf)) > 0 || (got < 0 && errno == EINTR));)
    if (got > 0) text.append(buf, static_cast<std::size_t>(got));
  close(pipefd[0]);
  int status = 0;
  pid_t waited = -1;
  while (pid > 0 && (waited = waitpid(pid, &status, 0)) < 0 && errno == EINTR) {
  }
  if (pid < 0 || waited != pid || !WIFEXITED(status) || WEXITSTATUS(status) != 0) return {-1, -1};
  // The times follow their mark (whatever PCL may have printed before them).
  const std::size_t at = text.rfind(kPclIoMark);
  double r = -1, w = -1;
  if (at == std::string::npos ||
      std::sscanf(text.c_str() + at + std::strlen(kPclIoMark), "%lf %lf", &r, &w) != 2)
    return {-1, -1};
  return {r, w};
}

/// The command's own peak in MB (its report's VmHWM), else `child_mb` (wait4's ru_maxrss,
/// which would be the bench's size when the bench, holding its clouds, is the larger).
double reportedPeak(const std::string& report, double child_mb) {
  double own = 0;
  try {
    own = nlohmann::json::parse(std::ifstream(report)).value("peak_rss_mb", 0.0);
  } catch (const std::exception&) {
  }
  return own > 0 ? own : child_mb;
}

}  // namespace

int pclIoReference(const char* in, const char* out) {
  pcl::PCLPointCloud2 cloud;
  auto t0 = std::chrono::steady_clock::now();
  pcl::PLYReader reader;
  if (reader.read(in, cloud) != 0) return 1;
  const double read_ms = msSince(t0);
  t0 = std::chrono::steady_clock::now();
  pcl::PLYWriter writer;
  if (writer.writeBinary(out, cloud) != 0) return 1;
  std::printf("%s%.6f %.6f\n", kPclIoMark, read_ms, msSince(t0));
  return 0;
}

nlohmann::json commandReference(const hgd::Shape& shape, const std::string& scenario, int repeat) {
  const fs::path cli = fs::read_symlink("/proc/self/exe").parent_path() / "hgdeform";
  if (!fs::exists(cli)) return {{"left_out", "no " + cli.string() + " beside the bench"}};
  const fs::path dir = fs::temp_directory_path() / ("hgdeform-bench-" + std::to_string(getpid()));
  fs::create_directories(dir);
  const std::string in = (dir / "in.ply").string(), out = (dir / "out.ply").string(),
                    pcl_out = (dir / "pcl.ply").string(), s = (dir / "s.json").string(),
                    report = (dir / "report.json").string();
  hgd::writeShape(in, shape);
  std::ofstream(s) << scenario;
  std::vector<double> command, peak, read, write;
  for (int r = 0; r < repeat; ++r) {
    const auto [ms, mb] =
        timeChild({cli.string(), "deform", in, "-s", s, "-o", out, "-q", "--report", report});
    if (ms < 0) {
      fs::remove_all(dir);
      return {{"left_out", "hgdeform deform failed on the bench's file"}};
    }
    command.push_back(ms);
    peak.push_back(reportedPeak(report, mb));
    fs::remove(out);
    const auto [read_ms, write_ms] = pclInChild(in, pcl_out);
    fs::remove(pcl_out);
    if (read_ms < 0) {
      fs::remove_all(dir);
      return {{"left_out", "PCL could not read and write the bench's file"}};
    }
    read.push_back(read_ms);
    write.push_back(write_ms);
  }
  fs::remove_all(dir);
  const double points = static_cast<double>(shape.size());
  return {{"points", shape.size()},          {"command_ms", median(command)},
          {"command_peak_mb", median(peak)}, {"pcl_read_ms", median(read)},
          {"pcl_write_ms", median(write)},   {"bytes_per_point", median(peak) * 1048576.0 / points}};
}

namespace {

/// Copies `in` to `out` through the page cache (read and write in 1 MiB blocks, no fsync): the
/// floor a streamed run is measured against. Its ms, or -1.
double copyThroughCache(const std::string& in, const std::string& out) {
  const auto t0 = std::chrono::steady_clock::now();
  const int a = open(in.c_str(), O_RDONLY | O_CLOEXEC);
  const int b = open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  std::vector<char> buf(1 << 20);
  bool ok = a >= 0 && b >= 0;
  for (ssize_t got; ok && (got = read(a, buf.data(), buf.size())) != 0;) {
    if (got < 0) {
      ok = errno == EINTR;
      continue;
    }
    for (ssize_t put = 0; ok && put < got;) {
      const ssize_t w = write(b, buf.data() + put, static_cast<std::size_t>(got - put));
      if (w < 0 && errno == EINTR) continue;
      ok = w > 0;
      put += w;
    }
  }
  if (a >= 0) close(a);
  if (b >= 0 && close(b) != 0) ok = false;
  return ok ? msSince(t0) : -1;
}

}  // namespace

nlohmann::json streamReference(long points, int repeat) {
  const fs::path cli = fs::read_symlink("/proc/self/exe").parent_path() / "hgdeform";
  if (!fs::exists(cli)) return {{"points", points}, {"left_out", "no " + cli.string() + " beside the bench"}};
  const fs::path dir = fs::temp_directory_path() / ("hgdeform-bench-stream-" + std::to_string(getpid()));
  fs::create_directories(dir);
  const std::string in = (dir / "in.ply").string(), out = (dir / "out.ply").string(),
                    copy = (dir / "copy.ply").string(), pcl_out = (dir / "pcl.ply").string(),
                    s = (dir / "s.json").string(), report = (dir / "report.json").string();
  const auto left_out = [&](const std::string& why) {
    fs::remove_all(dir);
    return nlohmann::json{{"points", points}, {"left_out", why}};
  };
  // hgdeform-make-scans' plane and scenario, written a row at a time (no cloud held).
  const double cells = std::max(2.0, std::round(std::sqrt(static_cast<double>(points))) - 1);
  const auto t0 = std::chrono::steady_clock::now();
  try {
    hgd::shapes::writeBumpyPlane(in, 4, 0.05f, static_cast<float>(1.0 / cells));
  } catch (const std::exception& e) {
    return left_out(std::string("cannot write the plane: ") + e.what());
  }
  const double generate_ms = msSince(t0);
  std::ofstream(s) << hgd::shapes::kBumpyPlaneScenario;
  const auto file_bytes = static_cast<double>(fs::file_size(in));
  // PCL's read + write holds the cloud and its copy: where the machine has room for them.
  const bool pcl_fits = static_cast<double>(hgd::availableMemory()) > 3 * file_bytes;
  std::vector<double> command, peak, copied, read, write;
  for (int r = 0; r < repeat; ++r) {
    const double c = copyThroughCache(in, copy);
    fs::remove(copy);
    if (c < 0) return left_out("cannot copy the bench's file");
    copied.push_back(c);
    const auto [ms, mb] =
        timeChild({cli.string(), "deform", "--stream", in, "-s", s, "-o", out, "-q", "--report", report});
    fs::remove(out);
    if (ms < 0) return left_out("hgdeform deform --stream failed on the bench's file");
    command.push_back(ms);
    peak.push_back(reportedPeak(report, mb));
    if (pcl_fits) {
      const auto [read_ms, write_ms] = pclInChild(in, pcl_out);
      fs::remove(pcl_out);
      if (read_ms >= 0) {
        read.push_back(read_ms);
        write.push_back(write_ms);
      }
    }
  }
  fs::remove_all(dir);
  nlohmann::json j = {{"points", static_cast<long>((cells + 1) * (cells + 1))},
                      {"file_mb", file_bytes / 1048576.0},
                      {"generate_ms", generate_ms},
                      {"command_ms", median(command)},
                      {"command_peak_mb", median(peak)},
                      {"copy_ms", median(copied)},
                      {"command_over_copy", median(command) / std::max(1e-9, median(copied))}};
  if (!read.empty()) {
    j["pcl_read_ms"] = median(read);
    j["pcl_write_ms"] = median(write);
  } else {
    j["pcl_left_out"] =
        pcl_fits ? "PCL could not read and write the file" : "the cloud does not fit in memory twice";
  }
  return j;
}

void printStreamRow(const nlohmann::json& r) {
  if (r.contains("left_out")) {
    std::printf("streamed, %ld points: left out: %s\n", r["points"].get<long>(),
                r["left_out"].get<std::string>().c_str());
    return;
  }
  const double ms = r["command_ms"].get<double>();
  std::string pcl = "PCL read + write: " + r.value("pcl_left_out", std::string());
  if (r.contains("pcl_read_ms")) {
    char b[160];
    const double p = r["pcl_read_ms"].get<double>() + r["pcl_write_ms"].get<double>();
    std::snprintf(b, sizeof b, "PCL read + write %.0f + %.0f = %.0f ms (command / PCL %.2fx)",
                  r["pcl_read_ms"].get<double>(), r["pcl_write_ms"].get<double>(), p, ms / std::max(1e-9, p));
    pcl = b;
  }
  std::printf(
      "streamed, %ld points (%.0f MB binary PLY): hgdeform deform --stream %.0f ms (%.2f M points/s), peak "
      "%.0f "
      "MB; copy through the page cache %.0f ms; command / copy %.1fx (target <= 2); %s\n",
      r["points"].get<long>(), r["file_mb"].get<double>(), ms, r["points"].get<double>() / ms / 1e3,
      r["command_peak_mb"].get<double>(), r["copy_ms"].get<double>(), r["command_over_copy"].get<double>(),
      pcl.c_str());
}

}  // namespace hgdbench
