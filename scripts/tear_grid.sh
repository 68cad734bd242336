#!/bin/bash
# The tear grid of docs/method.md ("Limiting the reweighting so that it cannot tear"): sharp
# frame moves of a thin square tube (generated here) and, when its mesh is given, of the
# Armadillo's right arm, through `hgdeform deform`; prints each move that pulls the surface
# apart (the report's surface.split_points) and the totals.
#
#   bash scripts/tear_grid.sh HGDEFORM [ARMADILLO.ply] [-- deform flags...]
#   bash scripts/tear_grid.sh build/tools/hgdeform armadillo_49990.ply -- -c 32 --reweight 8
set -euo pipefail
hgdeform=${1:?usage: tear_grid.sh HGDEFORM [ARMADILLO.ply] [-- deform flags...]}
shift
armadillo=""
if [ $# -gt 0 ] && [ "$1" != "--" ]; then
  armadillo=$1
  shift
fi
[ $# -gt 0 ] && [ "$1" = "--" ] && shift
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# The tube: 1 long, 0.1 across, its four sides sampled every 0.008 with outward normals, in
# random order (seeded); x < 0.05 fixed, x > 0.95 the handle.
python3 - "$work/bar.ply" <<'EOF'
import random, sys
random.seed(3)
h, w, pts, x = 0.008, 0.1, [], 0.0
while x <= 1.0:
    t = -w / 2
    while t < w / 2:
        for p, n in (((x, t, -w / 2), (0, 0, -1)), ((x, w / 2, t), (0, 1, 0)),
                     ((x, -t, w / 2), (0, 0, 1)), ((x, -w / 2, -t), (0, -1, 0))):
            pts.append(p + n)
        t += h
    x += h
random.shuffle(pts)
with open(sys.argv[1], "w") as f:
    f.write("ply\nformat ascii 1.0\nelement vertex %d\n" % len(pts))
    f.write("".join("property float %s\n" % c for c in ("x", "y", "z", "nx", "ny", "nz")))
    f.write("end_header\n")
    for p in pts:
        f.write("%g %g %g %g %g %g\n" % p)
EOF

cases=0 moves=0 torn=0
# run NAME INPUT FIXED_MIN FIXED_MAX HANDLE_MIN HANDLE_MAX TRANSLATE AXIS DEGREES
run() {
  local name=$1 input=$2
  cat > "$work/s.json" <<EOF
{"fixed": [{"box": {"min": [$3], "max": [$4]}}], "manipulated": {"box": {"min": [$5], "max": [$6]}},
 "move": {"frame": {"translate": [$7], "rotate": {"axis": [$8], "degrees": $9}}}}
EOF
  rm -f "$work/out.ply" "$work/r.json"
  "$hgdeform" deform "$input" -s "$work/s.json" -o "$work/out.ply" -q --report "$work/r.json" "${flags[@]}" \
    2> /dev/null || true
  moves=$((moves + 1))
  [ -f "$work/r.json" ] || { echo "  $name: failed"; return; }
  local st sp
  read -r st sp < <(python3 -c "import json,sys; s=json.load(open(sys.argv[1]))['surface']; \
print(round(s['max_stretch'], 2), s['split_points'])" "$work/r.json")
  if [ "$sp" != 0 ]; then
    cases=$((cases + 1))
    torn=$((torn + sp))
    echo "  $name: a pair stretched ${st}x, $sp points torn"
  fi
}
flags=("$@")
for deg in 90 135; do
  for ax in "0,1,0" "0,0,1"; do
    for tr in "0,0,0" "-0.3,0,0.3" "-0.5,0,0.5" "-0.7,0,0.3" "-0.9,0,0.1"; do
      run "tube $deg° about [$ax], translated [$tr]" "$work/bar.ply" \
        "-1,-1,-1" "0.05,1,1" "0.95,-1,-1" "2,1,1" "$tr" "$ax" "$deg"
    done
  done
done
if [ -n "$armadillo" ]; then
  for ax in "0,0,1" "1,0,0" "0,1,0"; do
    for tr in "0,0,0" "0,25,0" "-20,20,0"; do
      run "Armadillo arm 90° about [$ax], translated [$tr]" "$armadillo" \
        "-100,-100,-100" "100,-45,100" "48,-100,-100" "100,200,100" "$tr" "$ax" 90
    done
  done
fi
echo "flags [${flags[*]}]: $cases of $moves moves torn, $torn points"
