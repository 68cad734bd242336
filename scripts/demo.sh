#!/usr/bin/env bash
# Installs the dependencies, builds hgdeform and runs it on the bundled bunny: the ears are
# dragged sideways with the base fixed. Writes bunny_field.ply (the harmonic field as a
# 'harmonic' scalar and colours) and bunny_deformed.ply (+ bunny_report.json) in the
# current directory.
set -euo pipefail
out_dir=$(pwd)
root=$(cd "$(dirname "$0")/.." && pwd)
bash "$root/scripts/install-deps.sh"
cmake -S "$root" -B "$root/build" -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build "$root/build" -j 2 --target hgdeform-cli
tool="$root/build/tools/hgdeform"
"$tool" field "$root/datasets/bunny_1839.ply" --scenario "$root/datasets/bunny_ears.json" \
  -o "$out_dir/bunny_field.ply" --color
"$tool" deform "$root/datasets/bunny_1839.ply" --scenario "$root/datasets/bunny_ears.json" \
  -o "$out_dir/bunny_deformed.ply" --report "$out_dir/bunny_report.json"
echo "wrote $out_dir/bunny_field.ply, $out_dir/bunny_deformed.ply and $out_dir/bunny_report.json"
