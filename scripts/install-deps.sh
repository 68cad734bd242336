#!/usr/bin/env bash
# Installs the Debian 12 packages hgdeform needs to build, test and run its viewer.
# Idempotent; needs root (or sudo). Usage: scripts/install-deps.sh
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config git
  ccache                                    # scripts/ccache.sh: rebuilds from the cache, in any clone
  libpcl-dev libeigen3-dev libflann-dev libboost-dev
  liblz4-dev                                # FLANN's headers call LZ4: libhgdeform links it
  liblzf-dev                                # PCD binary_compressed (LZF) without linking pcl_io (and VTK)
  libsuitesparse-dev libopenblas0-pthread   # CHOLMOD for the exact field solve; OpenBLAS ~3x faster than reference BLAS
  nlohmann-json3-dev                        # scenario JSON
  libcli11-dev                              # the tools' command lines (header-only)
  libxxhash-dev                             # hgdeform batch: content hashes of the inputs (provenance)
  libopenmpi-dev openmpi-bin                # hgdeform batch under mpirun (already pulled in by VTK)
  libpng-dev                                # the viewer tests read screenshots
  libx11-dev                                # the renderer asks X whether a display opens (pulled in by VTK too)
  libgtest-dev libgmock-dev libbenchmark-dev
  libcgal-dev                               # hgdeform-bench --arap: CGAL's ARAP, the peer (header-only, optional)
  xvfb xauth clang-format
  xdotool                                   # tests/test_viewer_x.cpp: real X keyboard and mouse events (XTEST) for the viewer
  clang libclang-rt-14-dev                  # scripts/fuzz.sh: libFuzzer targets (clang's runtime)
  pybind11-dev python3-dev                  # the Python module, import hgdeform (python/, header-only binding)
  python3-numpy                             # the Python module's arrays (numpy in and out)
  python3-pytest                            # the Python tests (python/tests, run by ctest)
  python3-open3d                            # the Python tests' Open3D interop (optional for the module; ~15 s to install)
  python3-setuptools python3-wheel          # pip install . (pyproject.toml, setup.py drives CMake; no build isolation)
  python3-venv python3-pip                  # the python_pip_install test: pip install . into a fresh venv
  cloudcompare meshlab pcl-tools            # tests/conformance: files written by CloudCompare, meshlabserver and pcl_* converters (headless under xvfb-run)
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
echo "install-deps: installing ${missing[*]}"
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install-deps: done"
