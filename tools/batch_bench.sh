#!/usr/bin/env bash
# Times `hgdeform batch` on generated scans: --jobs 1 (all cores' OpenMP threads on each scan),
# --jobs 1 with one thread (OMP_NUM_THREADS=1), --jobs 2 and mpirun -np 2 (when the tool is built
# with MPI and mpirun is on PATH); prints files/second and speed-ups over the first, and checks
# that every mode writes byte-identical outputs.
#
# usage: tools/batch_bench.sh [BUILD_DIR] [COUNT] [POINTS]     (defaults: build 50 50000)
set -euo pipefail

BUILD=${1:-build}
COUNT=${2:-50}
POINTS=${3:-50000}
TOOL=$BUILD/tools/hgdeform
MAKE=$BUILD/tools/hgdeform-make-scans
for exe in "$TOOL" "$MAKE"; do
  [[ -x $exe ]] || { echo "batch_bench.sh: $exe not built (ninja hgdeform-cli hgdeform-make-scans)" >&2; exit 2; }
done

WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
"$MAKE" "$WORK/in" "$COUNT" "$POINTS"
echo "$(nproc) cores; $(du -sh "$WORK/in" | cut -f1) of input"

now() { date +%s.%N; }
BASE=""
declare -a ROWS

# bench LABEL OUT_DIR COMMAND...: runs COMMAND (a fresh OUT_DIR each time), records the time.
bench() {
  local label=$1 out=$2
  shift 2
  rm -rf "$out"
  local t0 t1
  t0=$(now)
  "$@" >"$WORK/$label.log" 2>&1 || { echo "batch_bench.sh: $label failed:" >&2; cat "$WORK/$label.log" >&2; exit 1; }
  t1=$(now)
  local s
  s=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.2f", b - a }')
  [[ -n $BASE ]] || BASE=$s
  ROWS+=("$(awk -v l="$label" -v s="$s" -v n="$COUNT" -v b="$BASE" \
    'BEGIN { printf "%-22s %8.2f s %8.2f files/s %7.2fx", l, s, n / s, b / s }')")
  if [[ $out != "$WORK/out-jobs1" ]] && ! diff -rq "$WORK/out-jobs1" "$out" >/dev/null; then
    echo "batch_bench.sh: $label: outputs differ from --jobs 1" >&2
    exit 1
  fi
}

common=(batch -s "$WORK/in/scenario.json" "$WORK/in" -q)
bench "jobs1" "$WORK/out-jobs1" "$TOOL" "${common[@]}" -o "$WORK/out-jobs1" --jobs 1
bench "jobs1-1thread" "$WORK/out-jobs1t" env OMP_NUM_THREADS=1 "$TOOL" "${common[@]}" -o "$WORK/out-jobs1t" --jobs 1
bench "jobs2" "$WORK/out-jobs2" "$TOOL" "${common[@]}" -o "$WORK/out-jobs2" --jobs 2
if command -v mpirun >/dev/null && [[ $(ldd "$TOOL") == *libmpi* ]]; then
  root=()
  [[ $(id -u) == 0 ]] && root=(--allow-run-as-root)
  bench "mpirun-np2" "$WORK/out-mpi2" mpirun "${root[@]}" -np 2 "$TOOL" "${common[@]}" -o "$WORK/out-mpi2"
else
  echo "(no MPI run: mpirun missing or $TOOL built without MPI)"
fi

echo
echo "hgdeform batch, $COUNT scans of $POINTS points (bumpy planes):"
printf '%-22s %10s %16s %8s\n' "mode" "wall" "rate" "speed-up"
for row in "${ROWS[@]}"; do echo "$row"; done
