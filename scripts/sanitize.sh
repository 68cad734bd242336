#!/usr/bin/env bash
# Builds hgdeform and its tests with AddressSanitizer + UndefinedBehaviorSanitizer (gcc,
# RelWithDebInfo, HGDEFORM_SANITIZE=ON) in build-asan/ and runs the whole test suite there.
# Any memory error, leak or undefined behaviour fails the run.
# Usage: bash scripts/sanitize.sh      (JOBS=N for the build, default 2)
set -euo pipefail
cd "$(dirname "$0")/.."
build=build-asan

cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DHGDEFORM_SANITIZE=ON -DHGDEFORM_WERROR=ON
cmake --build "$build" -j "${JOBS:-2}"

# Suppressions cover third-party code only; each entry is explained in its file.
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1"
export LSAN_OPTIONS="suppressions=$PWD/tests/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:suppressions=$PWD/tests/ubsan.supp"
status=0
ctest --test-dir "$build" --output-on-failure -j 2 --timeout 1800 -E '^BatchMpi\.' || status=1
# OpenMPI never frees what MPI_Init allocates, much of it inside plugins that MPI_Finalize
# unloads: only full stacks (the slow unwinder) reach the libmpi frames that lsan.supp names.
# So the tests that run under mpirun get the slow unwinder, and only they.
ASAN_OPTIONS="$ASAN_OPTIONS:fast_unwind_on_malloc=0" \
  ctest --test-dir "$build" --output-on-failure --timeout 1800 -R '^BatchMpi\.' || status=1
exit $status
