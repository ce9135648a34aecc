#!/usr/bin/env bash
# Every benchmark of docs/performance.md, one command:
#
#   bench/run_all.sh [--build DIR] [--out DIR] [--smoke] [--only LIST] [--no-farm] [--threads N]
#
#   speed_error   time, Mrays/s, RMSE, relMSE and the renderer's estimated RMSE against spp, per
#                 sampler, for the three showcase scenes; target-error renders against uniform spp
#                 at equal measured error; a log-log PNG per scene (gnuplot)
#   ray_ceiling   the renderer's Mrays/s against bare Embree on its own rays (single, 8-, 16-wide) and
#                 against the packet ceiling with Embree's robust triangles (Whitted, Cornell, bunny,
#                 armadillo); the watertight test's frame time against Embree's robust test
#   povray        POV-Ray 3.7 on the same Whitted scene: error and samples/s of both
#   lattice       how honest --sampler lattice's and the default frame target's error estimates are
#                 on the hard scenes of bench/lattice/scenes, over seeds (bench/lattice/lattice_honesty)
#   cycles        Blender 3.4's Cycles (Whitted-like settings) on the glTF test scene: error and
#                 samples/s of both (skipped, with a message, when blender is not installed), and
#                 the bound on their ratio: bare Embree's time for the frame's own queries
#   farm          bench/farm/run.sh (farm overhead, coordinator at scale), when it exists
#
# Results go to OUT (default bench-results/): JSON per run, summary.md (markdown tables) and the
# PNG plots. --smoke runs a seconds-long version of each (tiny images, few spp) for CI: it asserts
# nothing about time and fails only if a benchmark breaks. References (high-spp renders) are
# cached in BUILD/bench-cache. The full run takes about 20 minutes on 2 (shared) cores.
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(cd "$HERE/.." && pwd)
BUILD=$ROOT/build
OUT=""
SMOKE=0
ONLY=speed_error,ray_ceiling,povray,lattice,cycles,farm
FARM=1
THREADS=$(nproc)
while [ $# -gt 0 ]; do
  case $1 in
    --build) BUILD=$(cd "$2" && pwd); shift 2 ;;
    --out) OUT=$2; shift 2 ;;
    --smoke) SMOKE=1; shift ;;
    --only) ONLY=$2; shift 2 ;;
    --no-farm) FARM=0; shift ;;
    --threads) THREADS=$2; shift 2 ;;
    -h|--help) sed -n '2,18p' "$0"; exit 0 ;;
    *) echo "run_all.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
OUT=${OUT:-$ROOT/bench-results}
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
cd "$ROOT"
want() { [[ ",$ONLY," == *",$1,"* ]]; }
# A peer renderer's section: its heading on stderr and in the summary; false (after saying so in
# both) when the peer's program is not installed, so CI machines without it skip cleanly.
# Usage: peer PROGRAM DEBIAN_PACKAGE "stderr heading" "summary heading"
# Whether the number $1 is below $2 (floats, as the benchmarks print them).
less_than() { python3 -c 'import sys; sys.exit(0 if float(sys.argv[1]) < float(sys.argv[2]) else 1)' "$1" "$2"; }

peer() {
  echo "== $3" >&2
  echo -e "\n### $4\n" >>"$SUMMARY"
  if ! command -v "$1" >/dev/null; then
    echo "run_all.sh: $1 not installed (apt-get install $2): skipped" >&2
    echo "$1 not installed: skipped." >>"$SUMMARY"
    return 1
  fi
}
for exe in speed_error/speed_error ray_ceiling/ray_ceiling povray/pov_compare lattice/lattice_honesty cycles/cycles_compare; do
  if [ ! -x "$BUILD/bench/$exe" ]; then
    echo "run_all.sh: $BUILD/bench/$exe is missing: cmake --build $BUILD --target $(basename $exe)" >&2
    exit 1
  fi
done
CACHE=$BUILD/bench-cache
mkdir -p "$CACHE"
SUMMARY=$OUT/summary.md
if [ $SMOKE = 1 ]; then
  W=32 H=18 MAXSPP=4 REFSPP=16 CENTER=2 TARGETS=0.05 SEEDS=1   # speed_error
  CW=32 CH=18 CSPP=1 REPS=1                      # ray_ceiling
  PW=32 PH=18 PR=2 PSEEDS=0                      # povray: +R2 = 4 samples per pixel
  POV_ADAPTIVE=("+A0.3 +AM2 +R3")                # povray's adaptive anti-aliasing, as its users set it
  BW=32 BH=18 BSPP=2 BREF=16 BNOISE=0.1          # cycles (BNOISE: its adaptive sampling's noise threshold)
  LW=48 LH=27 LREF=64 LSEEDS=2 LSPP=16           # lattice
else
  W=192 H=108 MAXSPP=1024 REFSPP=4096 CENTER=16 TARGETS=auto SEEDS=3
  CW=480 CH=270 CSPP=4 REPS=3
  PW=640 PH=360 PR=4 PSEEDS=8                    # povray (PSEEDS: seeds of the estimate/measured spread): the size POV-Ray's users compare at (192x108 flattered Tessera at +A0.3: docs/performance-log.md)
  POV_ADAPTIVE=("+A0.3 +AM2 +R3" "+A0.1 +AM2 +R3" "+A0.03 +AM2 +R4")
  BW=192 BH=108 BSPP=16 BREF=1024 BNOISE=0.01    # 0.01: Cycles' default noise threshold
  LW=192 LH=108 LREF=1024 LSEEDS=8 LSPP=4,16,64  # lattice: the scenes' own size; the errors of 4, 16, 64 spp
fi
{
  echo "<!-- bench/run_all.sh$([ $SMOKE = 1 ] && echo ' --smoke') on $(date -u '+%Y-%m-%d %H:%M UTC'), $(nproc) cores: $(lscpu | sed -n 's/^Model name: *//p') -->"
} >"$SUMMARY"

# plot_speed_error SCENE: OUT/speed_error_SCENE.png from the .dat file speed_error wrote.
plot_speed_error() {
  local scene=$1
  if ! command -v gnuplot >/dev/null; then
    echo "run_all.sh: gnuplot not installed (apt-get install gnuplot-nox): no plot" >&2
    return 0
  fi
  gnuplot <<EOF
set terminal pngcairo size 800,560 noenhanced
set output "$OUT/speed_error_$scene.png"
set title "$scene, ${W}x${H}, max_depth 8: RMSE against render time"
set logscale xy
set ylabel "RMSE against a $REFSPP-spp reference (linear)"
set key bottom left
set grid
set xlabel "render time (CPU-seconds, all threads), $THREADS threads"
plot "$OUT/speed_error_$scene.dat" index 0 using 1:2 with linespoints lw 2 lc 1 title "sobol (default), uniform spp", \
     "" index 0 using 1:3 with lines dt 2 lc 1 title "sobol: renderer's estimated RMSE", \
     "" index 1 using 1:2 with linespoints lw 2 lc 4 title "cmj, uniform spp", \
     "" index 2 using 1:2 with linespoints lw 2 lc 2 title "independent", \
     "" index 2 using 1:3 with lines dt 2 lc 2 title "independent: renderer's estimated RMSE", \
     "" index 3 using 1:2 with linespoints lw 2 lc 3 title "center", \
     "$OUT/speed_error_${scene}_target.dat" using 1:2 with linespoints lw 3 pt 7 lc 7 title "sobol, --target-rmse (adaptive)", \
     "" using 1:3 with lines dt 2 lc 7 title "adaptive: renderer's estimated RMSE"
EOF
}

if want speed_error; then
  echo "== speed against error (${W}x${H}, spp 1..$MAXSPP, reference $REFSPP spp)" >&2
  echo -e "\n### Speed against error\n" >>"$SUMMARY"
  for scene in whitted cornell bunny; do
    "$BUILD/bench/speed_error/speed_error" --scene "scenes/$scene.json" --width $W --height $H \
      --max-spp $MAXSPP --ref-spp $REFSPP --center-max-spp $CENTER --threads "$THREADS" --cache "$CACHE" \
      --targets "$TARGETS" --seeds $SEEDS --markdown "$SUMMARY" --data "$OUT/speed_error_$scene.dat" \
      --target-data "$OUT/speed_error_${scene}_target.dat" >"$OUT/speed_error_$scene.json"
    plot_speed_error "$scene"
  done
fi

if want ray_ceiling; then
  echo "== ray throughput against the ceiling (${CW}x${CH}, $CSPP spp, 1 thread)" >&2
  {
    echo -e "\n### Ray throughput against bare Embree (1 thread, best of $REPS)\n"
    echo "Bare Embree replays the renderer's own rays on its own scene (single rays, 8- and 16-wide packets), and on the same scene built with Embree's robust triangles (the ceiling: the faster packet width)."
    echo
    echo "| scene | frame | rays | renderer Mrays/s | bare rtcIntersect1/Occluded1 | bare 8-wide packets | bare 16-wide | ceiling: robust triangles, packets | ratio to single / 8 / 16 | ratio to the ceiling | goal |"
    echo "|---|---|---:|---:|---:|---:|---:|---:|---|---:|---|"
  } >>"$SUMMARY"
  # scene:goal (the ratio to the ceiling aimed at for primary + shadow rays, depth 0); the full-depth
  # rows are context.
  for entry in whitted:0.3 cornell:0 bunny:0.5 armadillo:0.5; do
    scene=${entry%%:*} goal=${entry#*:}
    file=scenes/$scene.json
    for depth in 0 scene; do
      args=(--goal "$goal")
      [ $depth = 0 ] && args=(--max-depth 0 --goal "$goal")
      [ $depth = scene ] && args=(--goal 0)
      "$BUILD/bench/ray_ceiling/ray_ceiling" --scene "$file" --width $CW --height $CH --spp $CSPP \
        --reps $REPS "${args[@]}" --markdown "$SUMMARY" >"$OUT/ray_ceiling_${scene}_depth$depth.json"
    done
  done
fi

if want ray_ceiling; then
  # The watertight test (the default) against Embree's robust test, frame time
  # of the whole renderer and bare Embree's single rays against its packets, same frame.
  echo "== watertight triangles against Embree's robust test (${CW}x${CH}, $CSPP spp, depth 0, 1 thread)" >&2
  {
    echo -e "\n### Watertight triangles against Embree's robust test (1 thread, best of $REPS, depth 0)\n"
    echo "| scene | renderer frame s, watertight | renderer frame s, embree-robust | ratio (goal <= 1.15) | watertight bare single / 8-wide / 16-wide Mrays/s | packets at least as fast as single rays |"
    echo "|---|---:|---:|---:|---|---|"
  } >>"$SUMMARY"
  for scene in bunny armadillo; do
    "$BUILD/bench/ray_ceiling/ray_ceiling" --scene "scenes/$scene.json" --width $CW --height $CH --spp $CSPP \
      --reps $REPS --max-depth 0 --triangles embree-robust >"$OUT/ray_ceiling_${scene}_depth0_robust.json"
    python3 - "$OUT/ray_ceiling_${scene}_depth0.json" "$OUT/ray_ceiling_${scene}_depth0_robust.json" >>"$SUMMARY" <<'PY'
import json, sys
w, r = (json.load(open(f)) for f in sys.argv[1:3])
ratio = w["seconds"]["renderer"] / r["seconds"]["renderer"]
m = w["mrays_per_s"]
packets = max(m["packet8"], m["packet16"]) >= m["single"]
print(f"| {w['scene']} | {w['seconds']['renderer']:.4f} | {r['seconds']['renderer']:.4f} | **{ratio:.2f}** "
      f"({'met' if ratio <= 1.15 else 'not met'}) | {m['single']:.2f} / {m['packet8']:.2f} / {m['packet16']:.2f} | "
      f"{'yes' if packets else 'no'} |")
PY
  done
fi

if want povray && peer povray povray "POV-Ray 3.7 against Tessera (${PW}x${PH}, $((PR * PR)) spp, $THREADS threads)" \
    "POV-Ray 3.7 on the Whitted showcase (${PW}x${PH}, $THREADS threads)"; then
  # The reference is the speed_error one when its size matches; otherwise render one.
  REF=$CACHE/whitted_${PW}x${PH}_ref${REFSPP}_sobol.exr
  if [ ! -f "$REF" ]; then
    "$BUILD/bench/speed_error/speed_error" --scene scenes/whitted.json --width $PW --height $PH --max-spp 1 \
      --ref-spp $REFSPP --samplers sobol --targets none --threads "$THREADS" --cache "$CACHE" >/dev/null
  fi
  # +A0.0 +AM1 +R n: every pixel supersampled on an n x n grid (non-adaptive in effect), no
  # jitter; then POV-Ray's adaptive anti-aliasing as its users run it (+A threshold +AM2: a pixel
  # is subdivided where its corners differ by more than the threshold, up to +R levels). Linear
  # EXR output (assumed_gamma 1.0 in the scene); same thread count as ours.
  k=0
  for settings in "+A0.0 +AM1 +R$PR" "${POV_ADAPTIVE[@]}"; do
    name=povray$([ $k = 0 ] || echo "_adaptive_$k")
    # The fastest of three runs by trace CPU time (one in --smoke), as pov_compare keeps the
    # fastest of three Tessera renders: one POV-Ray run's time moved by up to 1.45x here.
    best_cpu=1e9
    for rep in $(seq 1 $([ $SMOKE = 1 ] && echo 1 || echo 3)); do
      s=$(date +%s.%N)
      # shellcheck disable=SC2086  # the settings are several flags
      /usr/bin/time -f "%U %S" -o "$OUT/$name.try.cpu" povray +I"$HERE/povray/whitted.pov" +O"$OUT/${name}_try.exr" \
        +FE +W$PW +H$PH $settings -J -D +WT"$THREADS" +V >"$OUT/$name.try.log" 2>&1
      e=$(date +%s.%N)
      # POV-Ray's own trace time (wall) and CPU-seconds: like Tessera's render time, they leave out
      # start-up and parsing (POV-Ray's front end alone takes most of a second).
      try_cpu=$(sed -n 's/.*thread(s) with \([0-9.]*\) CPU-seconds total.*/\1/p' "$OUT/$name.try.log" | tail -1)
      if [ -n "$try_cpu" ] && less_than "$try_cpu" "$best_cpu"; then
        best_cpu=$try_cpu
        process_wall=$(echo "$e - $s" | bc -l)
        mv "$OUT/$name.try.log" "$OUT/$name.log"
        mv "$OUT/$name.try.cpu" "$OUT/$name.cpu"
        mv "$OUT/${name}_try.exr" "$OUT/${name}_whitted.exr"
      fi
    done
    process_cpu=$(awk '{printf "%.3f", $1 + $2}' "$OUT/$name.cpu")
    wall=$(sed -n 's/.*Trace Time:.*(\([0-9.]*\) seconds).*/\1/p' "$OUT/$name.log" | tail -1)
    cpu=$(sed -n 's/.*thread(s) with \([0-9.]*\) CPU-seconds total.*/\1/p' "$OUT/$name.log" | tail -1)
    samples=$(sed -n 's/.*Samples: *\([0-9]*\).*/\1/p' "$OUT/$name.log" | tail -1)
    pixels=$(sed -n 's/^Pixels: *\([0-9]*\).*/\1/p' "$OUT/$name.log" | tail -1)
    echo "POV-Ray $settings process: ${process_wall} s wall, ${process_cpu} s CPU (start-up included)" >&2
    [ $k = 0 ] || echo -e "\nPOV-Ray's adaptive anti-aliasing, \`$settings\`:\n" >>"$SUMMARY"
    "$BUILD/bench/povray/pov_compare" --scene scenes/whitted.json --pov-exr "$OUT/${name}_whitted.exr" \
      --pov-wall "$wall" --pov-cpu "$cpu" --pov-samples "$samples" --pov-pixels "$pixels" --pov-spp $((PR * PR)) --reference "$REF" \
      --width $PW --height $PH --threads "$THREADS" --pov-settings "$settings" --honesty-seeds $PSEEDS \
      --markdown "$SUMMARY" >"$OUT/$name.json"
    k=$((k + 1))
  done
fi

if want lattice; then
  echo "== The lattice sampler's error estimate on hard scenes (${LW}x${LH}, $LSEEDS seeds)" >&2
  scenes=()
  for s in bench/lattice/scenes/*.json; do scenes+=(--scene "$s"); done
  "$BUILD/bench/lattice/lattice_honesty" "${scenes[@]}" --width $LW --height $LH --ref-spp $LREF --seeds $LSEEDS \
    --target-spp $LSPP --threads "$THREADS" --cache "$CACHE" --markdown "$SUMMARY" >"$OUT/lattice_honesty.json"
fi

if want cycles && peer blender blender "Blender's Cycles against Tessera on whitted_a.glb (${BW}x${BH}, $BSPP spp, $THREADS threads)" \
    "Cycles (Blender 3.4) on tests/data/gltf/whitted_a.glb (${BW}x${BH}, $THREADS threads)"; then
  # Blender renders in its own process; only the render's time counts (start-up and the glTF
  # import left out, as Tessera's render time leaves out loading).
  # One Cycles render of the scene: cycles_render.py's spp (and noise threshold, if given) into
  # EXR, its log into LOG; prints its CYCLES_RESULT JSON, or stops the run naming the log.
  cycles_render() {  # EXR LOG SPP [NOISE]
    blender -b --factory-startup --python "$HERE/cycles/cycles_render.py" -- tests/data/gltf/whitted_a.glb \
      "$1" $BW $BH "$3" 8 "$THREADS" ${4:-} >"$2" 2>&1
    local r
    r=$(sed -n 's/^CYCLES_RESULT //p' "$2" | tail -1)
    if [ -z "$r" ]; then
      echo "run_all.sh: Cycles gave no result (see $2)" >&2
      return 1
    fi
    echo "$r"
  }
  field() { python3 -c 'import json,sys; print(json.loads(sys.argv[1])[sys.argv[2]])' "$1" "$2"; }
  # Twice, the faster (CPU) counts, as cycles_compare keeps the fastest of three Tessera renders:
  # one render's time moves by up to 1.5x on a shared machine.
  result= best_cpu=1e9
  for rep in 1 2; do
    try=$(cycles_render "$OUT/cycles_whitted_a_try.exr" "$OUT/cycles_try.log" $BSPP)
    try_cpu=$(field "$try" cpu_s)
    if less_than "$try_cpu" "$best_cpu"; then
      best_cpu=$try_cpu result=$try
      mv "$OUT/cycles_whitted_a_try.exr" "$OUT/cycles_whitted_a.exr"
      mv "$OUT/cycles_try.log" "$OUT/cycles.log"
    fi
  done
  wall=$(field "$result" wall_s)
  cpu=$(field "$result" cpu_s)
  # Cycles at the reference's spp too: the two references differ where the models do.
  cycles_render "$OUT/cycles_whitted_a_ref.exr" "$OUT/cycles_ref.log" $BREF >/dev/null
  # Cycles' timed render includes its scene synchronization, BVH build and EXR write, which
  # Tessera's time leaves out: the same render at 1 spp, twice (the faster counts), lets
  # cycles_compare estimate that fixed cost and take it out of Cycles' times.
  one_wall=1e9 one_cpu=1e9
  for rep in 1 2; do
    one=$(cycles_render "$OUT/cycles_whitted_a_1spp.exr" "$OUT/cycles_1spp.log" 1)
    if less_than "$(field "$one" wall_s)" "$one_wall"; then one_wall=$(field "$one" wall_s); fi
    if less_than "$(field "$one" cpu_s)" "$one_cpu"; then one_cpu=$(field "$one" cpu_s); fi
  done
  # Cycles' adaptive sampling (noise threshold BNOISE, at most BREF spp) against Tessera's frame
  # target, each at equal error against its own reference.
  adaptive=$(cycles_render "$OUT/cycles_whitted_a_adaptive.exr" "$OUT/cycles_adaptive.log" $BREF $BNOISE)
  awall=$(field "$adaptive" wall_s)
  acpu=$(field "$adaptive" cpu_s)
  # The bound on the throughput ratio: bare Embree on the same frame's own queries, one thread
  # (cycles_compare's --ray-ceiling-json).
  "$BUILD/bench/ray_ceiling/ray_ceiling" --scene tests/data/gltf/whitted_a.glb --width $BW --height $BH --spp $BSPP \
    --max-depth 8 --reps $REPS >"$OUT/ray_ceiling_whitted_a_cycles_frame.json"
  "$BUILD/bench/cycles/cycles_compare" --scene tests/data/gltf/whitted_a.glb --cycles-exr "$OUT/cycles_whitted_a.exr" \
    --ray-ceiling-json "$OUT/ray_ceiling_whitted_a_cycles_frame.json" \
    --cycles-reference-exr "$OUT/cycles_whitted_a_ref.exr" \
    --cycles-adaptive-exr "$OUT/cycles_whitted_a_adaptive.exr" --cycles-adaptive-wall "$awall" \
    --cycles-adaptive-cpu "$acpu" --cycles-adaptive-threshold $BNOISE --cycles-adaptive-max-spp $BREF \
    --cycles-wall "$wall" --cycles-cpu "$cpu" --cycles-one-spp-wall "$one_wall" --cycles-one-spp-cpu "$one_cpu" --spp $BSPP --ref-spp $BREF --max-depth 8 --width $BW --height $BH \
    --threads "$THREADS" --markdown "$SUMMARY" >"$OUT/cycles.json"
fi

if want farm && [ $FARM = 1 ] && [ -x "$HERE/farm/run.sh" ]; then
  echo "== farm (bench/farm/run.sh)" >&2
  farm_args=(--build "$BUILD" --out "$OUT/farm")
  [ $SMOKE = 1 ] && farm_args+=(--smoke)
  "$HERE/farm/run.sh" "${farm_args[@]}"
fi
echo "run_all.sh: results in $OUT (summary.md)" >&2
