# Sourced by the build scripts: compiler caching through ccache when it is installed
# (scripts/install-deps.sh installs it). Rebuilds of an unchanged file, in this clone or in
# another clone of the repository on the same machine, come from the cache: the cache is keyed
# on paths relative to the clone (CCACHE_BASEDIR) and not on the working directory, so a CI
# run in a fresh clone reuses what a developer's builds compiled. Sets HGD_LAUNCHER for cmake.
HGD_LAUNCHER=()
if command -v ccache >/dev/null 2>&1 && [ "${HGD_NO_CCACHE:-}" != 1 ]; then
  export CCACHE_BASEDIR="$PWD" CCACHE_NOHASHDIR=1
  HGD_LAUNCHER=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
fi
