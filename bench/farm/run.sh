#!/usr/bin/env bash
# Farm benchmarks: overhead and scaling of a real farm (farm_overhead.py), the coordinator
# against hundreds of simulated workers (coordinator_load), and the floor of a coordinator in the
# pixel path (relay_floor: receive, durable append, send). Results (JSON and markdown) go to
# OUT (default BUILD/bench-results/farm); docs/performance.md records them with the machine.
#
#   bench/farm/run.sh [--build DIR] [--out DIR] [--smoke] [--configs 1x0,2x1,2x0] [--workers 10,100,1000]
#
# --smoke: a seconds-long version for CI (tiny image, 10 simulated workers). It asserts nothing
# about time; it fails only if something is broken (a process fails, a tile is lost).
# On a machine with 16+ cores, add the speedup curve: --configs 1x0,1x1,2x1,4x1,8x1,16x1, or run
# bench/farm/scale.sh (every process on CPUs of its own; the coordinator on 1, 2 and 4 CPUs).
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(cd "$HERE/../.." && pwd)
BUILD=$ROOT/build
OUT=""
SMOKE=0
CONFIGS=1x0,2x1,2x0
WORKERS=10,100,1000
TILES=""
REPEAT=1
while [ $# -gt 0 ]; do
  case $1 in
    --build) BUILD=$(cd "$2" && pwd); shift 2 ;;
    --out) OUT=$2; shift 2 ;;
    --smoke) SMOKE=1; shift ;;
    --configs) CONFIGS=$2; shift 2 ;;
    --workers) WORKERS=$2; shift 2 ;;
    --tiles) TILES=$2; shift 2 ;;
    --repeat) REPEAT=$2; shift 2 ;;
    -h|--help) sed -n '2,12p' "$0"; exit 0 ;;
    *) echo "run.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
OUT=${OUT:-$BUILD/bench-results/farm}
mkdir -p "$OUT"
cd "$ROOT"
for exe in client/tessera server/tessera-server worker/tessera-worker bench/farm/coordinator_load \
           bench/farm/first_tile_probe bench/farm/relay_floor; do
  [ -x "$BUILD/$exe" ] || { echo "run.sh: $BUILD/$exe is missing: build it first" >&2; exit 1; }
done

if [ "$SMOKE" = 1 ]; then
  overhead=(--width 64 --height 36 --spp 1 --tile 16 --configs 1x1,2x1)
  load=(--workers 10 --tiles 2000 --tile 8)
  floor=(--tiles 320 --repeat 1)
else
  overhead=(--configs "$CONFIGS" --repeat "$REPEAT")
  load=(--workers "$WORKERS" --tiles "${TILES:-200000}" --tile 8 --repeat "$REPEAT")
  floor=(--repeat "$REPEAT")
fi

echo "## Farm overhead and scaling"
python3 "$HERE/farm_overhead.py" --build "$BUILD" "${overhead[@]}" \
  --json "$OUT/farm_overhead.json" --markdown "$OUT/farm_overhead.md"
echo
echo "## Coordinator at scale (simulated workers)"
"$BUILD/bench/farm/coordinator_load" --server "$BUILD/server/tessera-server" --scene "$HERE/load_scene.json" \
  "${load[@]}" --json "$OUT/coordinator_load.json" --markdown "$OUT/coordinator_load.md"
echo
echo "## The same, workers of the protocol before batches (one result, one assignment a message)"
"$BUILD/bench/farm/coordinator_load" --server "$BUILD/server/tessera-server" --scene "$HERE/load_scene.json" \
  "${load[@]}" --no-batches --json "$OUT/coordinator_load_unbatched.json" \
  --markdown "$OUT/coordinator_load_unbatched.md"
echo
echo "## The same, workers that take leases of one tile"
"$BUILD/bench/farm/coordinator_load" --server "$BUILD/server/tessera-server" --scene "$HERE/load_scene.json" \
  "${load[@]}" --no-spans --json "$OUT/coordinator_load_unspanned.json" \
  --markdown "$OUT/coordinator_load_unspanned.md"
echo
echo "## The floor: receive, durable append and send of each tile, nothing else"
"$BUILD/bench/farm/relay_floor" --dir "$OUT" "${floor[@]}" --json "$OUT/relay_floor.json"
echo
echo "results in $OUT"
