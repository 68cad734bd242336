#pragma once
// glibc's malloc for the programs' large runs: huge pages, and freed memory kept for reuse.
//
// A 1M-point `hgdeform deform` touches some 150 MB of fresh memory. Where the kernel gives
// transparent huge pages only on request (`/sys/kernel/mm/transparent_hugepage/enabled` reads
// `[madvise]`, as on this project's machines), that is some 38,000 page faults of 4 KiB, each
// taking the address space's and the memory cgroup's locks, so that two threads filling buffers
// fault in turn. glibc asks for huge pages for the heap and for large blocks when told to
// (GLIBC_TUNABLES=glibc.malloc.hugetlb=1, glibc 2.35 and later): some 6,000 faults. The switch is
// read when the program starts, so the programs restart themselves with it (about 10 ms).

#include <cstdint>
#include <string>
#include <vector>

namespace hgdcli {

/// Restarts the program (execv of /proc/self/exe with `argv`) with glibc.malloc.hugetlb=1 added
/// to GLIBC_TUNABLES when the kernel's huge pages are `[madvise]`, glibc is 2.35 or later and
/// GLIBC_TUNABLES does not already set glibc.malloc.hugetlb (a user's own value, 0 included, is
/// kept). Never twice (the restart marks the environment), nor in a setuid program. Returns when
/// it does not restart, or when the exec fails (the program then goes on as it is).
void hugePageMalloc(char** argv);

/// hugePageMalloc() when the file `path` holds at least `min_bytes` (a small run would pay more
/// for the restart than it saves); nothing for a path that is not a regular file.
void hugePageMallocFor(const char* path, std::uintmax_t min_bytes, char** argv);

/// Whether this process runs with glibc's huge-page malloc, as far as its environment says:
/// glibc 2.35 or later and GLIBC_TUNABLES setting glibc.malloc.hugetlb to 1 or 2 (the last
/// setting counts, as glibc reads it).
bool hugePageMallocOn();

/// Keeps the memory the program frees for its later allocations, as jemalloc and tcmalloc do,
/// where glibc gives it back: glibc serves each block above its mmap threshold (128 KiB, rising
/// as blocks are freed up to 32 MiB, above which every block is mapped: at 4M points most of a
/// build's arrays) with its own mmap and unmaps it when freed, so that every build, and every
/// stage of one, writes fresh pages that the kernel first zeroes: at 4M points on this project's
/// machines that cost a quarter of a one-thread build's time, and it scales worse than the build
/// on two threads. Sets M_MMAP_MAX to 0 (large blocks come from the heap; on a thread other than
/// the main one, a block too large for its arena's heaps, 64 MiB, still gets its own mapping)
/// and M_TRIM_THRESHOLD to 2 GiB (freed memory stays mapped). For the programs that build one
/// shape and exit, and the bench: hgdeform deform and field, hgdeform-bench. Leaves glibc's defaults when the
/// environment sets any of these thresholds (GLIBC_TUNABLES' glibc.malloc.mmap_max, .mmap_threshold,
/// .trim_threshold, .top_pad, or MALLOC_MMAP_MAX_, MALLOC_MMAP_THRESHOLD_, MALLOC_TRIM_THRESHOLD_,
/// MALLOC_TOP_PAD_): a user's choice wins; and under a limit on the address space or the data
/// segment (`ulimit -v`, `ulimit -d`), where memory kept is memory the limit no longer leaves
/// for a thread's stack or a library's buffers. Returns whether it set them.
bool keepFreedMemory();

/// The environment as the user gave it (GLIBC_TUNABLES as it was before hugePageMalloc's
/// restart, the restart's marks left out), for programs this one starts to be timed as a user
/// runs them: the bench's `hgdeform deform`. Entries "NAME=value".
std::vector<std::string> userEnvironment();

}  // namespace hgdcli
