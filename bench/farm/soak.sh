#!/usr/bin/env bash
# The farm's soak (docs/reliability.md): one long job rendered while everything goes wrong at once, with
# real processes. Not part of CI (30 minutes by default); `--minutes 3 --frames 120` is a smoke.
#
#   bench/farm/soak.sh [--minutes 30] [--frames 1000] [--build build] [--keep]
#
# What happens, for --minutes:
#   - a coordinator whose data directory is a small tmpfs (4 MiB; a plain directory when this
#     user may not mount), kill -9'ed and restarted every 60-180 s;
#   - 3 workers, a random one kill -9'ed and restarted every 5-15 s; each tile is slowed down so
#     that the job lasts about the run's length;
#   - the data disk filled with a filler file every so often, and freed a while later;
#   - hostile peers in the background: bursts of 200 idle TCP connections and of garbage bytes;
#   - one `tessera submit -o` client for the whole job (it re-attaches by itself).
# Then it checks, and prints as `soak: ...` lines:
#   - every frame bit-identical to `tessera render` of that frame (idiff, exact);
#   - the coordinator's RSS and open descriptors over time (first vs last quarter of samples);
#   - nothing acknowledged was rendered again: no result was accepted by a coordinator for a
#     frame after that frame's acknowledgement was stored (AckFrame answered OK; coordinator
#     debug logs, in order).
# Exit 0 when every check holds.
set -euo pipefail
cd "$(dirname "$0")/../.."
minutes=30 frames=1000 build=build keep=0
while [ $# -gt 0 ]; do
  case "$1" in
    --minutes) minutes=$2; shift 2 ;;
    --frames) frames=$2; shift 2 ;;
    --build) build=$2; shift 2 ;;
    --keep) keep=1; shift ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
done
bin=$PWD/$build
dir=$(mktemp -d /tmp/tessera-soak-XXXXXX)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null || true; done
  [ -n "${server:-}" ] && kill -9 "$server" 2>/dev/null || true
  for w in "${workers[@]:-}"; do [ -n "$w" ] && kill -9 "$w" 2>/dev/null || true; done
  mountpoint -q "$dir/data" && umount -l "$dir/data"
  [ "$keep" = 1 ] || rm -rf "$dir"
}
trap cleanup EXIT
echo "soak: $minutes min, $frames frames, in $dir"

# A small animated scene: 64x48, 1 spp, 4 tiles of 32 px per frame.
cat > "$dir/scene.json" <<EOF
{
  "camera": { "position": [0, 1.6, 6.5], "look_at": [0, 0.9, 0], "up": [0, 1, 0], "vfov_deg": 40 },
  "image": { "width": 64, "height": 48, "spp": 1, "max_depth": 4, "seed": 1 },
  "background": [0.25, 0.45, 0.8],
  "lights": [ { "type": "point", "position": [-4, 6, 5], "intensity": 160 } ],
  "materials": { "matte": { "type": "diffuse", "albedo": [0.2, 0.5, 0.25] },
                 "glass": { "type": "glass", "ior": 1.5 } },
  "objects": [
    { "type": "plane", "name": "floor", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "matte" },
    { "type": "sphere", "name": "ball", "center": [0, 1, 0], "radius": 1, "material": "glass" }
  ],
  "animation": { "frames": $frames,
    "objects": { "ball": [ { "frame": 0, "translate": [-2, 0, 0] }, { "frame": $((frames - 1)), "translate": [2, 0, 0] } ] } }
}
EOF
mkdir -p "$dir/data" "$dir/out" "$dir/ref" "$dir/logs"
if mount -t tmpfs -o size=4m tmpfs "$dir/data" 2>/dev/null; then
  echo "soak: data directory on a 4 MiB tmpfs"
else
  echo "soak: cannot mount a tmpfs: data directory on the ordinary disk (no full-disk episodes)"
fi

port=$((20000 + RANDOM % 20000))
starts=0
start_server() {
  starts=$((starts + 1))
  "$bin/server/tessera-server" --listen "127.0.0.1:$port" --data-dir "$dir/data" --log-level debug \
    > "$dir/logs/server-$(printf %03d $starts).log" 2>&1 &
  server=$!
  for _ in $(seq 200); do
    grep -q "listening on" "$dir/logs/server-$(printf %03d $starts).log" 2>/dev/null && return 0
    sleep 0.05
  done
  echo "soak: the coordinator did not start:" >&2
  cat "$dir/logs/server-$(printf %03d $starts).log" >&2
  exit 1
}
start_server

# Tiles slowed so that the job lasts about the run (3 workers, 4 tiles a frame).
delay_ms=$(( minutes * 60 * 1000 * 3 * 8 / 10 / (frames * 4) ))
workers=("" "" "")
start_worker() {
  "$bin/worker/tessera-worker" --coordinator "127.0.0.1:$port" --name "w$1" --threads 1 \
    --cache-dir "$dir/cache-$1" --test-delay-ms "$delay_ms" >> "$dir/logs/worker-$1.log" 2>&1 &
  workers[$1]=$!
  disown "$!" 2>/dev/null || true  # no "Killed" lines from bash when the chaos kills it
}
for i in 0 1 2; do start_worker "$i"; done

"$bin/client/tessera" submit "$dir/scene.json" --coordinator "127.0.0.1:$port" -o "$dir/out/f_####.exr" \
  --tile 32 > "$dir/logs/client.log" 2>&1 &
client=$!

# Hostile peers: idle connections and garbage, in bursts.
(
  while true; do
    fds=()
    for _ in $(seq 200); do
      exec {fd}<>"/dev/tcp/127.0.0.1/$port" 2>/dev/null && fds+=("$fd")
    done
    head -c 4096 /dev/urandom > "/dev/tcp/127.0.0.1/$port" 2>/dev/null || true
    sleep 5
    for fd in "${fds[@]}"; do exec {fd}>&- 2>/dev/null || true; done
    sleep 5
  done
) > /dev/null 2>&1 &
pids+=($!)

end=$(( $(date +%s) + minutes * 60 ))
next_server_kill=$(( $(date +%s) + 60 + RANDOM % 120 ))
next_fill=$(( $(date +%s) + 30 + RANDOM % 60 ))
filled=0
echo "t_s,rss_kib,fds" > "$dir/samples.csv"
t0=$(date +%s)
server_kills=0 worker_kills=0 fills=0
while kill -0 "$client" 2>/dev/null && [ "$(date +%s)" -lt $((end + 600)) ]; do
  sleep $((5 + RANDOM % 11))
  now=$(date +%s)
  if [ -r "/proc/$server/status" ]; then
    rss=$(awk '/VmRSS/ {print $2}' "/proc/$server/status")
    fds=$(ls "/proc/$server/fd" 2>/dev/null | wc -l)
    echo "$((now - t0)),$rss,$fds" >> "$dir/samples.csv"
  fi
  if [ "$now" -ge "$end" ]; then  # past the chaos window: free the disk, let the job finish
    rm -f "$dir/data/filler"
    continue
  fi
  w=$((RANDOM % 3))
  kill -9 "${workers[$w]}" 2>/dev/null || true
  start_worker "$w"
  worker_kills=$((worker_kills + 1))
  if [ "$now" -ge "$next_server_kill" ]; then
    kill -9 "$server"; wait "$server" 2>/dev/null || true
    sleep 0.3
    start_server
    server_kills=$((server_kills + 1))
    next_server_kill=$(( now + 60 + RANDOM % 120 ))
  fi
  if mountpoint -q "$dir/data" && [ "$now" -ge "$next_fill" ]; then
    if [ "$filled" = 0 ]; then
      dd if=/dev/zero of="$dir/data/filler" bs=64k 2>/dev/null || true
      filled=1 fills=$((fills + 1))
      next_fill=$(( now + 20 + RANDOM % 30 ))
    else
      rm -f "$dir/data/filler"
      filled=0
      next_fill=$(( now + 60 + RANDOM % 60 ))
    fi
  fi
done
rm -f "$dir/data/filler"
set +e
wait "$client"; client_rc=$?
set -e
echo "soak: client exit $client_rc after $(( $(date +%s) - t0 )) s; $server_kills coordinator kill -9, $worker_kills worker kill -9, $fills disk-full episodes"
tail -3 "$dir/logs/client.log" | sed 's/^/soak:   client: /'

fail=0
[ "$client_rc" = 0 ] || fail=1
# Every frame bit-identical to tessera render.
bad=0 missing=0
for f in $(seq 0 $((frames - 1))); do
  n=$(printf %04d "$f")
  if [ ! -f "$dir/out/f_$n.exr" ]; then missing=$((missing + 1)); continue; fi
  "$bin/client/tessera" render "$dir/scene.json" -o "$dir/ref/r_$n.exr" --frame "$f" -q > /dev/null 2>&1
  idiff -fail 0 -warn 0 "$dir/out/f_$n.exr" "$dir/ref/r_$n.exr" > /dev/null 2>&1 || bad=$((bad + 1))
  rm -f "$dir/ref/r_$n.exr"
done
echo "soak: frames: $((frames - missing - bad)) of $frames bit-identical, $missing missing, $bad different"
[ "$bad" = 0 ] && [ "$missing" = 0 ] || fail=1
# Memory and descriptors: first vs last quarter of the samples.
python3 - "$dir/samples.csv" <<'EOF' || true
import csv, sys
rows = [r for r in csv.DictReader(open(sys.argv[1]))]
q = max(1, len(rows) // 4)
def avg(rs, k): return sum(int(r[k]) for r in rs) / len(rs)
first, last = rows[:q], rows[-q:]
print(f"soak: coordinator RSS {avg(first,'rss_kib')/1024:.1f} MiB (first quarter) -> {avg(last,'rss_kib')/1024:.1f} MiB "
      f"(last quarter), max {max(int(r['rss_kib']) for r in rows)/1024:.1f} MiB; descriptors "
      f"{avg(first,'fds'):.0f} -> {avg(last,'fds'):.0f}, max {max(int(r['fds']) for r in rows)} ({len(rows)} samples)")
EOF
# Nothing acknowledged rendered again: a result for a frame after its acknowledgement.
python3 - "$dir"/logs/server-*.log <<'EOF' || fail=1
import re, sys
acked, late, wasted, results, acks = set(), 0, 0, 0, 0
# An acknowledgement counts once it is stored: AckFrame answers OK only then.
ack = re.compile(r"job (\w+) frame (\d+) acknowledgement stored")
res = re.compile(r"result: lease \d+ job (\w+) frame (\d+) tile \d+ from worker \d+: (accepted|duplicate)")
for path in sys.argv[1:]:
    for line in open(path, errors="replace"):
        m = ack.search(line)
        if m:
            acked.add((m[1], int(m[2]))); acks += 1
            continue
        m = res.search(line)
        if m:
            results += 1
            if (m[1], int(m[2])) in acked:
                # accepted: the coordinator wanted the tile again (the broken promise);
                # duplicate: a speculative copy started before the ack finished after it.
                if m[3] == "accepted": late += 1
                else: wasted += 1
print(f"soak: {results} results received, {acks} acknowledgements logged; {late} tiles of acknowledged frames "
      f"rendered again, {wasted} late duplicate copies (speculation) discarded")
sys.exit(1 if late else 0)
EOF
echo "soak: $([ "$fail" = 0 ] && echo PASS || echo FAIL)"
exit "$fail"
