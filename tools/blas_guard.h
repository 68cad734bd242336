#pragma once
// Running under an address-space limit (`ulimit -v`, RLIMIT_AS) with OpenBLAS.
//
// OpenBLAS (Debian 12 ships 0.3.21) maps a 128 MiB work buffer per thread and, when mmap fails,
// retries for ever (OpenMathLib/OpenBLAS#5289, fixed upstream in 0.3.30). Under a tight
// `ulimit -v` its worker thread spins at start-up and exit() waits on it; a later BLAS call on
// the main thread (CHOLMOD's dpotrf) would spin the same way. So, only when RLIMIT_AS is set:
//  - reserveBlasBuffer(), first thing in main, re-executes the program with
//    OPENBLAS_NUM_THREADS=1 unless the user chose a value: no worker thread, one buffer; and with
//    OMP_THREAD_LIMIT at the program's thread count unless the user chose one (CHOLMOD asks for
//    a team of 4 whatever the count, and libgomp ends the program when it cannot map a thread's
//    stack);
//  - then maps that one buffer while the address space is still free (OpenBLAS keeps and
//    reuses it), or fails with a message if it cannot fit.
// Without a limit reserveBlasBuffer() does nothing.

#include <string>

namespace hgdcli {

/// OpenBLAS on one thread unless OPENBLAS_NUM_THREADS says otherwise, and the worker thread it
/// started at load time stopped. hgdeform's BLAS work is CHOLMOD on the field's coarse system
/// (10k unknowns at 173k points, 61k at 1M), where a second BLAS thread gains little, while
/// OpenBLAS's idle threads spin (sched_yield) on the core the OpenMP team needs: at 173k points
/// that cost the kNN and the field solve up to 2x, and the first 0.13 s of every run (the worker
/// started at load spins that long) about 100 ms of a 200k-point command on two threads.
void singleThreadBlas();

/// `argv` as main received it (for the exec). Returns "" when it is safe to go on, otherwise the message to
/// print before exiting 1.
std::string reserveBlasBuffer(char** argv);

}  // namespace hgdcli
