// The programs' malloc policy (tools/huge_pages.h): freed blocks stay for reuse, unless the
// user's environment chose glibc's thresholds.
#include <gtest/gtest.h>
#include <malloc.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <utility>
#include <vector>

#include "huge_pages.h"
#include "test_util.h"

namespace {

// glibc's malloc settings belong to the process, so each case runs in a child: with `env` set
// (after clearing every variable keepFreedMemory() reads), it calls keepFreedMemory() and says
// in its exit status what malloc then did with a 48 MiB block (above glibc's largest mmap
// threshold, 32 MiB, so glibc's defaults give it a mapping of its own and unmap it on free):
// bit 0, keepFreedMemory() returned true; bit 1, the block came from the heap (no mapping of its
// own, as glibc counts them); bit 2, the heap still held it after the free (not given back).
// With `limit_resource`, the child runs under a limit of 1 TiB on that resource.
int probe(const std::vector<std::pair<std::string, std::string>>& env, int limit_resource = -1) {
  std::fflush(nullptr);
  const pid_t pid = fork();
  if (pid == 0) {
    if (limit_resource >= 0) {  // a limit far above what the child uses, but a limit
      const rlimit rl{rlim_t{1} << 40, rlim_t{1} << 40};
      if (setrlimit(limit_resource, &rl) != 0) _exit(65);
    }
    for (const char* name : {"GLIBC_TUNABLES", "MALLOC_MMAP_MAX_", "MALLOC_MMAP_THRESHOLD_",
                             "MALLOC_TRIM_THRESHOLD_", "MALLOC_TOP_PAD_"})
      unsetenv(name);
    for (const auto& [name, value] : env) setenv(name.c_str(), value.c_str(), 1);
    int bits = hgdcli::keepFreedMemory() ? 1 : 0;
    constexpr std::size_t kBlock = std::size_t{48} << 20;
    const std::size_t mapped_before = mallinfo2().hblks, heap_before = mallinfo2().arena;
    void* block = std::malloc(kBlock);
    if (!block) _exit(64);
    __asm__ volatile("" : : "r"(block) : "memory");  // (used: the pair is not optimised away)
    if (mallinfo2().hblks == mapped_before) bits |= 2;
    std::free(block);
    if (mallinfo2().arena >= heap_before + kBlock) bits |= 4;
    _exit(bits);
  }
  int status = 0;
  if (pid < 0 || waitpid(pid, &status, 0) != pid || !WIFEXITED(status)) return -1;
  return WEXITSTATUS(status);
}

}  // namespace

// AddressSanitizer's allocator answers mallopt itself, and ignores it.
#ifdef HGD_TEST_ASAN
#define HGD_SKIP_UNDER_ASAN() GTEST_SKIP() << "AddressSanitizer's allocator ignores mallopt"
#else
#define HGD_SKIP_UNDER_ASAN() (void)0
#endif

TEST(MallocPolicy, LargeBlocksComeFromTheHeapAndStayThereWhenFreed) {
  HGD_SKIP_UNDER_ASAN();
  EXPECT_EQ(probe({}), 7);
  // Huge pages are not a threshold: the programs' own restart sets them.
  EXPECT_EQ(probe({{"GLIBC_TUNABLES", "glibc.malloc.hugetlb=1"}}), 7);
  EXPECT_EQ(probe({{"GLIBC_TUNABLES", "glibc.malloc.hugetlb=1:glibc.malloc.tcache_count=0"}}), 7);
  // A value that spells a threshold's name is no threshold (entries are name=value, ':' apart).
  EXPECT_EQ(probe({{"GLIBC_TUNABLES", "glibc.cpu.x86_ibt=glibc.malloc.mmap_max"}}), 7);
}

TEST(MallocPolicy, AUsersOwnThresholdsAreKept) {
  HGD_SKIP_UNDER_ASAN();
  // glibc reads these at start; a child set afterwards keeps glibc's defaults, and so must the
  // policy: the block gets its own mapping and goes back on free.
  const std::vector<std::pair<std::string, std::string>> choices = {
      {"MALLOC_MMAP_MAX_", "65536"},
      {"MALLOC_MMAP_THRESHOLD_", "131072"},
      {"MALLOC_TRIM_THRESHOLD_", "131072"},
      {"MALLOC_TOP_PAD_", "0"},
      {"GLIBC_TUNABLES", "glibc.malloc.mmap_max=65536"},
      {"GLIBC_TUNABLES", "glibc.malloc.hugetlb=1:glibc.malloc.mmap_threshold=131072"},
      {"GLIBC_TUNABLES", "glibc.malloc.trim_threshold=131072:glibc.malloc.hugetlb=1"},
      {"GLIBC_TUNABLES", "glibc.malloc.top_pad=0"}};
  for (const auto& choice : choices) EXPECT_EQ(probe({choice}), 0) << choice.first << "=" << choice.second;
}

TEST(MallocPolicy, UnderAnAddressSpaceOrDataLimitFreedMemoryGoesBack) {
  HGD_SKIP_UNDER_ASAN();
  // Memory kept counts against `ulimit -v` and `ulimit -d`: a program under either, near its
  // limit, could not start a thread after a large stage freed its arrays.
  rlimit as{}, data{};
  ASSERT_EQ(getrlimit(RLIMIT_AS, &as), 0);
  ASSERT_EQ(getrlimit(RLIMIT_DATA, &data), 0);
  if (as.rlim_max < (rlim_t{1} << 40) || data.rlim_max < (rlim_t{1} << 40))
    GTEST_SKIP() << "this process is already under a lower limit";
  EXPECT_EQ(probe({}, RLIMIT_AS), 0);
  EXPECT_EQ(probe({}, RLIMIT_DATA), 0);
}
