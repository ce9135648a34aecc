#!/usr/bin/env bash
# Configures and builds Tessera (Release with debug info). Extra args go to cmake.
# TESSERA_BUILD_DIR picks the build directory (default build/; the sanitizer build uses build-asan/).
set -euo pipefail
cd "$(dirname "$0")/.."
dir=${TESSERA_BUILD_DIR:-build}
jobs=$(nproc 2>/dev/null || echo 2)
generator=()
command -v ninja >/dev/null && generator=(-G Ninja)
# ccache, when installed, makes rebuilds in fresh build directories cheap (not needed by CI).
command -v ccache >/dev/null && generator+=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
if [ ! -f "$dir/CMakeCache.txt" ]; then
  cmake -S . -B "$dir" "${generator[@]}" -DCMAKE_BUILD_TYPE=RelWithDebInfo "$@"
else
  cmake -S . -B "$dir" "$@" >/dev/null
fi
cmake --build "$dir" -j "$jobs"
