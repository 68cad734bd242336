#!/usr/bin/env bash
# Checks that two builds of `hgdeform` write byte-identical outputs (a refactoring must not
# change results): the bundled bunny dragged (.ply/.pcd/.obj; ascii with the linear blend and 8
# isovalues), a frame move then a drag, the field with colours, and, when ../shared has it, the
# Armadillo turned by a frame move, a 600k-point procedural scan (the multi-resolution build) and
# the noisy mug scan with its strays. Prints one sha256 per output and whether the builds agree.
#   bash scripts/same_outputs.sh OLD/tools/hgdeform NEW/tools/hgdeform
set -euo pipefail
cd "$(dirname "$0")/.."
old=$1 new=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
d=datasets
cat > "$work/frame.json" <<'JSON'
{"format": "hgdeform-scenario/1",
 "fixed": [{"box": {"min": [-10, -1, -10], "max": [10, 0.8, 10]}}],
 "manipulated": {"box": {"min": [-10, 8.0, -10], "max": [10, 11, 10]}},
 "move": [{"frame": {"translate": [1, 0, 0], "rotate": {"axis": [0, 0, 1], "degrees": 50}}},
          {"drag": {"from": [0.0027, 9.6547, -1.3556], "to": [3, 8, -1]}}]}
JSON
armadillo=../shared/datasets/meshes/armadillo_49990.ply
cat > "$work/arma.json" <<'JSON'
{"format": "hgdeform-scenario/1",
 "fixed": [{"box": {"min": [-65, -56, -59], "max": [65, -42.1, 59]}}],
 "manipulated": {"box": {"min": [-65, 81.9, -59], "max": [65, 99, 59]}},
 "move": [{"frame": {"translate": [30.26, 0, 0], "rotate": {"axis": [0, 0, 1], "degrees": 30}}}]}
JSON
# A noisy organized stereo scan (NaNs, strays): its left part fixed, its right part dragged.
mug=../shared/datasets/pointclouds/table_scene_mug_stereo_textured.pcd
cat > "$work/mug.json" <<'JSON'
{"format": "hgdeform-scenario/1",
 "fixed": [{"box": {"min": [-0.5, -0.6, 0.6], "max": [-0.2, 0.2, 2.7]}}],
 "manipulated": {"box": {"min": [0.5, -0.6, 0.6], "max": [0.8, 0.2, 2.7]}},
 "move": [{"frame": {"translate": [0, -0.1, 0], "rotate": {"axis": [0, 0, 1], "degrees": 15}}}]}
JSON
# A cloud above the multi-resolution threshold (600k points), made by the new build's tool.
"$(dirname "$new")/hgdeform-make-scans" "$work/big" 1 600000 > /dev/null
big=$(ls "$work"/big/*.p* | head -1)
run() {
  local bin=$1 out=$2
  mkdir -p "$out"
  "$bin" deform $d/bunny_1839.ply -s $d/bunny_ears.json -o "$out/b.ply" -q
  "$bin" deform $d/bunny_1839.ply -s $d/bunny_ears.json -o "$out/b.pcd" -q
  "$bin" deform $d/bunny_1839.ply -s $d/bunny_ears.json -o "$out/b.obj" -q
  "$bin" deform $d/bunny_1839.ply -s $d/bunny_ears.json -o "$out/ba.ply" --ascii -q --blend linear -c 8
  "$bin" deform $d/bunny_1839.ply -s "$work/frame.json" -o "$out/bf.ply" -q
  "$bin" field $d/bunny_1839.ply -s $d/bunny_ears.json -o "$out/bfield.ply" -q --color
  "$bin" deform "$big" -s "$work/big/scenario.json" -o "$out/big.ply" -q
  if [ -f "$mug" ]; then "$bin" deform "$mug" -s "$work/mug.json" -o "$out/mug.pcd" -q; fi
  if [ -f "$armadillo" ]; then "$bin" deform "$armadillo" -s "$work/arma.json" -o "$out/arma.ply" -q; fi
  (cd "$out" && sha256sum -- *)
}
run "$old" "$work/old" > "$work/old.sum"
run "$new" "$work/new" > "$work/new.sum"
cat "$work/new.sum"
if diff "$work/old.sum" "$work/new.sum"; then echo "same outputs"; else echo "OUTPUTS DIFFER"; exit 1; fi
