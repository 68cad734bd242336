#!/bin/sh
# ctest python_pip_install (python/CMakeLists.txt): `pip install .` from the checkout into a fresh
# venv (with the system's site packages: Debian's numpy; no network, no build isolation), then
# the installed package imported from elsewhere, LD_LIBRARY_PATH and PYTHONPATH unset, and one
# deform. setup.py builds in SOURCE/build-pip through ccache, so a warm cache makes it a relink.
#   pip_install.sh SOURCE WORK PYTHON [CMAKE_ARG...]
set -eu
src=$1 work=$2 python=$3
shift 3
rm -rf "$work"
mkdir -p "$work"
"$python" -m venv --system-site-packages "$work/venv"
cd "$src"
HGDEFORM_CMAKE_ARGS="$*" "$work/venv/bin/python" -m pip install --no-build-isolation --no-deps \
  --no-cache-dir --disable-pip-version-check -q .
cd "$work"
env -u LD_LIBRARY_PATH -u PYTHONPATH "$work/venv/bin/python" - "$work/venv" <<'PY'
import sys

import numpy as np

import hgdeform

venv = sys.argv[1]
assert hgdeform.__file__.startswith(venv), hgdeform.__file__  # the installed package, not a tree's
rng = np.random.default_rng(1)
points = rng.uniform(0.0, 1.0, (800, 3)) * (10.0, 1.0, 1.0)
scenario = (hgdeform.Scenario().fix(np.flatnonzero(points[:, 0] < 1.0))
            .manipulate(np.flatnonzero(points[:, 0] > 9.0)).frame(translate=(0.0, 1.0, 0.0)))
out, report = hgdeform.deform(points, scenario)
tip = points[:, 0] > 9.0
assert report["points"] == len(points)
assert np.abs(out[tip] - (points[tip] + (0.0, 1.0, 0.0))).max() < 1e-9
print("pip install: hgdeform", hgdeform.__version__, "from", hgdeform.__file__)
PY
