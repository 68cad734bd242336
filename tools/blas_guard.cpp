#include "blas_guard.h"

#include <dlfcn.h>
#include <omp.h>
#include <pthread.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

namespace {

bool addressSpaceLimited(rlim_t& limit) {
  rlimit rl{};
  if (getrlimit(RLIMIT_AS, &rl) != 0 || rl.rlim_cur == RLIM_INFINITY) return false;
  limit = rl.rlim_cur;
  return true;
}

/// Mapped address space of this process, from /proc/self/statm.
bool mappedBytes(unsigned long long* bytes) {
  std::FILE* f = std::fopen("/proc/self/statm", "r");
  if (!f) return false;
  unsigned long long pages = 0;
  const bool ok = std::fscanf(f, "%llu", &pages) == 1;
  std::fclose(f);
  *bytes = pages * static_cast<unsigned long long>(sysconf(_SC_PAGESIZE));
  return ok;
}

}  // namespace

namespace hgdcli {

void singleThreadBlas() {
  if (std::getenv("OPENBLAS_NUM_THREADS")) return;
  using SetThreads = void (*)(int);
  const auto set = reinterpret_cast<SetThreads>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"));
  if (!set) return;
  set(1);
  // The worker OpenBLAS started when it was loaded goes on spinning for about 2^28 cycles (0.13 s
  // here) after that: the first parallel loops (the geometry's Morton sort at 200k points: 56 ms
  // instead of 4) waited for the core it held. Its own shutdown (what OpenBLAS does before a
  // fork) ends it; with one thread set, no BLAS call starts it again.
  using Shutdown = int (*)();
  if (const auto stop = reinterpret_cast<Shutdown>(dlsym(RTLD_DEFAULT, "blas_thread_shutdown_"))) stop();
}

std::string reserveBlasBuffer(char** argv) {
  rlim_t limit = 0;
  if (!addressSpaceLimited(limit)) return "";
  if (!dlsym(RTLD_DEFAULT, "openblas_get_config")) return "";  // another BLAS: nothing known to fix
  if (!std::getenv("OPENBLAS_NUM_THREADS") || !std::getenv("OMP_THREAD_LIMIT")) {
    // OpenBLAS read its thread count when it was loaded, and its worker may already be stuck
    // mapping its buffer: start again with one thread (exec ends the worker). And CHOLMOD's
    // supernodal factorisation asks for a team of 4 (its CHOLMOD_OMP_NUM_THREADS) whatever the
    // program's thread count: 2 more threads than the budget below on two cores, whose stacks
    // libgomp cannot map near the limit, and libgomp then ends the program ("Thread creation
    // failed", exit 1, none of our message). OMP_THREAD_LIMIT caps every team at the program's
    // own count. Both are read at start (a variable set here before the runtimes initialise
    // would be lost), hence the exec; a value of the user's own is kept.
    if (!std::getenv("OPENBLAS_NUM_THREADS")) setenv("OPENBLAS_NUM_THREADS", "1", 1);
    if (!std::getenv("OMP_THREAD_LIMIT"))
      setenv("OMP_THREAD_LIMIT", std::to_string(std::max(1, omp_get_max_threads())).c_str(), 1);
    execv("/proc/self/exe", argv);
    return std::string("cannot restart itself with OPENBLAS_NUM_THREADS=1 under the address-space limit: ") +
           std::strerror(errno);
  }
  using Potrf = void (*)(const char*, const int*, double*, const int*, int*);
  const auto potrf = reinterpret_cast<Potrf>(dlsym(RTLD_DEFAULT, "dpotrf_"));
  if (!potrf) return "";
  // OpenBLAS's x86-64 buffer: 128 MiB plus a page, which it retries for ever if it cannot map.
  // Then the OpenMP team's stacks (libgomp exits the program when it cannot create a thread).
  constexpr unsigned long long kBuffer = (128ull << 20) + (2ull << 20);
  pthread_attr_t attr;
  std::size_t stack = 8u << 20;
  if (pthread_getattr_default_np(&attr) == 0) {
    pthread_attr_getstacksize(&attr, &stack);
    pthread_attr_destroy(&attr);
  }
  const int threads = omp_get_max_threads();
  const unsigned long long team = static_cast<unsigned long long>(threads - 1) * (stack + (1u << 20));
  unsigned long long mapped = 0;
  if (!mappedBytes(&mapped)) return "";
  if (limit < mapped + kBuffer + team + (16ull << 20)) {
    char buf[320];
    std::snprintf(buf, sizeof buf,
                  "out of memory: the address-space limit (ulimit -v %llu kB) leaves %lld MB after start-up; "
                  "the BLAS library and %d threads alone need %llu MB",
                  static_cast<unsigned long long>(limit) / 1024,
                  (static_cast<long long>(limit) - static_cast<long long>(mapped)) / (1 << 20), threads,
                  (kBuffer + team + (16ull << 20)) >> 20);
    return buf;
  }
  // potrf takes OpenBLAS's buffer for any n > 0; OpenBLAS keeps it mapped for the later calls.
  double one = 1.0;
  const int n = 1;
  int info = 0;
  potrf("L", &n, &one, &n, &info);
  // libgomp keeps its team: start it now, while its stacks fit.
  int started = 0;
#pragma omp parallel reduction(+ : started)
  started += 1;
  (void)started;
  return "";
}

}  // namespace hgdcli
