#!/usr/bin/env bash
# The main job, from a fresh Debian machine: installs what is missing, builds, starts a local
# coordinator with two local workers, renders the Whitted showcase to out/, then stops them.
# Only what the three programs need: the packages to build and run them (install-deps.sh
# --programs) and their targets (build.sh --programs), no tests or benchmarks; scripts/test.sh
# adds those later to the same build/. docs/getting-started.md has the times, step by step.
set -euo pipefail
cd "$(dirname "$0")/.."
t0=$SECONDS
bash scripts/install-deps.sh --programs
t_deps=$SECONDS
bash scripts/build.sh --programs
t_build=$SECONDS

bin=build
data=$(mktemp -d /tmp/tessera-showcase.XXXXXX)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -TERM "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  rm -rf "$data"
}
trap cleanup EXIT

# Port 0: the coordinator picks a free port and says which.
"$bin/server/tessera-server" --listen 127.0.0.1:0 --data-dir "$data/coordinator" >"$data/server.log" 2>&1 &
pids+=($!)
addr=""
for _ in $(seq 1 100); do
  addr=$(grep -oE 'listening on [0-9.]+:[0-9]+' "$data/server.log" | head -1 | awk '{print $3}') || true
  [ -n "$addr" ] && break
  sleep 0.1
done
[ -n "$addr" ] || { echo "coordinator did not start:"; cat "$data/server.log"; exit 1; }
echo "coordinator on $addr"
threads=$(( $(nproc) > 1 ? $(nproc) / 2 : 1 ))
for i in 1 2; do
  "$bin/worker/tessera-worker" --coordinator "$addr" --threads "$threads" --name "local-$i" >"$data/worker$i.log" 2>&1 &
  pids+=($!)
done
mkdir -p out
"$bin/client/tessera" submit scenes/whitted.json --coordinator "$addr" -o out/whitted_####.exr "$@"
# A viewable copy next to the float EXR.
if "$bin/client/tessera" convert --help >/dev/null 2>&1; then
  "$bin/client/tessera" convert out/whitted_0000.exr out/whitted_0000.png --tonemap aces
fi
echo "done: $(ls out/whitted_0000.*)"
echo "showcase: $((SECONDS - t0)) s: packages $((t_deps - t0)) s, build $((t_build - t_deps)) s, render $((SECONDS - t_build)) s"
