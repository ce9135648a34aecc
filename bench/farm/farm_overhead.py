#!/usr/bin/env bash
# Farm overhead: wall time of `tessera submit` on a local farm with 1 and 2 workers, against
# `tessera render` in-process, same scene, same settings. Prints JSON on stdout.
#
#   bench/farm_overhead.sh [BUILD_DIR] [SCENE] [WIDTH] [HEIGHT] [SPP] [THREADS_PER_WORKER]
#
# Defaults: build, scenes/whitted.json, 1920x1080, 16 spp, and workers with
# nproc/N threads each (so 1 worker and 2 workers use the same cores as the in-process render).
# Times include everything the user waits for: bundle upload, scheduling, network, EXR writing.
set -euo pipefail
BUILD=${1:-build}
SCENE=${2:-scenes/whitted.json}
W=${3:-1920}
H=${4:-1080}
SPP=${5:-16}
NPROC=$(nproc)
TMP=$(mktemp -d)
PIDS=()
cleanup() { for p in "${PIDS[@]}"; do kill -KILL "$p" 2>/dev/null || true; done; rm -rf "$TMP"; }
trap cleanup EXIT

now() { date +%s.%N; }
elapsed() { echo "$2 - $1" | bc -l; }

# CPU seconds (user+sys) of a live process, from /proc: the machine may be shared, and CPU time
# shows the farm's overhead even when wall time is disturbed by other load.
cpu_of() { awk -v hz="$(getconf CLK_TCK)" '{printf "%.3f", ($14 + $15) / hz}' "/proc/$1/stat"; }

t0=$(now)
/usr/bin/time -f "%U %S" -o "$TMP/inproc.cpu" \
  "$BUILD/client/tessera" render "$SCENE" -o "$TMP/inproc.exr" --width "$W" --height "$H" --spp "$SPP" -q >/dev/null
t1=$(now)
inproc=$(elapsed "$t0" "$t1")
inproc_cpu=$(awk '{printf "%.3f", $1 + $2}' "$TMP/inproc.cpu")

run_farm() {  # $1 = workers, $2 = threads per worker
  local n=$1 threads=$2
  "$BUILD/server/tessera-server" --listen 127.0.0.1:0 --data-dir "$TMP/data$n" --log-level warn >"$TMP/server$n.log" 2>&1 &
  local spid=$!
  PIDS+=("$spid")
  local addr=""
  for _ in $(seq 200); do
    addr=$(grep -o 'listening on 127.0.0.1:[0-9]*' "$TMP/server$n.log" | awk '{print $3}' || true)
    [ -n "$addr" ] && break
    sleep 0.05
  done
  local wpids=()
  for i in $(seq "$n"); do
    "$BUILD/worker/tessera-worker" --coordinator "$addr" --threads "$threads" --name "bench$i" \
      --cache-dir "$TMP/cache$n-$i" --log-level warn >"$TMP/worker$n-$i.log" 2>&1 &
    wpids+=($!)
    PIDS+=($!)
  done
  # Wait until the workers are registered: their start-up is not what we measure.
  for _ in $(seq 200); do
    [ "$("$BUILD/client/tessera" workers --coordinator "$addr" --json | grep -c '"name"')" -ge "$n" ] && break
    sleep 0.05
  done
  local s=$(now)
  /usr/bin/time -f "%U %S" -o "$TMP/client$n.cpu" \
    "$BUILD/client/tessera" submit "$SCENE" --coordinator "$addr" -o "$TMP/farm$n.exr" \
    --width "$W" --height "$H" --spp "$SPP" -q >"$TMP/submit$n.log" 2>&1
  local e=$(now)
  local cpu
  cpu=$(awk '{printf "%.3f", $1 + $2}' "$TMP/client$n.cpu")
  local server_cpu
  server_cpu=$(cpu_of "$spid")
  for p in "${wpids[@]}"; do cpu=$(echo "$cpu + $(cpu_of "$p")" | bc -l); done
  cpu=$(echo "$cpu + $server_cpu" | bc -l)
  kill -TERM "${wpids[@]}" "$spid" 2>/dev/null || true
  wait "${wpids[@]}" "$spid" 2>/dev/null || true
  echo "$(elapsed "$s" "$e") $cpu $server_cpu"
}

t_per_worker1=${6:-$NPROC}
t_per_worker2=${6:-$(( NPROC / 2 > 0 ? NPROC / 2 : 1 ))}
read -r farm1 cpu1 scpu1 <<<"$(run_farm 1 "$t_per_worker1")"
read -r farm2 cpu2 scpu2 <<<"$(run_farm 2 "$t_per_worker2")"
load=$(cut -d' ' -f1 /proc/loadavg)
cat <<JSON
{
  "scene": "$SCENE", "width": $W, "height": $H, "spp": $SPP, "cores": $NPROC,
  "load_average_after": $load,
  "inprocess": {"seconds": $(printf %.3f "$inproc"), "cpu_seconds": $inproc_cpu},
  "farm_1_worker": {"threads_per_worker": $t_per_worker1, "seconds": $(printf %.3f "$farm1"), "ratio": $(printf %.3f "$(echo "$farm1 / $inproc" | bc -l)"),
                    "cpu_seconds_all_processes": $(printf %.3f "$cpu1"), "cpu_ratio": $(printf %.3f "$(echo "$cpu1 / $inproc_cpu" | bc -l)"), "coordinator_cpu_seconds": $scpu1},
  "farm_2_workers": {"threads_per_worker": $t_per_worker2, "seconds": $(printf %.3f "$farm2"), "ratio": $(printf %.3f "$(echo "$farm2 / $inproc" | bc -l)"),
                    "cpu_seconds_all_processes": $(printf %.3f "$cpu2"), "cpu_ratio": $(printf %.3f "$(echo "$cpu2 / $inproc_cpu" | bc -l)"), "coordinator_cpu_seconds": $scpu2}
}
JSON
