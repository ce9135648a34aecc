#!/usr/bin/env bash
# The farm in real containers: builds the images (docker/Dockerfile), starts a coordinator and 3
# workers with compose (the root compose.yaml, as the README does), submits a 4-frame job from the
# host's `tessera` CLI through the published port, `docker kill`s a worker in the middle of the
# job, scales to 4 workers, and checks every frame is pixel-for-pixel identical to an in-process
# `tessera render`. Containers, networks and volumes are removed on every exit; the images stay
# (tagged :ctest) so a second run reuses the build cache.
#
#   container_farm_test.sh SOURCE_DIR TESSERA_CLI TESSERA_SERVER TESSERA_WORKER
#
# Which programs go into the images (TESSERA_CONTAINER_BINARIES):
#   host    (the default on a Debian bookworm host) the programs given above, built on this host:
#           the Dockerfile's build stage is swapped for a copy of them, every other stage (runtime
#           packages, user, health checks, entry points) is the file's own. Minutes, not the half
#           hour of compiling inside the image on a 2-core machine: what CI runs.
#   source  the Dockerfile as it is, compiling the project inside the image (what users build):
#           bench/containers/image_build.sh runs this variant.
# TESSERA_CONTAINER_NO_CACHE=1 builds without Docker's layer cache.
#
# Needs a Docker engine. As root with apt, installs docker.io, docker-compose and debootstrap when
# missing and starts dockerd; otherwise, or when no engine can be started, exits 77 (CTest: skipped).
# No registry is reachable on the build machines, so debian:bookworm-slim is made locally with
# debootstrap when missing (see ../shared/docs/environment.md).
set -euo pipefail

SKIP=77
usage="usage: container_farm_test.sh SOURCE_DIR TESSERA_CLI TESSERA_SERVER TESSERA_WORKER"
src=$(cd "${1:?$usage}" && pwd)
cli=${2:?$usage}
server=${3:?$usage}
worker=${4:?$usage}
here="$src/tests/containers"
scene="$here/orbit4.json"
frames=4
t0=$SECONDS

log() { echo "[container test $(date +%T), +$((SECONDS - t0)) s] $*"; }
skip() { echo "SKIPPED: $*"; exit "$SKIP"; }
fail() { echo "FAILED: $*" >&2; exit 1; }

binaries=${TESSERA_CONTAINER_BINARIES:-host}
case "$binaries" in
  host)
    if ! grep -qx 'VERSION_CODENAME=bookworm' /etc/os-release 2>/dev/null; then
      log "this host is not Debian bookworm: its programs may not run in the bookworm image, compiling inside it"
      binaries=source
    fi ;;
  source) ;;
  *) fail "TESSERA_CONTAINER_BINARIES must be host or source, not '$binaries'" ;;
esac

# ---- tools and engine -----------------------------------------------------------------------
can_install() { [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null; }
missing=()
docker info >/dev/null 2>&1 || command -v dockerd >/dev/null || missing+=(docker.io)
command -v docker >/dev/null || missing+=(docker.io)
command -v docker-compose >/dev/null || missing+=(docker-compose)
command -v debootstrap >/dev/null || missing+=(debootstrap)
if [ ${#missing[@]} -gt 0 ]; then
  can_install || skip "needs ${missing[*]} (not installed, and installing needs root with apt-get)"
  log "installing ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq $(printf '%s\n' "${missing[@]}" | sort -u) >/dev/null
fi
# shellcheck source=../../scripts/lib/bookworm_image.sh
. "$src/scripts/lib/bookworm_image.sh"
docker_engine_up || skip "$bookworm_why"
compose=(docker-compose)
command -v idiff >/dev/null || fail "idiff (openimageio-tools) is missing: run scripts/install-deps.sh"
log "engine $(docker version --format '{{.Server.Version}}'), $("${compose[@]}" version --short 2>/dev/null || echo compose)"

# ---- the base image, made locally when no registry can give it --------------------------------
rc=0
bookworm_slim_image || rc=$?
[ "$rc" -ne 1 ] || skip "$bookworm_why"
[ "$rc" -eq 0 ] || fail "$bookworm_why"

# ---- one compose project per run, removed on every exit ----------------------------------------
project="tesseract$$"
tmp=$(mktemp -d /tmp/tessera-container-test.XXXXXX)
export TESSERA_TAG=ctest TESSERA_PUBLISH="127.0.0.1:" TESSERA_HEARTBEAT_MS=500 TESSERA_LEASE_TIMEOUT_MS=5000
# One copy of the sources for both images: compose sends the build context once per service, and
# a tree being edited in the meantime would otherwise give the two images different builds.
snap="$tmp/src"
mkdir -p "$snap"
tar -C "$src" --exclude='./build*' --exclude=./.git --exclude=./out -cf - . | tar -C "$snap" -xf -
compose_files=(-f "$snap/compose.yaml" -f "$snap/tests/containers/compose.test.yaml")
dc() { "${compose[@]}" -p "$project" "${compose_files[@]}" "$@"; }
cleanup() {
  local rc=$?
  if [ "$rc" -ne 0 ] && [ "$rc" -ne "$SKIP" ]; then
    echo "---- container logs (last 40 lines each) ----"
    dc logs --no-color --tail 40 2>/dev/null || true
    for f in "$tmp"/*.log; do [ -f "$f" ] && { echo "---- $f"; tail -20 "$f"; }; done
  fi
  dc down --volumes --remove-orphans --timeout 5 >/dev/null 2>&1 || true
  rm -rf "$tmp"
  exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM
if [ "$binaries" = host ]; then
  # The host's programs, stripped as the build stage strips them, with the packages that own the
  # libraries they load (the same script the build stage runs), in place of the build stage.
  mkdir -p "$snap/host-binaries/bin"
  cp "$cli" "$server" "$worker" "$snap/host-binaries/bin/"
  strip --strip-unneeded "$snap/host-binaries/bin/"*
  sh "$src/docker/runtime-packages.sh" "$snap/host-binaries/bin/"* >"$snap/host-binaries/runtime-packages" ||
    fail "cannot name the packages the host's programs need (docker/runtime-packages.sh)"
  awk '/^FROM .* AS build$/ { print; print "COPY host-binaries/ /out/"; skipping = 1; swapped = 1; next }
       skipping && /^# ----/ { skipping = 0 }
       !skipping { print }
       END { exit !swapped }' "$snap/docker/Dockerfile" >"$snap/docker/Dockerfile.host-binaries" ||
    fail "docker/Dockerfile has no 'FROM ... AS build' stage to swap for the host's programs"
  cat >"$tmp/compose.host-binaries.yaml" <<'YAML'
services:
  coordinator:
    build:
      dockerfile: docker/Dockerfile.host-binaries
  worker:
    build:
      dockerfile: docker/Dockerfile.host-binaries
YAML
  compose_files+=(-f "$tmp/compose.host-binaries.yaml")
fi
# Projects of earlier runs that were killed before their trap ran (CTest timeout): remove them.
for p in $(docker ps -a --format '{{.Label "com.docker.compose.project"}}' | grep -E '^tesseract[0-9]+$' | sort -u); do
  kill -0 "${p#tesseract}" 2>/dev/null && continue
  log "removing the leftover project $p"
  "${compose[@]}" -p "$p" -f "$src/compose.yaml" down --volumes --remove-orphans --timeout 1 >/dev/null 2>&1 || true
done

# ---- build ----------------------------------------------------------------------------------
if [ "$binaries" = host ]; then
  log "building the images (docker/Dockerfile with this host's programs in place of its build stage)"
else
  log "building the images (docker/Dockerfile; the first build compiles the project)"
fi
build_start=$SECONDS
build_flags=()
[ "${TESSERA_CONTAINER_NO_CACHE:-0}" = 1 ] && build_flags=(--no-cache)  # a cold build, for timing it
dc build "${build_flags[@]}" >"$tmp/build.log" 2>&1 || { tail -40 "$tmp/build.log"; fail "image build failed (log above)"; }
log "images built in $((SECONDS - build_start)) s: $(docker image ls --format '{{.Repository}}:{{.Tag}} {{.Size}}' | grep ':ctest' | tr '\n' ' ')"

# ---- the reference: the same frames rendered in-process on the host -------------------------
for f in $(seq 0 $((frames - 1))); do
  "$cli" render "$scene" --frame "$f" -o "$tmp/ref_$f.exr" >"$tmp/render.log" 2>&1 ||
    { cat "$tmp/render.log"; fail "tessera render of frame $f failed"; }
done

# ---- a coordinator and 3 workers -----------------------------------------------------------
log "starting a coordinator and 3 workers (project $project)"
dc up -d --scale worker=3 >"$tmp/up.log" 2>&1 || { cat "$tmp/up.log"; fail "docker-compose up failed"; }
addr=$(dc port coordinator 7878)
[ -n "$addr" ] || fail "the coordinator's port 7878 is not published"
log "coordinator published on $addr"

for _ in $(seq 1 60); do "$cli" health --coordinator "$addr" --timeout 2 --quiet 2>/dev/null && break; sleep 1; done
"$cli" health --coordinator "$addr" --timeout 5 || fail "the coordinator's health service does not answer on $addr"

count_workers() {
  "$cli" workers --coordinator "$addr" --json 2>/dev/null |
    python3 -c 'import json,sys; print(len(json.load(sys.stdin)))' 2>/dev/null || echo 0
}
wait_workers() {  # N SECONDS
  for _ in $(seq 1 "$2"); do [ "$(count_workers)" -eq "$1" ] && return 0; sleep 1; done
  "$cli" workers --coordinator "$addr" || true
  fail "expected $1 workers at the coordinator, have $(count_workers)"
}
wait_workers 3 90
log "3 workers connected by service name"

# ---- the job: submitted from the host, frames written on the host ----------------------------
out="$tmp/farm"
mkdir -p "$out"
"$cli" submit "$scene" --coordinator "$addr" --detach --tile 16 -q >"$tmp/submit.log" 2>&1 ||
  { cat "$tmp/submit.log"; fail "tessera submit failed"; }
job=$(grep -oE 'job [0-9a-f]+ submitted' "$tmp/submit.log" | awk '{print $2}')
[ -n "$job" ] || { cat "$tmp/submit.log"; fail "no job id in the submit output"; }
"$cli" watch "$job" --coordinator "$addr" -o "$out/frame_####.exr" -q >"$tmp/watch.log" 2>&1 &
watch_pid=$!
log "job $job submitted: $(grep -oE '[0-9]+ tiles' "$tmp/submit.log" | head -1)"

job_field() {  # FIELD: from `tessera status JOB --json`
  "$cli" status "$job" --coordinator "$addr" --json 2>/dev/null |
    python3 -c "import json,sys; print(json.load(sys.stdin)['$1'])" 2>/dev/null || echo "?"
}
total=$(job_field tiles_total)
[[ "$total" =~ ^[0-9]+$ ]] || fail "cannot read the job's status"
# A worker that holds leases, while the job runs: its name is <container hostname>-<pid>, and a
# container's hostname is the start of its id.
leased_worker() {
  "$cli" workers --coordinator "$addr" --json 2>/dev/null | python3 -c '
import json, sys
ws = [w for w in json.load(sys.stdin) if w["tiles_in_flight"] > 0]
print(ws[0]["name"], ws[0]["tiles_in_flight"]) if ws else None' 2>/dev/null || true
}
victim=""
for _ in $(seq 1 300); do
  done_tiles=$(job_field tiles_done)
  if [[ "$done_tiles" =~ ^[0-9]+$ ]] && [ "$done_tiles" -ge 4 ]; then
    [ "$(job_field state)" = running ] || fail "the job ended ($done_tiles/$total tiles) before a worker could be killed: make it longer"
    victim=$(leased_worker)
    [ -n "$victim" ] && break
  fi
  sleep 0.2
done
[ -n "$victim" ] || fail "no worker held a lease while the job ran"
read -r victim_name victim_leases <<<"$victim"
cid=${victim_name%-*}
[ "$(docker inspect --format '{{index .Config.Labels "com.docker.compose.project"}}' "$cid" 2>/dev/null)" = "$project" ] ||
  fail "worker '$victim_name' is not a container of this project"
log "$done_tiles/$total tiles done: docker kill $cid, a worker holding $victim_leases lease(s)"
docker kill "$cid" >/dev/null
log "scaling to 4 workers"
dc up -d --no-recreate --scale worker=4 >"$tmp/scale.log" 2>&1 || { cat "$tmp/scale.log"; fail "scaling to 4 workers failed"; }
running=$(docker ps -q --filter "label=com.docker.compose.project=$project" --filter "label=com.docker.compose.service=worker" | wc -l)
log "$running worker containers running"
[ "$running" -eq 4 ] || fail "expected 4 running worker containers after scaling, have $running"

# ---- every frame, complete and identical to the in-process render -----------------------------
for _ in $(seq 1 300); do kill -0 "$watch_pid" 2>/dev/null || break; sleep 1; done
kill -0 "$watch_pid" 2>/dev/null && { kill "$watch_pid"; fail "the job did not finish within 300 s ($(job_field tiles_done)/$total tiles)"; }
wait "$watch_pid" || { cat "$tmp/watch.log"; fail "tessera watch failed"; }
[ "$(job_field state)" = done ] || fail "job state is $(job_field state), expected done"
wait_workers 4 30
log "job status after it ended: $(job_field tiles_done)/$total tiles done, $(job_field tiles_rendered_twice) rendered twice"
dc logs --no-color coordinator >"$tmp/coordinator.log" 2>&1 || true
grep -iE 'requeu|lost|left|expired' "$tmp/coordinator.log" | sed 's/^/  coordinator: /' | tail -5 || true

for f in $(seq 0 $((frames - 1))); do
  got=$(printf '%s/frame_%04d.exr' "$out" "$f")
  [ -f "$got" ] || fail "frame $f was not written ($got)"
  # idiff with zero thresholds: exit 0 only when every pixel value is equal.
  idiff -fail 0 -failpercent 0 -warn 0 -warnpercent 0 "$tmp/ref_$f.exr" "$got" >"$tmp/idiff_$f.log" 2>&1 ||
    { cat "$tmp/idiff_$f.log"; fail "frame $f from the container farm differs from tessera render"; }
done
log "PASSED: $frames frames identical to tessera render; one worker killed, scaled 3 -> 4"
