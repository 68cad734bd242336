#!/usr/bin/env bash
# Builds the libFuzzer targets (clang: fuzz/) and runs each for a bounded time, starting from
# its seed corpus in fuzz/corpus/<target>/. Fails (non-zero) on any crash, sanitizer report,
# leak, timeout or uncaught exception; the input that did it is kept in
# build-fuzz/artifacts/<target>/ (turn it into a regression test in tests/test_robust.cpp).
# On a failure it prints the fuzzer's report with its stack and the input (base64), so that a
# CI log alone is enough to reproduce it: base64 -d > crash; build-fuzz/fuzz/fuzz_<t> crash.
# Usage: bash scripts/fuzz.sh [SECONDS_PER_TARGET]    (default 60; JOBS=N for the build;
#        SEED=N for libFuzzer's -seed, which makes a run repeat the same mutations: CI uses one)
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-60}
build=build-fuzz
targets=(fuzz_scenario fuzz_ply fuzz_pcd fuzz_obj fuzz_xyz fuzz_off fuzz_stl fuzz_pts fuzz_las)

source scripts/ccache.sh
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo "${HGD_LAUNCHER[@]}" \
  -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_C_COMPILER=clang -DHGDEFORM_FUZZ=ON \
  -DHGDEFORM_BUILD_TESTS=OFF -DHGDEFORM_BUILD_TOOLS=OFF -DHGDEFORM_PYTHON=OFF >/dev/null
cmake --build "$build" --target fuzz_targets -j "${JOBS:-2}"

status=0
summary=""
for t in "${targets[@]}"; do
  name=${t#fuzz_}
  work="$build/corpus/$name"       # grows as the fuzzer finds new coverage; the seeds stay clean
  artifacts="$build/artifacts/$name/"
  mkdir -p "$work" "$artifacts"
  dict=()
  [ -f "fuzz/$name.dict" ] && dict=(-dict="fuzz/$name.dict")
  log="$build/$t.log"
  echo "--- $t: ${secs}s ---"
  rc=0
  seed=()
  [ -n "${SEED:-}" ] && seed=(-seed="$SEED")
  # The reader targets' scratch directory (fuzz_reader.cpp: hgd-fuzz-<pid> in /dev/shm or the
  # temporary directory): libFuzzer ends without running atexit handlers when its time is up or
  # it finds a crash, so it is removed here, and so is the fuzzer if this script is stopped.
  "$build/fuzz/$t" -max_total_time="$secs" -rss_limit_mb=2048 -timeout=10 -print_final_stats=1 "${seed[@]}" \
    -artifact_prefix="$artifacts" "${dict[@]}" "$work" "fuzz/corpus/$name" >"$log" 2>&1 &
  pid=$!
  trap 'kill "$pid" 2>/dev/null; rm -rf "/dev/shm/hgd-fuzz-$pid" "${TMPDIR:-/tmp}/hgd-fuzz-$pid"; exit 130' INT TERM
  wait "$pid" || rc=$?
  trap - INT TERM
  rm -rf "/dev/shm/hgd-fuzz-$pid" "${TMPDIR:-/tmp}/hgd-fuzz-$pid"
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  if [ "$rc" -ne 0 ]; then
    status=1
    echo "$t FAILED (exit $rc); log: $log; artifacts: $artifacts"
    # The report: from the first error line to the artifact's name (the stack is in between).
    sed -n '/ERROR\|runtime error\|broken invariant\|fuzz harness\|terminate called/,/Test unit written/p' "$log" |
      head -80 || true
    grep -E "^INFO: Seed:" "$log" | head -1 || true
    for a in "$artifacts"*; do
      [ -f "$a" ] || continue
      echo "input $(basename "$a") ($(stat -c %s "$a") bytes), base64:"
      head -c 16384 "$a" | base64
    done
  fi
  summary+=$(printf '%-14s %10s executions  %s' "$t" "${execs:-?}" "$([ "$rc" -eq 0 ] && echo ok || echo FAILED)")$'\n'
done
echo "--- fuzzing summary (${secs}s per target) ---"
printf '%s' "$summary"
exit $status
