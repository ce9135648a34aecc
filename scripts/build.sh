#!/usr/bin/env bash
# Configures and builds Tessera: RelWithDebInfo, -O2. Extra args go to cmake.
#   build.sh [CMAKE_ARGS...]             everything: the programs, the tests and the benchmarks, with
#                                        debug info (-O2 -g; scripts/test.sh)
#   build.sh --programs [CMAKE_ARGS...]  only tessera-server, tessera-worker and tessera (scripts/showcase.sh)
# TESSERA_BUILD_DIR picks the build directory (default build/; the sanitizer build uses build-asan/).
#
# CMake keeps options in the build directory's cache, so each mode says what it needs, and
# CMAKE_ARGS come after (e.g. test.sh's -DTESSERA_BUILD_BENCH=OFF for build-asan/), so they win:
#  - everything turns the tests, the benchmarks and -g on every time: a tree that --programs
#    configured gains them (and compiles its objects again, with debug info);
#  - --programs configures a new tree without tests, benchmarks or debug info: -O2 -DNDEBUG, the
#    flags of the container images' build (docker/Dockerfile), and two that only make GCC faster:
#    -pipe (no temporary files) and a garbage collector that runs less often (up to ~1.5 GB per
#    compiler). None changes an instruction: the three programs disassemble byte for byte the same
#    as an -O2 -g build's, so no pixel changes either (docs/getting-started.md). An existing tree
#    keeps its options: --programs builds just the three programs' targets in it, so a tree with
#    tests keeps them.
set -euo pipefail
cd "$(dirname "$0")/.."
dir=${TESSERA_BUILD_DIR:-build}
jobs=$(nproc 2>/dev/null || echo 2)
programs=0
if [ "${1:-}" = --programs ]; then
  programs=1
  shift
fi
generator=()
command -v ninja >/dev/null && generator=(-G Ninja)
# ccache, when installed, makes rebuilds in fresh build directories cheap (not needed by CI).
command -v ccache >/dev/null && generator+=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
# Scheduling only (no compile flag changes): a static library's objects need not wait for the
# libraries it links to be built, only for generated sources (the protobuf stubs), so both cores
# keep busy. About 10 s of a 4-minute --programs build (docs/getting-started.md).
options=(-DCMAKE_OPTIMIZE_DEPENDENCIES=ON)
targets=()
if [ "$programs" = 1 ]; then
  [ -f "$dir/CMakeCache.txt" ] ||
    options+=(-DTESSERA_BUILD_TESTS=OFF -DTESSERA_BUILD_BENCH=OFF
              "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O2 -DNDEBUG -pipe --param=ggc-min-expand=100 --param=ggc-min-heapsize=1048576")
  targets=(--target tessera-server tessera-worker tessera)
else
  options+=(-DTESSERA_BUILD_TESTS=ON -DTESSERA_BUILD_BENCH=ON "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O2 -g -DNDEBUG")
fi
start=$SECONDS
if [ ! -f "$dir/CMakeCache.txt" ]; then
  cmake -S . -B "$dir" "${generator[@]}" -DCMAKE_BUILD_TYPE=RelWithDebInfo "${options[@]}" "$@"
else
  cmake -S . -B "$dir" "${options[@]}" "$@" >/dev/null
fi
configured=$SECONDS
cmake --build "$dir" -j "$jobs" "${targets[@]}"
echo "build.sh: $dir configured in $((configured - start)) s, built in $((SECONDS - configured)) s"
