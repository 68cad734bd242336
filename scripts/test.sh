#!/usr/bin/env bash
# Installs the dependencies, builds hgdeform (warnings as errors) and runs the whole test suite.
# Usage: bash scripts/test.sh        (from anywhere; root or sudo for the install step)
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
source scripts/ccache.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DHGDEFORM_WERROR=ON "${HGD_LAUNCHER[@]}"
cmake --build build -j 2
ctest --test-dir build --output-on-failure -j 2
