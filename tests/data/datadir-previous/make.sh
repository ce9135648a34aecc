#!/usr/bin/env bash
# Makes this fixture: a coordinator data directory as a release of Tessera leaves it. Run it with
# that release's binaries (BIN: a directory holding tessera-server, tessera-worker and tessera)
# from the repository root; it writes OUT (default tests/data/datadir-previous/data).
#   job A: done, frames not fetched (its tiles are in tiles/*.seg)
#   job B: done and fetched by `tessera watch` (acknowledged, evicted: a row, no tiles)
#   job C: queued (submitted with no worker connected)
#   job D: cancelled before any worker took a tile
# Then the coordinator is stopped with SIGTERM. Left out: .reserve (512 KiB of nothing, made
# again at start) and the bundle's extracted copy bundles/<sha256>/ (extracted again on demand).
set -euo pipefail
BIN=${BIN:?BIN: the directory of the release binaries}
OUT=${OUT:-tests/data/datadir-previous/data}
PORT=${PORT:-17931}
SCENE=tests/farm/whitted_orbit.json
ADDR=127.0.0.1:$PORT
work=$(mktemp -d)
trap 'kill $server $worker 2>/dev/null || true; rm -rf "$work"' EXIT
args=(--width 72 --height 40 --spp 2 --tile 16 --coordinator "$ADDR" -q)  # 5x3 tiles, the last column and row 8 px

"$BIN/tessera-server" --listen "$ADDR" --data-dir "$work/data" >"$work/server.log" 2>&1 &
server=$!
"$BIN/tessera-worker" --coordinator "$ADDR" --name w1 --threads 1 >"$work/worker.log" 2>&1 &
worker=$!
sleep 2
id_of() { sed -n "s/.*job \([0-9a-f]*\) submitted.*/\1/p" | head -1; }
wait_done() {
  for _ in $(seq 120); do
    "$BIN/tessera" status "$1" --json --coordinator "$ADDR" | grep -q '"state": *"done"' && return 0
    sleep 0.5
  done
  echo "job $1 did not finish" >&2
  exit 1
}
A=$("$BIN/tessera" submit "$SCENE" "${args[@]}" --frames 0-1 --name job-a --detach | id_of)
wait_done "$A"
B=$("$BIN/tessera" submit "$SCENE" "${args[@]}" --frames 2 --name job-b --detach | id_of)
wait_done "$B"
"$BIN/tessera" watch "$B" --coordinator "$ADDR" -o "$work/b_####.exr" -q
kill -TERM "$worker"
wait "$worker" || true
C=$("$BIN/tessera" submit "$SCENE" "${args[@]}" --frames 0-2 --name job-c --priority 3 --detach | id_of)
D=$("$BIN/tessera" submit "$SCENE" "${args[@]}" --frames 1 --name job-d --detach | id_of)
"$BIN/tessera" cancel "$D" --coordinator "$ADDR"
"$BIN/tessera" status --json --coordinator "$ADDR" >"$work/status.json"
kill -TERM "$server"
wait "$server" || true
grep -q "job $B left memory" "$work/server.log" || { echo "job B was not evicted" >&2; cat "$work/server.log" >&2; exit 1; }
rm -f "$work/data/.reserve"
find "$work/data/bundles" -mindepth 1 -maxdepth 1 -type d -exec rm -rf {} +
rm -rf "$OUT"
mkdir -p "$(dirname "$OUT")"
cp -a "$work/data" "$OUT"
echo "A=$A B=$B C=$C D=$D"
cat "$work/status.json"
