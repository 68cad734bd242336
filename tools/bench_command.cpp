#include "bench_command.h"

#include <fcntl.h>
#include <pcl/io/ply_io.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <vector>

#include "bench_references.h"
#include "hgdeform/io/io.h"
#include "huge_pages.h"

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
    // The command's own peak (its report's VmHWM): ru_maxrss would be the bench's size when the
    // bench, holding its clouds, is the larger.
    double own = 0;
    try {
      own = nlohmann::json::parse(std::ifstream(report)).value("peak_rss_mb", 0.0);
    } catch (const std::exception&) {
    }
    peak.push_back(own > 0 ? own : mb);
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

}  // namespace hgdbench
