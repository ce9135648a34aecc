#!/usr/bin/env bash
# The test command: installs what is missing, builds, and runs every test (unit tests beside the
# code; integration tests with real tessera-server/tessera-worker processes on loopback; the
# container test when a Docker engine can be started). Three stages, all by default:
#   main      build/       every test (ctest labels: color, cli, farm, stability, fuzz, bench-smoke,
#                          containers, and the unlabelled unit tests)
#   sanitize  build-asan/  the same suite built with AddressSanitizer (and LeakSanitizer); any report
#                          fails (containers and bench smoke are left out: images and benchmarks are
#                          not sanitizer builds; so are the Python package's and the Blender
#                          add-on's). TESSERA_SANITIZERS=address,undefined adds UBSan to the whole
#                          suite, which about doubles the stage's build (some 25 minutes
#                          on 2 cores): more than CI can afford beside the other builds. CI has
#                          UBSan where untrusted bytes are parsed, in the fuzz stage.
#   fuzz      build-fuzz/  each libFuzzer target for TESSERA_FUZZ_SECONDS (default 20) seconds
# TESSERA_TEST_STAGES=main,fuzz (for example) runs a subset; extra args go to the main ctest.
set -euo pipefail
cd "$(dirname "$0")/.."
stages=",${TESSERA_TEST_STAGES:-main,sanitize,fuzz},"
jobs=$(nproc 2>/dev/null || echo 2)

# Each stage's minutes, printed again at the end, where a CI log's tail shows them.
timings=()
stage_name="" stage_start=$SECONDS
stage() {
  [ -n "$stage_name" ] && timings+=("$stage_name $(( (SECONDS - stage_start) / 60 ))m$(( (SECONDS - stage_start) % 60 ))s")
  stage_name=$1 stage_start=$SECONDS
  echo; echo "=== test stage: $1 ($(date -u +%H:%M:%S))"
}
stage setup
bash scripts/install-deps.sh

if [[ $stages == *,main,* ]]; then
  stage main-build
  bash scripts/build.sh
  stage main-tests
  (cd build && ctest --output-on-failure --timeout 600 -j "$jobs" "$@")
fi

if [[ $stages == *,sanitize,* ]]; then
  stage sanitize-build
  # -O1 -g1: the sanitizers' instrumentation makes compiling at -O2 with full debug info about 4x
  # slower than a normal build; -O1 with line tables (enough for symbolized reports) halves that.
  TESSERA_BUILD_DIR=build-asan bash scripts/build.sh -DTESSERA_SANITIZE=ON -DTESSERA_BUILD_BENCH=OFF \
    "-DTESSERA_SANITIZERS=${TESSERA_SANITIZERS:-address}" "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG"
  stage sanitize-tests
  # halt_on_error / abort: a sanitizer report ends the process with a failure the test sees; the
  # server and worker processes that tests start inherit these settings.
  export ASAN_OPTIONS=detect_leaks=1:halt_on_error=1:abort_on_error=1:detect_stack_use_after_return=0
  export UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1
  # python/ and blender/ suites are left out too: they test Python code the sanitizer does not
  # see, and the coordinator and worker paths they drive run here in the C++ farm tests.
  (cd build-asan && ctest --output-on-failure --timeout 900 -j "$jobs" -LE 'containers|python|blender')
fi

if [[ $stages == *,fuzz,* ]]; then
  stage fuzz
  bash fuzz/run.sh "${TESSERA_FUZZ_SECONDS:-20}"
fi
stage done
echo "stage times: ${timings[*]}"
