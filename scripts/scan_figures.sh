#!/usr/bin/env bash
# The real-scan figures (docs/scans.md): scan-shaped inputs (a fork at 50k-4M points, with noise
# and outliers; the Armadillo as a mesh and resampled with normals in random signs, where
# $ARMADILLO or the default path has it) deformed by one or more builds of `hgdeform`, one row per case
# and build: clusters, unreachable, torn and split points among the surface points (not the
# strays a case adds), largest stretch, build ms.
# Usage: bash scripts/scan_figures.sh HGDEFORM [HGDEFORM ...]   (after a build: build/tools/hgdeform)
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -ge 1 ] || { echo "usage: $0 HGDEFORM [HGDEFORM ...]" >&2; exit 2; }
figures=build/tests/hgdeform-scan-figures
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
armadillo=${ARMADILLO:-../shared/datasets/meshes/armadillo_49990.ply}
[ -f "$armadillo" ] || armadillo=""
"$figures" gen "$work" $armadillo
printf '%-28s %-6s %8s %11s %6s %6s %8s %8s\n' case build clusters unreachable torn split stretch build_ms
while read -r name input scenario drag surface; do
  b=0
  for tool in "$@"; do
    b=$((b + 1))
    out="$work/out_$b.ply"
    rm -f "$out" "$work/r.json"
    "$tool" deform "$work/$input" --scenario "$work/$scenario" -o "$out" --report "$work/r.json" >/dev/null 2>&1 || {
      echo "$name: build $b failed" >&2
      continue
    }
    read -r clusters unreachable ms < <(python3 -c 'import json,sys; r=json.load(open(sys.argv[1])); print(r["clusters"], r.get("unreachable", 0), r["ms"]["build"])' "$work/r.json")
    read -r _ torn _ split _ stretch < <("$figures" measure "$work/$input" "$out" "$drag" "$surface")
    printf '%-28s %-6s %8s %11s %6s %6s %8s %8.0f\n' "$name" "$b" "$clusters" "$unreachable" "$torn" "$split" "$stretch" "$ms"
  done
done < "$work/cases.txt"
