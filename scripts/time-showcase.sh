#!/usr/bin/env bash
# Times the README's first command from a bare machine: a fresh debian:bookworm-slim container,
# nothing installed, a copy of this working tree (build*/, .git and out/ left out), and
# `time scripts/showcase.sh` as root in it, on 2 CPUs, apt from the same mirror as this machine's.
# Prints showcase.sh's own breakdown (packages, configure, build, render) with the load before and
# after; docs/getting-started.md keeps the results.
#
#   scripts/time-showcase.sh [LOG]     # default log: /tmp/tessera-time-showcase.log
#
# Needs root and a Docker engine: as tests/containers/container_farm_test.sh does, it starts
# dockerd when none answers, and makes debian:bookworm-slim with debootstrap (from the bookworm
# mirror apt uses here) when no registry can give it. The container and the copy are removed at
# the end; the image stays.
set -euo pipefail
cd "$(dirname "$0")/.."
src=$(pwd)
log=${1:-/tmp/tessera-time-showcase.log}
cpus=${TESSERA_TIME_CPUS:-2}

if ! docker info >/dev/null 2>&1; then
  [ "$(id -u)" -eq 0 ] && command -v dockerd >/dev/null || { echo "no Docker engine, and starting dockerd needs root and docker.io"; exit 1; }
  echo "starting dockerd (log: /tmp/tessera-dockerd.log)"
  (setsid dockerd >/tmp/tessera-dockerd.log 2>&1 </dev/null &)
  for _ in $(seq 1 60); do docker info >/dev/null 2>&1 && break; sleep 1; done
  docker info >/dev/null 2>&1 || { tail -20 /tmp/tessera-dockerd.log; exit 1; }
fi
if ! docker image inspect debian:bookworm-slim >/dev/null 2>&1; then
  command -v debootstrap >/dev/null || { echo "debian:bookworm-slim is missing: apt-get install debootstrap"; exit 1; }
  # The bookworm mirror of apt's sources (deb822 .sources or one-line .list), as the container test finds it.
  mirror=$(awk '/^[[:space:]]*$/ {u = ""} /^URIs:/ {u = $2} /^Suites:/ && / bookworm( |$)/ && u != "" {print u; exit}' \
             /etc/apt/sources.list.d/*.sources 2>/dev/null || true)
  [ -n "$mirror" ] || mirror=$(awk '$1 == "deb" && / bookworm / {for (i = 2; i <= NF; i++) if ($i ~ /^[a-z]+:\/\//) {print $i; exit}}' \
                                 /etc/apt/sources.list /etc/apt/sources.list.d/*.list 2>/dev/null | head -1)
  [ -n "$mirror" ] || { echo "apt's sources name no bookworm mirror"; exit 1; }
  echo "making debian:bookworm-slim with debootstrap from $mirror"
  rootfs=$(mktemp -d /tmp/tessera-bookworm-rootfs.XXXXXX)
  debootstrap --variant=minbase bookworm "$rootfs" "$mirror" >/tmp/tessera-debootstrap.log 2>&1 ||
    { tail -20 /tmp/tessera-debootstrap.log; rm -rf "$rootfs"; exit 1; }
  tar -C "$rootfs" -c . | docker import - debian:bookworm-slim >/dev/null
  rm -rf "$rootfs"
fi

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
