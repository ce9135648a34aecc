#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (ASan + UBSan) in build-fuzz/ and runs each one for
# SECONDS (default 30). New inputs go to build-fuzz/fuzz-work/<target>/, crashes to
# build-fuzz/fuzz-artifacts/<target>/; the committed corpus (fuzz/corpus) is read, not changed.
#   fuzz/run.sh            # CI: 4 x 30 s
#   fuzz/run.sh 3600       # by hand: an hour each
#   FUZZ_TARGETS=bundle fuzz/run.sh 600
# A crash: copy the artifact to fuzz/regressions/<target>/, fix the bug; the replay tests
# (ctest -L fuzz, normal build) then keep it fixed. To grow the committed corpus after a long run:
#   build-fuzz/fuzz/fuzz_T -merge=1 fuzz/corpus/T build-fuzz/fuzz-work/T
set -euo pipefail
cd "$(dirname "$0")/.."
secs="${1:-30}"
build="${TESSERA_FUZZ_BUILD:-build-fuzz}"
targets=(${FUZZ_TARGETS:-scene_parser bundle tile_decoder gltf_scene})
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)

# -O1 -g1, as the sanitizer stage of scripts/test.sh builds: half the compile time of -O2 -g under
# the sanitizers, and the level libFuzzer's documentation builds its examples with.
CC=clang CXX=clang++ cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo "${launcher[@]}" \
  "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG" \
  -DTESSERA_FUZZ=ON -DTESSERA_BUILD_TESTS=OFF -DTESSERA_BUILD_BENCH=OFF >/dev/null
cmake --build "$build" -j "${FUZZ_JOBS:-2}" --target "${targets[@]/#/fuzz_}"

status=0
summary=()
for t in "${targets[@]}"; do
  work="$build/fuzz-work/$t"
  artifacts="$build/fuzz-artifacts/$t/"
  mkdir -p "$work" "$artifacts"
  dict=()
  [ -f "fuzz/$t.dict" ] && dict=(-dict="fuzz/$t.dict")
  # Regressions are seeds too; git keeps no empty directory, so a target may have none yet.
  seeds=("fuzz/corpus/$t")
  [ -d "fuzz/regressions/$t" ] && seeds+=("fuzz/regressions/$t")
  log="$build/fuzz-$t.log"
  echo "fuzz $t: ${secs} s"
  # -timeout: an input running 10 s is a hang; -rss_limit_mb: one using 2 GiB is a memory bomb.
  if ASAN_OPTIONS=detect_leaks=1 "$build/fuzz/fuzz_$t" -max_total_time="$secs" -timeout=10 -rss_limit_mb=2048 \
      -max_len=65536 -print_final_stats=1 -artifact_prefix="$artifacts" "${dict[@]}" \
      "$work" "${seeds[@]}" >"$log" 2>&1; then
    result=ok
  else
    result="CRASH (see $log and $artifacts)"
    status=1
    tail -n 40 "$log"
  fi
  runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | tail -n 1 | grep -o '[0-9]*$' || echo "?")
  rate=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | tail -n 1 | grep -o '[0-9]*$' || echo "?")
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -n 1 | grep -o '[0-9]*' || echo "?")
  summary+=("fuzz $t: $result, $runs runs in ${secs} s ($rate exec/s), coverage $cov edges")
done
printf '%s\n' "${summary[@]}"
exit $status
