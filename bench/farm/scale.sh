#!/usr/bin/env bash
# Farm scaling on a many-core machine (the farm-scaling goal of docs/performance.md), every process on CPUs of its own:
#  1. N one-thread workers against `tessera render --threads N` on the same CPUs, the coordinator
#     on one CPU and the client on another (farm_overhead.py --pin), at 16 spp, and at 64 spp for
#     the two largest N;
#  2. the coordinator against 100 simulated workers on 1, 2 and 4 CPUs of its own, the load
#     generator on the rest (coordinator_load --server-cpus/--loadgen-cpus): tiles per second
#     as the coordinator gets cores.
# JSON and markdown go to OUT. Needs 2 + max(N) CPUs; asserts nothing about time.
#
#   bench/farm/scale.sh [--build DIR] [--out DIR] [--workers 1,2,4,8,14] [--repeat R] [--tiles T]
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(cd "$HERE/../.." && pwd)
BUILD=$ROOT/build
OUT=""
CORES=$(nproc)
WORKERS=""
REPEAT=2
TILES=20000
while [ $# -gt 0 ]; do
  case $1 in
    --build) BUILD=$(cd "$2" && pwd); shift 2 ;;
    --out) OUT=$2; shift 2 ;;
    --workers) WORKERS=$2; shift 2 ;;
    --repeat) REPEAT=$2; shift 2 ;;
    --tiles) TILES=$2; shift 2 ;;
    -h|--help) sed -n '2,10p' "$0"; exit 0 ;;
    *) echo "scale.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
[ "$CORES" -ge 6 ] || { echo "scale.sh: needs at least 6 CPUs, this machine has $CORES" >&2; exit 1; }
MAXW=$((CORES - 2))
if [ -z "$WORKERS" ]; then
  WORKERS=""
  for n in 1 2 4 8 16 32 64; do [ $n -lt $MAXW ] && WORKERS="$WORKERS,$n"; done
  WORKERS="${WORKERS#,},$MAXW"
fi
CONFIGS=$(echo "$WORKERS" | sed -E 's/([0-9]+)/\1x1/g')
OUT=${OUT:-$BUILD/bench-results/scale}
mkdir -p "$OUT"
cd "$ROOT"
lscpu > "$OUT/lscpu.txt" 2>/dev/null || grep -m1 "model name" /proc/cpuinfo > "$OUT/lscpu.txt"
LARGEST=$(echo "$CONFIGS" | tr ',' '\n' | tail -2 | paste -sd,)
for spp in 16 64; do
  configs=$CONFIGS
  [ $spp -eq 16 ] || configs=$LARGEST
  echo "== farm_overhead --pin, $spp spp, configs $configs"
  python3 "$HERE/farm_overhead.py" --build "$BUILD" --pin --configs "$configs" --spp $spp --repeat "$REPEAT" \
    --json "$OUT/scale_${spp}spp.json" --markdown "$OUT/scale_${spp}spp.md"
done
LAST=$((CORES - 1))
for c in 1 2 4; do
  echo "== coordinator_load, coordinator on $c CPU(s)"
  "$BUILD/bench/farm/coordinator_load" --server "$BUILD/server/tessera-server" --scene "$HERE/load_scene.json" \
    --workers 100 --tiles "$TILES" --tile 32 --server-cpus "0-$((c - 1))" --loadgen-cpus "$c-$LAST" \
    --json "$OUT/coordinator_cpus_$c.json" --markdown "$OUT/coordinator_cpus_$c.md"
done
