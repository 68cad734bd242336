#include "huge_pages.h"

#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>

namespace hgdcli {

namespace {

bool hugePagesOnRequestOnly() {
  std::ifstream f("/sys/kernel/mm/transparent_hugepage/enabled");
  std::string line;
  return std::getline(f, line) && line.find("[madvise]") != std::string::npos;
}

}  // namespace

void hugePageMalloc(char** argv) {
  const char* old = std::getenv("GLIBC_TUNABLES");
  const std::string tunables = old ? old : "";
  if (tunables.find("glibc.malloc.hugetlb") != std::string::npos) return;  // chosen already
  if (!hugePagesOnRequestOnly()) return;  // `always` gives them anyway; `never` not at all
  const std::string set = tunables.empty() ? "glibc.malloc.hugetlb=1" : tunables + ":glibc.malloc.hugetlb=1";
  if (setenv("GLIBC_TUNABLES", set.c_str(), 1) != 0) return;
  execv("/proc/self/exe", argv);
  // No /proc, or the program was replaced while it ran: go on without.
  if (old)
    setenv("GLIBC_TUNABLES", old, 1);
  else
    unsetenv("GLIBC_TUNABLES");
}

void hugePageMallocFor(const char* path, std::uintmax_t min_bytes, char** argv) {
  struct stat st {};
  if (path && stat(path, &st) == 0 && S_ISREG(st.st_mode) &&
      static_cast<std::uintmax_t>(st.st_size) >= min_bytes)
    hugePageMalloc(argv);
}

bool hugePageMallocOn() {
  const char* env = std::getenv("GLIBC_TUNABLES");
  if (!env) return false;
  const std::string t = env, key = "glibc.malloc.hugetlb=";
  bool on = false;
  for (std::size_t at = t.find(key); at != std::string::npos; at = t.find(key, at + 1))
    if (at == 0 || t[at - 1] == ':') {
      const char v = at + key.size() < t.size() ? t[at + key.size()] : '\0';
      on = v == '1' || v == '2';
    }
  return on;
}

}  // namespace hgdcli
