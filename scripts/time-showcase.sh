#!/usr/bin/env bash
# Times the README's first command from a bare machine: a fresh debian:bookworm-slim container,
# nothing installed, a copy of this working tree (build*/, .git and out/ left out), and
# `time scripts/showcase.sh` as root in it, on 2 CPUs, apt from the same mirror as this machine's.
# Prints showcase.sh's own breakdown (packages, configure, build, render) with the load before and
# after; docs/getting-started.md keeps the results.
#
#   scripts/time-showcase.sh [LOG]     # default log: /tmp/tessera-time-showcase.log
#
# Needs root and a Docker engine: it starts dockerd when none answers, and makes
# debian:bookworm-slim with debootstrap (from the bookworm mirror apt uses here) when no registry
# can give it (scripts/lib/bookworm_image.sh, as tests/containers/container_farm_test.sh does). The container and the copy are removed at
# the end; the image stays.
set -euo pipefail
cd "$(dirname "$0")/.."
src=$(pwd)
log=${1:-/tmp/tessera-time-showcase.log}
cpus=${TESSERA_TIME_CPUS:-2}

# shellcheck source=lib/bookworm_image.sh
. scripts/lib/bookworm_image.sh
docker_engine_up || { echo "$bookworm_why"; exit 1; }
bookworm_slim_image || { echo "$bookworm_why"; exit 1; }

copy=$(mktemp -d /tmp/tessera-time-showcase.XXXXXX)
name="tessera-time-showcase-$$"
trap 'docker rm -f "$name" >/dev/null 2>&1 || true; rm -rf "$copy"' EXIT
tar -C "$src" --exclude='./build*' --exclude=./.git --exclude=./out -cf - . | tar -C "$copy" -xf -
{
  echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //'), $(nproc) cores; container: --cpus $cpus"
  echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)   $(date -u '+%Y-%m-%d %H:%M UTC')"
} | tee "$log"
docker run --rm --name "$name" --cpus "$cpus" -v "$copy:/mnt/src:ro" debian:bookworm-slim bash -c '
  cp -a /mnt/src /root/tessera && cd /root/tessera
  time bash scripts/showcase.sh
  ls -l out/' 2>&1 | tee -a "$log" | grep -E '^(install-deps:|build.sh:|showcase:|real|user|sys)' || true
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)" | tee -a "$log"
grep -q '^showcase: ' "$log" || { echo "the showcase failed: $log"; exit 1; }
