// The OpenMP thread count of a test (tests that compare results on 1, 2 and 3 threads).
#pragma once

#include <omp.h>

namespace hgdtest {

/// Sets the OpenMP thread count back to what it was when made.
class ThreadCount {
 public:
  explicit ThreadCount(int threads) : threads_(threads) {}
  ~ThreadCount() { omp_set_num_threads(threads_); }
  ThreadCount(const ThreadCount&) = delete;
  ThreadCount& operator=(const ThreadCount&) = delete;

 private:
  int threads_;
};

}  // namespace hgdtest
