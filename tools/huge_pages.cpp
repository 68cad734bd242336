#include "huge_pages.h"

#include <gnu/libc-version.h>
#include <malloc.h>
#include <sys/auxv.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <optional>
#include <string>

extern char** environ;

namespace hgdcli {

namespace {

// Set by the restart: that it happened, as the process id that the exec keeps (never twice,
// whatever glibc made of the tunable; a mark inherited from elsewhere is another id), and the
// user's own GLIBC_TUNABLES when there was one (for the bench's children, userEnvironment).
constexpr const char* kRestarted = "HGDEFORM_HUGE_PAGE_RESTART";
constexpr const char* kUserTunables = "HGDEFORM_USER_GLIBC_TUNABLES";

bool restarted() {
  const char* mark = std::getenv(kRestarted);
  return mark && std::to_string(getpid()) == mark;
}

bool hugePagesOnRequestOnly() {
  std::ifstream f("/sys/kernel/mm/transparent_hugepage/enabled");
  std::string line;
  return std::getline(f, line) && line.find("[madvise]") != std::string::npos;
}

// glibc.malloc.hugetlb is glibc 2.35's.
bool glibcKnowsHugetlb() {
  int major = 0, minor = 0;
  return std::sscanf(gnu_get_libc_version(), "%d.%d", &major, &minor) == 2 &&
         (major > 2 || (major == 2 && minor >= 35));
}

// The value GLIBC_TUNABLES gives `name`: its last name=value entry (entries are ':' apart), as
// glibc reads them; "" for an entry without a value; nothing when no entry names it.
std::optional<std::string> tunable(const char* name) {
  const char* env = std::getenv("GLIBC_TUNABLES");
  if (!env) return std::nullopt;
  const std::string t = env;
  std::optional<std::string> value;
  for (std::size_t at = 0; at <= t.size();) {
    const std::size_t end = std::min(t.find(':', at), t.size());
    const std::size_t eq = std::min(t.find('=', at), end);
    if (t.compare(at, eq - at, name) == 0) value = eq < end ? t.substr(eq + 1, end - eq - 1) : std::string();
    at = end + 1;
  }
  return value;
}

}  // namespace

void hugePageMalloc(char** argv) {
  if (restarted() || getauxval(AT_SECURE) != 0 || !glibcKnowsHugetlb()) return;
  const char* old = std::getenv("GLIBC_TUNABLES");
  const std::string tunables = old ? old : "";
  if (tunables.find("glibc.malloc.hugetlb") != std::string::npos) return;  // chosen already
  if (!hugePagesOnRequestOnly()) return;  // `always` gives them anyway; `never` not at all
  const std::string set = tunables.empty() ? "glibc.malloc.hugetlb=1" : tunables + ":glibc.malloc.hugetlb=1";
  if (setenv(kRestarted, std::to_string(getpid()).c_str(), 1) != 0 ||
      (old ? setenv(kUserTunables, old, 1) : unsetenv(kUserTunables)) != 0 ||
      setenv("GLIBC_TUNABLES", set.c_str(), 1) != 0)
    return;
  execv("/proc/self/exe", argv);
  // No /proc, or the program was replaced while it ran: go on without.
  unsetenv(kRestarted);
  unsetenv(kUserTunables);
  if (old)
    setenv("GLIBC_TUNABLES", tunables.c_str(), 1);
  else
    unsetenv("GLIBC_TUNABLES");
}

void hugePageMallocFor(const char* path, std::uintmax_t min_bytes, char** argv) {
  struct stat st {};
  if (path && std::strcmp(path, "-") != 0 && stat(path, &st) == 0 && S_ISREG(st.st_mode) &&
      static_cast<std::uintmax_t>(st.st_size) >= min_bytes)
    hugePageMalloc(argv);
}

bool hugePageMallocOn() {
  if (!glibcKnowsHugetlb()) return false;
  const std::optional<std::string> value = tunable("glibc.malloc.hugetlb");
  return value && (*value == "1" || *value == "2");
}

bool keepFreedMemory() {
  // Under a limit on the address space or the data segment, memory kept is memory the limit no
  // longer leaves for later needs (a thread's stack, OpenBLAS's buffers): glibc's way then.
  for (const int resource : {RLIMIT_AS, RLIMIT_DATA}) {
    rlimit rl{};
    if (getrlimit(resource, &rl) != 0 || rl.rlim_cur != RLIM_INFINITY) return false;
  }
  for (const char* name :
       {"MALLOC_MMAP_MAX_", "MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "MALLOC_TOP_PAD_"})
    if (std::getenv(name)) return false;
  for (const char* name : {"glibc.malloc.mmap_max", "glibc.malloc.mmap_threshold",
                           "glibc.malloc.trim_threshold", "glibc.malloc.top_pad"})
    if (tunable(name)) return false;
  if (mallopt(M_MMAP_MAX, 0) != 1) return false;
  if (mallopt(M_TRIM_THRESHOLD, INT_MAX) == 1) return true;
  mallopt(M_MMAP_MAX, 65536);  // glibc's default back: both or neither
  return false;
}

std::vector<std::string> userEnvironment() {
  std::vector<std::string> env;
  const bool was_restarted = restarted();
  for (char** e = environ; *e; ++e) {
    const std::string entry = *e;
    const std::string name = entry.substr(0, entry.find('='));
    if (was_restarted && (name == "GLIBC_TUNABLES" || name == kRestarted || name == kUserTunables)) continue;
    env.push_back(entry);
  }
  if (was_restarted)
    if (const char* user = std::getenv(kUserTunables)) env.push_back(std::string("GLIBC_TUNABLES=") + user);
  return env;
}

}  // namespace hgdcli
